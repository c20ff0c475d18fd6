"""Adaptive sample elimination: M candidate positions -> a blue-noise subset of N (Li et al., Virtual Blue Noise
Lighting, HPG 2022, sec. 3.2, after Yuksel, Sample Elimination for Generating Poisson Disk Sample Sets, 2015).

Each candidate i gets a maximum Poisson-disk radius from its local density (eq. 2): with d_i the distance to its
m-th nearest candidate, A_i = pi d_i^2 and ``r_i = sqrt(M A_i / (2 sqrt(3) N m))``; *uniform* elimination uses one
radius for all, from the estimated total area (eq. 1). Yuksel's weight of a candidate sums
``(1 - d_ij / (2 r_i))^8`` over the other live candidates within ``2 r_i``; the candidate of largest weight is removed
and its neighbours' weights drop.

Greedy removal one at a time is sequential. The paper parallelises it over the boxes of a k-d tree; here it is
vectorised instead: every round removes, among the live candidates of largest weight, those whose weight beats all
their live neighbours' (so no two neighbours go in the same round), at most ``round_fraction`` of the live set per
round. With 5 % per round the result has the same nearest-neighbour statistics as the sequential greedy
(tests/test_vbnl.py), and 1M -> 100K takes seconds (bench/vbnl_stages.py). Neighbour lists come once from scipy's
k-d tree, queried in the tree's own order for locality.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import csr_matrix
from scipy.spatial import cKDTree

WEIGHT_EXPONENT = 8  # Yuksel 2015, alpha in w = (1 - d / 2r)^alpha
RIVALS = 16  # nearest live neighbours a candidate must outweigh to go in a round
MODES = ("adaptive", "uniform", "none")


@dataclass
class Elimination:
    keep: np.ndarray  # (N,) indices of the kept candidates
    r_max: np.ndarray  # (N,) their maximum Poisson-disk radius (eq. 2, or eq. 1 for uniform elimination)


def eliminate(points: np.ndarray, count: int, rng: np.random.Generator, mode: str = "adaptive",
              local: int = 32, neighbours: int = 40, round_fraction: float = 0.05) -> Elimination:
    """Keep ``count`` of ``points`` (M,3). ``mode``: adaptive (eq. 2), uniform (eq. 1) or none (a random subset,
    the ablation of Fig. 18); ``local`` is m of eq. 2, ``neighbours`` how many nearest candidates a weight sums."""
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
    dist, near = tree.query(points[order], k=k, workers=-1)
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
    kept = _eliminate_rounds(dist[:, 1:], near[:, 1:], r_max, count, round_fraction)
    return Elimination(order[kept], r_max[kept])


def _eliminate_rounds(dist, near, r_max, count, round_fraction):
    """Positions (in tree order) of the ``count`` survivors; ``dist``/``near`` are each candidate's neighbours."""
    total = len(r_max)
    # Yuksel's weight terms (1 - d / 2r_i)^8 of the pairs within 2 r_i, in float32 (the heavy (M,k) arrays)
    near = near.astype(np.int32)
    ratio = dist.astype(np.float32) / (2.0 * r_max[:, None]).astype(np.float32)
    self_pair = near == np.arange(total, dtype=np.int32)[:, None]  # duplicates can push one off column 0
    pair = (ratio < 1.0) & ~self_pair
    rows = np.repeat(np.arange(total, dtype=np.int32), pair.sum(axis=1))  # boolean masks keep row-major order
    term = 1.0 - ratio[pair]
    term *= term
    term *= term
    term *= term
    weight = np.bincount(rows, term, total)
    # who counts whom: removing j lowers the weight of every i whose list holds j (a CSR matrix by j)
    counted = csr_matrix((term, (near[pair], rows)), shape=(total, total))
    starts, listed_by, listed_weight = counted.indptr, counted.indices, counted.data
    neighbour = np.where(self_pair, -1, near)
    alive = np.ones(total, bool)
    live = np.arange(total)
    excess = total - count
    while excess > 0:
        cap = min(excess, max(1, int(round_fraction * len(live))))
        look = min(len(live), 3 * cap)
        top = live[np.argpartition(-weight[live], look - 1)[:look]] if look < len(live) else live
        others = neighbour[top, :RIVALS]
        rival = np.where(others >= 0, alive[np.maximum(others, 0)], False)
        other_weight = weight[np.maximum(others, 0)]
        beats = (weight[top][:, None] > other_weight) | ((weight[top][:, None] == other_weight) &
                                                          (top[:, None] > others))
        winners = top[np.all(beats | ~rival, axis=1)]
        if len(winners) == 0:  # ties left the top out of the look window: the greedy choice itself
            winners = live[np.lexsort((live, weight[live]))[-1:]]
        if len(winners) > cap:
            winners = winners[np.argsort(-weight[winners], kind="stable")[:cap]]
        alive[winners] = False
        excess -= len(winners)
        lo, hi = starts[winners], starts[winners + 1]
        span = np.repeat(lo - np.cumsum(np.r_[0, (hi - lo)[:-1]]), hi - lo) + np.arange((hi - lo).sum())
        weight -= np.bincount(listed_by[span], listed_weight[span], total)
        live = live[alive[live]]
    return np.nonzero(alive)[0]
