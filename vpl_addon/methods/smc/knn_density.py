"""k-nearest-neighbour density of VPLs on surfaces (Hedman, Karras, Lehtinen, Sequential Monte Carlo Instant
Radiosity, sec. 3.2.4, eq. 7): as in photon mapping, the k nearest VPLs found by an unconstrained 3D search are
assumed to lie on the same plane, so the density with respect to area of a point y among I VPLs is

    p(y) ~ k / (I pi r_k(y)^2),

r_k the distance to the k-th nearest VPL. k = 1 for candidates (a candidate close to any current VPL is unlikely to
be chosen: blue-noise-like spacing); for rendering k = max(1, floor(sqrt(I) / 32)) (eq. 8), a consistent choice.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree


def rendering_k(count: int) -> int:
    """Eq. 8."""
    return max(1, int(np.floor(np.sqrt(max(count, 0)) / 32.0)))


def knn_radius(points: np.ndarray, among: np.ndarray, k: int, exclude_self: bool = False) -> np.ndarray:
    """Distance from each point to its k-th nearest neighbour in ``among`` (the point itself not counted when
    ``exclude_self``, i.e. ``points`` is ``among``); inf where there are too few neighbours."""
    points, among = np.asarray(points, np.float64), np.asarray(among, np.float64)
    wanted = k + (1 if exclude_self else 0)
    if len(points) == 0:
        return np.zeros(0)
    if len(among) < wanted:
        return np.full(len(points), np.inf)
    dist, _ = cKDTree(among).query(points, k=wanted)
    return dist if dist.ndim == 1 else dist[:, -1]


def knn_radii(points: np.ndarray, ks: tuple[int, ...], workers: int = 1) -> tuple[np.ndarray, ...]:
    """``knn_radius(points, points, k, exclude_self=True)`` for each k of ``ks``, from one query of the largest (on
    ``workers`` threads)."""
    points = np.asarray(points, np.float64)
    if len(points) <= max(ks):
        return tuple(knn_radius(points, points, k, exclude_self=True) for k in ks)
    dist, _ = cKDTree(points).query(points, k=max(ks) + 1, workers=workers)
    return tuple(dist[:, k] for k in ks)


def knn_density(points: np.ndarray, among: np.ndarray, k: int, total: int, exclude_self: bool = False,
                floor: float = 0.0) -> np.ndarray:
    """Eq. 7: p(y) = k / (total pi r_k^2), with r_k at least ``floor`` (coincident points would give infinity)."""
    r = np.maximum(knn_radius(points, among, k, exclude_self), floor)
    with np.errstate(divide="ignore"):
        return k / (max(total, 1) * np.pi * r * r)
