"""The one gather: light from virtual point lights to shading points, with ray-traced visibility.

``sum_pairs`` evaluates VPL -> point pairs: I cos(theta_vpl) cos(theta_x) / (pi max(d^2, d_min^2)) V, the light a
VPL sends to a white Lambertian receiver (Cycles' ``Diffuse Indirect`` meaning). The geometry term is clamped at
``d_min`` (Keller 1997; pbrt's igi "glimit"), which removes the 1/d^2 spikes of nearby VPLs at the cost of a
little energy near corners; ``clamp_distance`` ties d_min to the mean VPL spacing so it shrinks as the budget grows.

``gather`` sums all VPLs at every point (exact), or with interleaved sampling (Keller and Heidrich 2001, as used by
Segovia et al. and Hedman et al.): the pixels of each t x t tile see disjoint random subsets of the VPLs, scaled
to the whole set; ``bilateral.deinterleave`` then removes the tile pattern.

The pairs' geometry and their sums are compiled kernels (``core.compiled``); their shadow rays go to embree in
batches of about ``PAIRS_PER_BATCH``, from ends offset once per point and once per VPL.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.compiled import kernel
from ..materials.surface import bent, bump_factor

PAIRS_PER_BATCH = 1 << 18  # a batch's shadow rays are one tracer call: about 25 ms, what a viewport change waits for


@dataclass
class GatherSettings:
    interleave: int = 4  # tile size t: t*t VPL subsets; 1 = exact gather (every point sees every VPL)
    clamp: float = 0.5  # d_min as a multiple of the mean VPL spacing sqrt(area / (pi N)); 0 = no clamping
    filter: bool = True  # geometry-aware filter after interleaving
    # Cycles' Clamp Indirect: the largest value a gathering sample's indirect light may take (its brightest
    # channel, the colour kept); 0 = off. It trades the rare bright samples of caustics for bias, as in Cycles
    clamp_indirect: float = 0.0

    def __post_init__(self):
        for name in ("clamp", "clamp_indirect"):  # NaN would spread to every pixel of the gather
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0.0):
                raise ValueError(f"{name} must be a finite number of at least 0 (got {value})")


def clamp_distance(surface_area: float, count: int, clamp: float) -> float:
    """d_min = clamp * sqrt(area / (pi N)): the radius of the disc each of N VPLs stands for."""
    if clamp <= 0.0 or count <= 0:
        return 0.0
    return clamp * float(np.sqrt(surface_area / (np.pi * count)))


def sum_pairs(surface, point_index, vpls, vpl_index, tracer, d_min, group, count) -> np.ndarray:
    """(count,3): the light of the pairs (point_index[i], vpl_index[i]) summed by ``group[i]`` (a point or a VPL
    index), evaluated in batches so memory stays flat however many pairs there are."""
    out = np.zeros((count, 3))
    ends = _ends(surface, vpls, tracer)
    for lo in range(0, len(point_index), PAIRS_PER_BATCH):
        hi = lo + PAIRS_PER_BATCH
        _add_pairs(surface, vpls, ends, point_index[lo:hi], vpl_index[lo:hi], group[lo:hi], tracer, d_min, out)
    return out


def _ends(surface, vpls, tracer) -> tuple[np.ndarray, np.ndarray]:
    """Where the shadow rays of the pairs start and end, once per point and per VPL: the points pushed off their
    surface along the geometric normal (the side a pair's direction leaves by), the VPLs along their normal (the
    side the light leaves by), as ``Tracer.visible`` offsets both ends of a segment."""
    return (tracer.offset_origin(surface.position, surface.geometric_normal),
            tracer.offset_origin(vpls.position, vpls.normal))


def _add_pairs(surface, vpls, ends, point_index, vpl_index, group, tracer, d_min, out):
    """out[group[i]] += the light of VPL vpl_index[i] at point point_index[i], I cos(theta_vpl) cos(theta_x) /
    (pi max(d^2, d_min^2)) V (Keller 1997 with pbrt's clamp), the receiver's cos with the bump shadowing term
    (``surface.diffuse_cosine``)."""
    s = surface
    rows, w, g, origin, direction, tmax = _pairs(s.position, s.geometric_normal, s.shading_normal, vpls.position,
                                                 vpls.normal, *ends, point_index, vpl_index, d_min * d_min)
    turned = np.nonzero(bent(s.smooth_normal, s.shading_normal)[point_index[rows]])[0]
    if len(turned):  # a normal map bent these points' normals: the diffuse lobe's light is shadowed by the bump
        at = point_index[rows[turned]]
        g[turned] *= bump_factor(s.shading_normal[at], s.smooth_normal[at], w[turned])
        lit = np.nonzero(g > 0.0)[0]
        rows, g, origin, direction, tmax = rows[lit], g[lit], origin[lit], direction[lit], tmax[lit]
    if len(rows):
        blocked, _, tint = tracer.occluded_through(origin, direction, tmax, tinted=True)
        _accumulate(group, vpl_index, rows, g, blocked, np.zeros((0, 3)) if tint is None else tint, vpls.intensity,
                    out)


@kernel
def _pairs(position, ng, ns, q, nq, origins, targets, point_index, vpl_index, d_min2):
    """The pairs that can carry light (both cosines positive, the direction leaving the point's surface), as
    (their rows, unit directions w point -> VPL, geometry terms cos_v cos_x / (pi max(d^2, d_min^2)) without the
    bump term, and the shadow rays between the offset ends ``origins`` (per point) and ``targets`` (per VPL):
    origins, unit directions, lengths shortened by 1e-5 as ``Tracer.visible``'s)."""
    m = len(point_index)
    rows = np.empty(m, np.int64)
    w = np.empty((m, 3))
    g = np.empty(m)
    origin = np.empty((m, 3))
    direction = np.empty((m, 3))
    tmax = np.empty(m)
    k = 0
    for i in range(m):
        a, b = point_index[i], vpl_index[i]
        v0, v1, v2 = q[b, 0] - position[a, 0], q[b, 1] - position[a, 1], q[b, 2] - position[a, 2]
        d2 = v0 * v0 + v1 * v1 + v2 * v2
        d = np.sqrt(d2)
        inv = max(d, 1e-300)
        v0, v1, v2 = v0 / inv, v1 / inv, v2 / inv
        cos_x = max(ns[a, 0] * v0 + ns[a, 1] * v1 + ns[a, 2] * v2, 0.0)
        cos_v = -(nq[b, 0] * v0 + nq[b, 1] * v1 + nq[b, 2] * v2)
        if not (cos_x > 0.0 and cos_v > 0.0 and ng[a, 0] * v0 + ng[a, 1] * v1 + ng[a, 2] * v2 > 0.0 and d > 0.0):
            continue
        rows[k] = i
        w[k, 0], w[k, 1], w[k, 2] = v0, v1, v2
        g[k] = cos_x * cos_v / (np.pi * max(d2, d_min2))
        length = 0.0
        for c in range(3):
            origin[k, c] = origins[a, c]
            direction[k, c] = targets[b, c] - origins[a, c]
            length += direction[k, c] * direction[k, c]
        length = np.sqrt(length)
        if length > 0.0:
            for c in range(3):
                direction[k, c] /= length
        else:
            direction[k, 0], direction[k, 1], direction[k, 2] = v0, v1, v2
        tmax[k] = length * (1.0 - 1e-5)
        k += 1
    return rows[:k], w[:k], g[:k], origin[:k], direction[:k], tmax[:k]


@kernel
def _accumulate(group, vpl_index, rows, g, blocked, tint, intensity, out):
    """out[group[r]] += intensity[vpl_index[r]] g (times ``tint[i]``, what coloured glass between them leaves, if
    given: ``tint`` has a row per pair or none) for the pairs r = rows[i] not ``blocked``, in pair order."""
    tinted = len(tint) > 0
    for i in range(len(rows)):
        if blocked[i]:
            continue
        r = rows[i]
        at, b = group[r], vpl_index[r]
        for c in range(3):
            out[at, c] += intensity[b, c] * g[i] * (tint[i, c] if tinted else 1.0)


def gather(surface, pixel_xy, vpls, tracer, settings: GatherSettings, d_min: float,
           permutation: np.ndarray) -> np.ndarray:
    """(K,3) indirect light at every surface point.

    ``pixel_xy`` (K,2) integer pixel coordinates pick each point's interleaving subset; ``permutation`` is a random
    order of the VPLs shared by the whole image, so every tile position sees the same disjoint subset."""
    out = np.zeros((len(surface), 3))
    if len(vpls) == 0 or len(surface) == 0:
        return out
    t = max(1, int(settings.interleave))
    subsets = min(t * t, len(vpls))  # fewer VPLs than tile positions: positions share them cyclically
    position = (pixel_xy[:, 1] % t) * t + (pixel_xy[:, 0] % t)
    subset = [permutation[g % subsets::subsets] if t > 1 else np.arange(len(vpls)) for g in range(t * t)]
    ends = _ends(surface, vpls, tracer)
    for point_index, vpl_index in _batches([np.nonzero(position == g)[0] for g in range(t * t)], subset):
        _add_pairs(surface, vpls, ends, point_index, vpl_index, point_index, tracer, d_min, out)
    scale = np.array([len(vpls) / max(len(part), 1) for part in subset])  # each subset stands for the whole set
    return out * scale[position][:, None]


def _batches(points, subsets):
    """(point_index, vpl_index) of every point of ``points[g]`` with every VPL of ``subsets[g]``, in batches of at
    most ``PAIRS_PER_BATCH`` pairs (or one point's)."""
    pending, size = [], 0
    for pts, subset in zip(points, subsets):
        if len(subset) == 0:
            continue
        step = max(1, PAIRS_PER_BATCH // len(subset))
        for lo in range(0, len(pts), step):
            part = pts[lo:lo + step]
            if pending and size + len(part) * len(subset) > PAIRS_PER_BATCH:
                yield tuple(np.concatenate(column) for column in zip(*pending))
                pending, size = [], 0
            pending.append((np.repeat(part, len(subset)), np.tile(subset, len(part))))
            size += len(part) * len(subset)
    if pending:
        yield tuple(np.concatenate(column) for column in zip(*pending))
