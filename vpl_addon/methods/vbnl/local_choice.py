"""Which photon light a gather's light sample goes to, by the light each can bring to the point's neighbourhood.

Li et al. choose a light by its power alone (eq. 4): P_j / sum P wherever the point is. A point then draws lights
that cannot light it (behind it, in its own plane, far off) as often as the lights beside it, and its BSDF sample
does the work: on cornell_area's boxes the light a face gets from the floor in front of it, on the ceiling the bright
patch under the lamp. Here the points are put in cells (cubes of ``CELL`` median light radii, and the axis their
normal leans to most, with its sign), and each cell draws light j with probability

    p_j = (1 - LOCAL) P_j / sum P + LOCAL q_j,  q_j ~ P_j cos+(theta_x) cos+(theta_j) / (d^2 + c^2 + r_j^2),

the light the cell's centre x (with the cell's axis for a normal) would get from j, unshadowed: d the distance from
x to the light's centre, theta_x the angle at x from the cell's axis, theta_j the angle at the light from its
normal, c the cell's side and r_j the light's radius (so a light in or near the cell is not a spike). It is a
spatial cache of light-selection probabilities (as in Vevoda, Kondapaneni and Krivanek 2018, "Bayesian online
regression for adaptive direct illumination sampling", but computed from the lights' bounds, not learned), kept
robust by the power choice mixed in (defensive importance sampling, Hesterberg 1995): a light the estimate misses
(one the cell's axis turns from, though some of its points face it) keeps a tenth of its power's share. The
probabilities are exact for any point of the cell, so the multiple importance sampling of eq. 5 stays unbiased.

A cell's lights are drawn down the same tree of the lights as the power choice (``virtual_light_sampling._descend``,
with the cell's cumulative probabilities in the tree's order), so a sequence's next frame draws the same lights
where the probabilities changed little. Only the camera's points choose by cell (``virtual_light_sampling``): they
come many to a cell, where the vertices of extended paths come few, and their tables cost more than they gave.
Measured on the five example scenes (2 seeds, bench/README.md, "Thirty-second session"): the denoised Combined's
error in 4 x 4 blocks 2-5 % lower at 64 samples, 2-11 % at 16, for 0-5 % more time.
"""
from __future__ import annotations

import numpy as np
from numba import types
from numba.typed import Dict

from ...core.compiled import kernel

LOCAL = 0.9  # the share of a cell's choice made by the light each light brings to it (the rest: by power)
CELL = 2.0  # a cell's side, in median light radii
MOST_ENTRIES = 1 << 22  # about the most cells x lights of a scene's tables (32 MB): more lights, larger cells


def cell_side(lights) -> float:
    """A cell's side: ``CELL`` median light radii, or more where the lights are many, so that the cells of the
    lights' surface (its area the sum of their catchments, or of a quarter of their discs) times the lights stay
    within ``MOST_ENTRIES``."""
    area = float(lights.catchment.sum()) if lights.catchment is not None else \
        float(np.pi * np.sum(lights.radius * lights.radius)) / 4.0
    return max(CELL * float(np.median(lights.radius)), np.sqrt(max(area, 0.0) * len(lights) / MOST_ENTRIES))


def local_choice(position: np.ndarray, normal: np.ndarray, lights, choice: np.ndarray, order: np.ndarray,
                 box: tuple, cells: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(row (K,), table (R, N), cdf (R, N + 1)): the cell of each of the K points at ``position`` with unit
    ``normal`` (cubes of ``cell_side`` from the corner of the scene's ``box``, and the axis the normal leans to
    most, with its sign), each cell's probabilities of the N ``lights`` (the power choice ``choice`` mixed with the
    light they bring to the cell's centre, seen with the axis for its normal), and their cumulative sums in the
    tree's ``order`` for ``_descend``. A point's row depends on the point alone, not on the others of its batch,
    so a path draws the same lights whatever paths are traced with it. Without ``cells`` or power, one row: the
    power choice."""
    k, n = len(position), len(choice)
    if not cells or k == 0 or n == 0 or not choice.any():
        return np.zeros(k, np.int64), choice[None, :], np.r_[0.0, np.cumsum(choice[order])][None, :]
    lo, hi = (np.asarray(b, np.float64) for b in box)
    side = max(cell_side(lights), float(np.max(hi - lo)) / 65536.0, 1e-300)  # the keys fit in 64 bits
    dims = np.floor((hi - lo) / side).astype(np.int64) + 1
    row, cells = _cells(position, normal, lo, side, dims)
    table, cdf = _table(cells, lo, side, dims, lights.position, lights.normal, lights.radius, choice, order, LOCAL)
    return row, table, cdf


@kernel
def _cells(position, normal, lo, side, dims):
    """(row (K,), cells (R,)): each point's cell key (its cube's index from ``lo`` in cubes of ``side``, within
    ``dims``, times 6, plus twice the axis its normal leans to most and 1 for that axis' minus side) as a row into
    the cells' keys in the order they first come (points of one cell mostly come one after another)."""
    k = len(position)
    row, keys = np.empty(k, np.int64), np.empty(k, np.int64)
    rows = Dict.empty(key_type=types.int64, value_type=types.int64)
    count, last, last_row = 0, -1, -1
    for i in range(k):
        c0 = min(max(int(np.floor((position[i, 0] - lo[0]) / side)), 0), dims[0] - 1)
        c1 = min(max(int(np.floor((position[i, 1] - lo[1]) / side)), 0), dims[1] - 1)
        c2 = min(max(int(np.floor((position[i, 2] - lo[2]) / side)), 0), dims[2] - 1)
        axis = 0
        for a in range(1, 3):
            if abs(normal[i, a]) > abs(normal[i, axis]):
                axis = a
        key = ((c0 * dims[1] + c1) * dims[2] + c2) * 6 + 2 * axis + (1 if normal[i, axis] < 0.0 else 0)
        if key != last:
            found = rows.get(key, np.int64(-1))
            if found < 0:
                found = count
                rows[key] = count
                keys[count] = key
                count += 1
            last, last_row = key, found
        row[i] = last_row
    return row, keys[:count].copy()


@kernel
def _table(cells, lo, side, dims, centre, normal, radius, choice, order, local):
    """(table (R, N), cdf (R, N + 1)): each cell's probabilities (1 - local) choice_j + local q_j (the module's
    formula, at the cell's centre with its axis for a normal), and their cumulative sums in the tree's ``order``."""
    n = len(choice)
    table, cdf = np.empty((len(cells), n)), np.zeros((len(cells), n + 1))
    for c in range(len(cells)):
        cube, bin_ = cells[c] // 6, cells[c] % 6
        x0 = lo[0] + (cube // (dims[1] * dims[2]) + 0.5) * side
        x1 = lo[1] + (cube // dims[2] % dims[1] + 0.5) * side
        x2 = lo[2] + (cube % dims[2] + 0.5) * side
        axis, sign = bin_ // 2, -1.0 if bin_ % 2 == 1 else 1.0
        total = 0.0
        for j in range(n):
            d0, d1, d2 = centre[j, 0] - x0, centre[j, 1] - x1, centre[j, 2] - x2
            dist2 = d0 * d0 + d1 * d1 + d2 * d2
            length = np.sqrt(dist2)
            q = 0.0
            if length > 0.0 and choice[j] > 0.0:
                cos_x = sign * (d0 if axis == 0 else d1 if axis == 1 else d2) / length
                cos_j = -(d0 * normal[j, 0] + d1 * normal[j, 1] + d2 * normal[j, 2]) / length
                if cos_x > 0.0 and cos_j > 0.0:
                    q = choice[j] * cos_x * cos_j / (dist2 + side * side + radius[j] * radius[j])
            table[c, j] = q
            total += q
        for j in range(n):
            table[c, j] = (1.0 - local) * choice[j] + local * table[c, j] / total if total > 0.0 else choice[j]
        for p in range(n):
            cdf[c, p + 1] = cdf[c, p] + table[c, order[p]]
    return table, cdf
