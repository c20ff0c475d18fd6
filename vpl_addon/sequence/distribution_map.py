"""Distribution maps of a light's emitted paths (Moreau, Doggett, Sintorn, Path Verification for Dynamic Indirect
Illumination, sec. 3.1): the cells partition the light's emission samples (position on the light x outgoing
direction); DM_T is how many of a light's kept paths each cell should hold, DM_C how many it holds.

A cell is a box in the unit square coordinates that ``LightSet.emit`` maps to emission samples, so every cell has
the same probability under the light's own sampling and DM_T is uniform (the light's path count over the cells):

* point and spot lights without radius: the direction only, (1 - z) / 2 x phi / 2 pi of ``uniform_sphere``
  (8 x 16 cells);
* point and spot lights with a radius (spheres): the point on the sphere by the same two coordinates (4 x 8) x the
  cosine-weighted direction about the sphere's normal, sin^2 theta x phi / 2 pi of ``cosine_hemisphere`` (2 x 2);
* rectangular area lights: the point on the rectangle, its two edge coordinates (4 x 4), x the cosine-weighted
  direction about the normal (2 x 4).

Other lights (round area lights, suns, emissive triangles, the world) have no map: when they change, their paths
are traced again. ``prune`` draws the paths to drop with probability (DM_C - DM_T) / DM_C (eq. 1) and ``fill``
samples the light restricted to the cells below their target.
"""
from __future__ import annotations

import numpy as np

from ..core.sampling import cosine_hemisphere, dot, orthonormal_basis, uniform_sphere
from ..lights import AreaLight, PointLight

SPHERE_BINS = (8, 16)  # (1 - z) / 2, phi / 2 pi of a direction (or of the point on a sphere light)
SPHERE_POINT_BINS = (4, 8)
LOBE_BINS = (2, 2)  # sin^2 theta, phi / 2 pi of a cosine-weighted direction
RECT_BINS = (4, 4, 2, 4)  # edge coordinates u, v; sin^2 theta, phi / 2 pi


def supported(light) -> bool:
    """Whether the light has a distribution map (its paths can follow it when it moves)."""
    return isinstance(light, PointLight) or (isinstance(light, AreaLight) and not light.round)


def bins(light) -> tuple[int, ...]:
    if isinstance(light, PointLight):
        return SPHERE_BINS if light.radius <= 0.0 else SPHERE_POINT_BINS + LOBE_BINS
    return RECT_BINS


def _sphere_coords(d):
    phi = np.arctan2(d[:, 1], d[:, 0]) / (2.0 * np.pi)
    return [0.5 * (1.0 - np.clip(d[:, 2], -1.0, 1.0)), phi - np.floor(phi)]


def _lobe_coords(d, n):
    t, s = orthonormal_basis(n)
    cos = np.clip(dot(d, n), 0.0, 1.0)
    phi = np.arctan2(dot(d, s), dot(d, t)) / (2.0 * np.pi)
    return [1.0 - cos * cos, phi - np.floor(phi)]


def coordinates(light, origins: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    """(N, k) unit-square coordinates of emission samples (the inverse of the light's ``emit``)."""
    if isinstance(light, PointLight):
        if light.radius <= 0.0:
            return np.stack(_sphere_coords(dirs), axis=1)
        normal = (origins - light.position) / light.radius
        normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
        return np.stack(_sphere_coords(normal) + _lobe_coords(dirs, normal), axis=1)
    rel = origins - light.center
    u = dot(rel, light.axis_u) / dot(light.axis_u, light.axis_u) + 0.5
    v = dot(rel, light.axis_v) / dot(light.axis_v, light.axis_v) + 0.5
    return np.stack([u, v] + _lobe_coords(dirs, np.broadcast_to(light.normal, dirs.shape)), axis=1)


def cells(light, origins: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    """The cell of each emission sample (flat index into ``bins(light)``)."""
    shape = np.array(bins(light))
    index = np.clip((coordinates(light, origins, dirs) * shape).astype(np.int64), 0, shape - 1)
    return np.ravel_multi_index(tuple(index.T), tuple(shape))


def sample(light, cell: np.ndarray, rng) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Emission samples restricted to the given cells: (origins, dirs, power) as ``light.emit`` gives them."""
    shape = bins(light)
    corner = np.stack(np.unravel_index(cell, shape), axis=1)
    u = (corner + rng.random((len(cell), len(shape)))) / np.array(shape)
    if isinstance(light, PointLight):
        if light.radius <= 0.0:
            dirs = uniform_sphere(u[:, 0], u[:, 1])
            origins = np.broadcast_to(light.position, dirs.shape).copy()
        else:
            normal = uniform_sphere(u[:, 0], u[:, 1])
            dirs, _ = cosine_hemisphere(u[:, 2], u[:, 3], normal)
            origins = light.position + light.radius * normal
        return origins, dirs, light.attenuation(dirs)[:, None] * light.power
    origins = light.center + (u[:, :1] - 0.5) * light.axis_u + (u[:, 1:2] - 0.5) * light.axis_v
    dirs, cos = cosine_hemisphere(u[:, 2], u[:, 3], np.broadcast_to(light.normal, (len(cell), 3)))
    return origins, dirs, light.spread_profile(cos)[:, None] * light.power


def prune(counts: np.ndarray, target: np.ndarray, cell: np.ndarray, rng) -> np.ndarray:
    """Eq. 1: each path of a cell holding more than its target is dropped with probability (DM_C - DM_T) / DM_C;
    returns the mask of paths kept."""
    with np.errstate(divide="ignore", invalid="ignore"):
        drop = np.where(counts > target, (counts - target) / counts, 0.0)
    return rng.random(len(cell)) >= drop[cell]


def fill(counts: np.ndarray, target: np.ndarray, rng) -> np.ndarray:
    """The cells of the new paths that bring each cell up to its target (a fractional shortfall is rounded at
    random). ``counts`` is DM_C before pruning: a cell that pruning took below its target is not filled, so every
    cell's expected count is its target."""
    lack = np.maximum(target - counts, 0.0)
    number = np.floor(lack + rng.random(len(lack))).astype(np.int64)
    return np.repeat(np.arange(len(lack)), number)


def transform(old, new, origins: np.ndarray, dirs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Emission samples of ``old`` moved rigidly with the light to ``new`` (sec. 3.1, "update path origins")."""
    (c0, r0), (c1, r1) = _frame(old), _frame(new)
    rotation = r1 @ r0.T
    return c1 + (origins - c0) @ rotation.T, dirs @ rotation.T


def _frame(light) -> tuple[np.ndarray, np.ndarray]:
    """The light's centre and orthonormal frame (columns), which its emission samples move with."""
    if isinstance(light, AreaLight):
        axis = light.normal
        t = light.axis_u - dot(light.axis_u, axis) * axis
    elif hasattr(light, "direction"):
        axis = light.direction
        t = orthonormal_basis(axis)[0]
    else:
        return light.position, np.eye(3)
    t = t / np.linalg.norm(t)
    frame = np.stack([t, np.cross(axis, t), axis], axis=1)
    return (light.center if isinstance(light, AreaLight) else light.position), frame


def shape(light) -> tuple:
    """What a rigid motion keeps: a light whose shape changed has its paths emitted again."""
    if isinstance(light, AreaLight):
        return ("area", light.name, float(np.linalg.norm(light.axis_u)), float(np.linalg.norm(light.axis_v)),
                light.round, float(light.spread))
    return (type(light).__name__, light.name, float(light.radius), bool(light.soft_falloff),
            float(getattr(light, "spot_size", 0.0)), float(getattr(light, "spot_blend", 0.0)))
