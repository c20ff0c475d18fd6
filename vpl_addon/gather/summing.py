"""The one gather: light from virtual point lights to shading points, with ray-traced visibility.

``connect`` evaluates VPL -> point pairs: I cos(theta_vpl) cos(theta_x) / (pi max(d^2, d_min^2)) V, the light a
VPL sends to a white Lambertian receiver (Cycles' ``Diffuse Indirect`` meaning). The geometry term is clamped at
``d_min`` (Keller 1997; pbrt's igi "glimit"), which removes the 1/d^2 spikes of nearby VPLs at the cost of a
little energy near corners; ``clamp_distance`` ties d_min to the mean VPL spacing so it shrinks as the budget grows.

``gather`` sums all VPLs at every point (exact), or with interleaved sampling (Keller and Heidrich 2001, as used by
Segovia et al. and Hedman et al.): the pixels of each t x t tile see disjoint random subsets of the VPLs, scaled
to the whole set; ``bilateral.deinterleave`` then removes the tile pattern.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.sampling import dot, group_sum
from ..materials.surface import diffuse_cosine

PAIRS_PER_BATCH = 1 << 20


@dataclass
class GatherSettings:
    interleave: int = 4  # tile size t: t*t VPL subsets; 1 = exact gather (every point sees every VPL)
    clamp: float = 0.5  # d_min as a multiple of the mean VPL spacing sqrt(area / (pi N)); 0 = no clamping
    filter: bool = True  # geometry-aware filter after interleaving

    def __post_init__(self):
        if not (np.isfinite(self.clamp) and self.clamp >= 0.0):  # NaN would spread to every pixel of the gather
            raise ValueError(f"clamp must be a finite number of at least 0 (got {self.clamp})")


def clamp_distance(surface_area: float, count: int, clamp: float) -> float:
    """d_min = clamp * sqrt(area / (pi N)): the radius of the disc each of N VPLs stands for."""
    if clamp <= 0.0 or count <= 0:
        return 0.0
    return clamp * float(np.sqrt(surface_area / (np.pi * count)))


def connect(p, ng, ns, smooth, q, nq, intensity, tracer, d_min: float) -> np.ndarray:
    """(M,3) light from VPLs (q, nq, intensity) to points (p, ng, ns, smooth normal), pairwise row by row; the
    receiver's cos with the bump shadowing term (``surface.diffuse_cosine``)."""
    w = q - p
    d2 = dot(w, w)
    d = np.sqrt(d2)
    w = w / np.maximum(d, 1e-300)[:, None]
    cos_x = diffuse_cosine(ns, smooth, w)
    cos_v = -dot(nq, w)
    ok = np.nonzero((cos_x > 0.0) & (cos_v > 0.0) & (dot(ng, w) > 0.0) & (d > 0.0))[0]
    out = np.zeros((len(p), 3))
    if len(ok) == 0:
        return out
    g = cos_x[ok] * cos_v[ok] / (np.pi * np.maximum(d2[ok], d_min * d_min))
    vis = tracer.visible(p[ok], ng[ok], w[ok], d[ok], nq[ok])
    out[ok] = intensity[ok] * (g * vis)[:, None]
    return out


def gather_pairs(surface, point_index, vpls, vpl_index, tracer, d_min) -> np.ndarray:
    """Light of the pairs (point_index[i], vpl_index[i])."""
    s = surface
    return connect(s.position[point_index], s.geometric_normal[point_index], s.shading_normal[point_index],
                   s.smooth_normal[point_index], vpls.position[vpl_index], vpls.normal[vpl_index],
                   vpls.intensity[vpl_index], tracer, d_min)


def sum_pairs(surface, point_index, vpls, vpl_index, tracer, d_min, group, count) -> np.ndarray:
    """(count,3): the light of the pairs (point_index[i], vpl_index[i]) summed by ``group[i]`` (a point or a VPL
    index), evaluated in batches so memory stays flat however many pairs there are."""
    out = np.zeros((count, 3))
    for lo in range(0, len(point_index), PAIRS_PER_BATCH):
        hi = lo + PAIRS_PER_BATCH
        light = gather_pairs(surface, point_index[lo:hi], vpls, vpl_index[lo:hi], tracer, d_min)
        out += group_sum(group[lo:hi], light, count)
    return out


def _sum_over(surface, points, vpls, subset, tracer, d_min, out, scale):
    """out[points] += scale * sum over the VPLs ``subset`` of their light, a slice of points at a time."""
    if len(points) == 0 or len(subset) == 0:
        return
    step = max(1, PAIRS_PER_BATCH // len(subset))
    for lo in range(0, len(points), step):
        pts = points[lo:lo + step]
        local = np.repeat(np.arange(len(pts)), len(subset))
        out[pts] += scale * sum_pairs(surface, pts[local], vpls, np.tile(subset, len(pts)), tracer, d_min, local,
                                      len(pts))


def gather(surface, pixel_xy, vpls, tracer, settings: GatherSettings, d_min: float,
           permutation: np.ndarray) -> np.ndarray:
    """(K,3) indirect light at every surface point.

    ``pixel_xy`` (K,2) integer pixel coordinates pick each point's interleaving subset; ``permutation`` is a random
    order of the VPLs shared by the whole image, so every tile position sees the same disjoint subset."""
    out = np.zeros((len(surface), 3))
    if len(vpls) == 0 or len(surface) == 0:
        return out
    t = max(1, int(settings.interleave))
    if t == 1:
        _sum_over(surface, np.arange(len(surface)), vpls, np.arange(len(vpls)), tracer, d_min, out, 1.0)
        return out
    groups = t * t
    subsets = min(groups, len(vpls))  # fewer VPLs than tile positions: positions share them cyclically
    tile_of_point = (pixel_xy[:, 1] % t) * t + (pixel_xy[:, 0] % t)
    for g in range(groups):
        subset = permutation[g % subsets::subsets]
        if len(subset):
            points = np.nonzero(tile_of_point == g)[0]
            _sum_over(surface, points, vpls, subset, tracer, d_min, out, len(vpls) / len(subset))
    return out
