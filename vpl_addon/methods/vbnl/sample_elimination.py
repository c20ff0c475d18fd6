"""Adaptive sample elimination: M candidate positions -> a blue-noise subset of N (Li et al., Virtual Blue Noise
Lighting, HPG 2022, sec. 3.2, after Yuksel, Sample Elimination for Generating Poisson Disk Sample Sets, 2015).

Each candidate i gets a maximum Poisson-disk radius from its local density (eq. 2): with d_i the distance to its
m-th nearest candidate, A_i = pi d_i^2 and ``r_i = sqrt(M A_i / (2 sqrt(3) N m))``; *uniform* elimination uses one
radius for all, from the estimated total area (eq. 1). Yuksel's weight of a candidate sums
``(1 - d_ij / (2 r_i))^8`` over the other live candidates within ``2 r_i``; the candidate of largest weight is removed
and its neighbours' weights drop.

Removal goes one candidate at a time, the greedy order of Yuksel's algorithm itself, in a compiled kernel
(``core.compiled``) with a max-heap of weights: a weight only drops, so a popped candidate whose weight dropped since
it was pushed goes back with its current weight, and the first popped with a current weight is the heaviest. The
paper parallelises the elimination over the boxes of a k-d tree; the sequential greedy takes 40,960 -> 4,096
(the defaults' candidates in the Cornell box) in about 60 ms of one core, and 1M -> 100K in about 3 s
(bench/vbnl_stages.py). Neighbour lists come once from scipy's k-d tree, queried in the tree's own order for
locality: that query of every candidate's 41 nearest costs two to three times the elimination itself.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ...core.compiled import kernel

WEIGHT_EXPONENT = 8  # Yuksel 2015, alpha in w = (1 - d / 2r)^alpha
STEP = 8192  # candidates queried or removed between checkpoints: a few tens of ms
MODES = ("adaptive", "uniform", "none")


@dataclass
class Elimination:
    keep: np.ndarray  # (N,) indices of the kept candidates
    r_max: np.ndarray  # (N,) their maximum Poisson-disk radius (eq. 2, or eq. 1 for uniform elimination)


def eliminate(points: np.ndarray, count: int, rng: np.random.Generator, mode: str = "adaptive",
              local: int = 32, neighbours: int = 40, checkpoint=lambda: None) -> Elimination:
    """Keep ``count`` of ``points`` (M,3). ``mode``: adaptive (eq. 2), uniform (eq. 1) or none (a random subset,
    the ablation of Fig. 18); ``local`` is m of eq. 2, ``neighbours`` how many nearest candidates a weight sums.
    ``checkpoint()`` is called between slices of the work (``STEP`` candidates queried or removed): it may raise to
    stop it (the viewport's ``Tracer.checkpoint``)."""
    if mode not in MODES:
        raise ValueError(f"unknown sample elimination {mode!r}; choose one of {', '.join(MODES)}")
    points = np.asarray(points, np.float64)
    total = len(points)
    count = int(min(max(count, 0), total))
    if count == 0:
        return Elimination(np.zeros(0, np.int64), np.zeros(0))
    tree = cKDTree(points)
    order = tree.indices  # work in the tree's order: neighbours are close in memory
    k = int(min(max(local, neighbours) + 1, total))
    dist, near = np.empty((total, k)), np.empty((total, k), np.int64)
    for lo in range(0, total, STEP):
        dist[lo:lo + STEP], near[lo:lo + STEP] = tree.query(points[order[lo:lo + STEP]], k=k, workers=-1)
        checkpoint()
    rank = np.empty(total, np.int64)
    rank[order] = np.arange(total)
    near = rank[near]  # neighbours as positions in the tree order
    extent = float(np.linalg.norm(np.ptp(points, axis=0))) if total > 1 else 1.0
    floor = 1e-9 * max(extent, 1e-30)
    m = min(local, k - 1)
    area = np.pi * dist[:, m] ** 2 if m > 0 else np.full(total, extent ** 2)  # A_i of eq. 2
    if mode == "uniform":
        area = np.full(total, area.mean())
    r_max = np.maximum(np.sqrt(total * area / (2.0 * np.sqrt(3.0) * count * max(m, 1))), floor)
    if mode == "none" or count == total:
        keep = np.sort(rng.choice(total, count, replace=False)) if count < total else np.arange(total)
        return Elimination(order[keep], r_max[keep])
    heap = _weights(dist, near, r_max)
    alive, size = np.ones(total, np.bool_), total
    while size > count:
        size = _remove(*heap, alive, size, max(count, size - STEP))
        checkpoint()
    kept = np.nonzero(alive)[0]
    return Elimination(order[kept], r_max[kept])


@kernel
def _term(d, r):
    """Yuksel's weight of a neighbour at distance ``d`` from a candidate of radius ``r``: (1 - d / 2r)^8 within 2r,
    else 0."""
    return (1.0 - d / (2.0 * r)) ** WEIGHT_EXPONENT if d < 2.0 * r else 0.0


@kernel
def _weights(dist, near, r_max):
    """Yuksel's greedy elimination set up: each candidate's weight (``_term`` summed over its list ``dist``/``near``
    (M,k) of nearest candidates, itself among them and skipped), who counts whom (removing j lowers the weight of
    every i whose list holds j by j's term: ``listed_by``/``listed_term`` from ``start[j]``) and the max-heap of
    the weights (``key``, ``ids``). Returns (weight, start, listed_by, listed_term, key, ids)."""
    total, k = near.shape
    weight = np.zeros(total)
    start = np.zeros(total + 1, np.int64)
    for i in range(total):
        for q in range(k):
            t = _term(dist[i, q], r_max[i])
            if near[i, q] != i and t > 0.0:
                weight[i] += t
                start[near[i, q] + 1] += 1
    start = np.cumsum(start)
    listed_by, listed_term, fill = np.empty(start[-1], np.int64), np.empty(start[-1]), start[:-1].copy()
    for i in range(total):
        for q in range(k):
            t = _term(dist[i, q], r_max[i])
            j = near[i, q]
            if j != i and t > 0.0:
                listed_by[fill[j]], listed_term[fill[j]] = i, t
                fill[j] += 1
    key, ids = weight.copy(), np.arange(total)
    for pos in range(total // 2 - 1, -1, -1):
        _sift_down(key, ids, total, pos)
    return weight, start, listed_by, listed_term, key, ids


@kernel
def _remove(weight, start, listed_by, listed_term, key, ids, alive, size, until):
    """Removes the heaviest candidate until ``until`` of the heap's ``size`` remain (``alive`` marks them) and
    returns ``until``: a popped candidate whose weight dropped since it was pushed goes back with its current
    weight, so the first popped with a current weight is the heaviest."""
    while size > until:
        i = ids[0]
        if key[0] > weight[i]:
            key[0] = weight[i]
        else:
            alive[i] = False
            size -= 1
            key[0], ids[0] = key[size], ids[size]
            for e in range(start[i], start[i + 1]):
                weight[listed_by[e]] -= listed_term[e]
        _sift_down(key, ids, size, 0)
    return size


@kernel
def _sift_down(key, ids, size, pos):
    """Moves the entry at ``pos`` of the max-heap (``key``, ``ids``) of ``size`` entries down to its place."""
    top, top_id = key[pos], ids[pos]
    while 2 * pos + 1 < size:
        child = 2 * pos + 1
        if child + 1 < size and key[child + 1] > key[child]:
            child += 1
        if key[child] <= top:
            break
        key[pos], ids[pos] = key[child], ids[child]
        pos = child
    key[pos], ids[pos] = top, top_id
