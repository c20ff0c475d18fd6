"""Seams stitched: a surface point that the UV map holds at two places (an edge its two triangles meet along in
space but not in the map) gets one value at both, so a texture filter does not show a line where the islands meet.

As the seam stitching of Godot's and Unreal's lightmappers does it in its simplest form: along each seam edge, at a
step of half a texel, the texel under the edge's point on one side and the texel under the same point on the other
are each given the mean of the two; a texel that several such pairs meet takes the mean of all of theirs. Both
sides then hold the same light along the seam.
"""
from __future__ import annotations

import numpy as np


def seam_pairs(triangles: np.ndarray, uvs: np.ndarray, size: int) -> np.ndarray:
    """(P,2) flat texel indices (``y * size + x``, y from v = 0) of the texel pairs across the seams of one
    object's ``triangles`` (T,3,3) with ``uvs`` (T,3,2): each edge that two triangles share in space with different
    UVs, sampled every half texel."""
    corners = np.round(triangles.astype(np.float64), 5)
    ends = np.stack([np.roll(np.arange(3), -k)[:2] for k in range(3)])  # (3,2): edges 01, 12, 20
    a, b = corners[:, ends[:, 0]].reshape(-1, 3), corners[:, ends[:, 1]].reshape(-1, 3)
    ua, ub = uvs[:, ends[:, 0]].reshape(-1, 2), uvs[:, ends[:, 1]].reshape(-1, 2)
    swap = _later(a, b)  # each edge from its lower corner to its higher one, so both sides run the same way
    a, b = np.where(swap[:, None], b, a), np.where(swap[:, None], a, b)
    ua, ub = np.where(swap[:, None], ub, ua), np.where(swap[:, None], ua, ub)
    key = np.concatenate([a, b], axis=1)
    order = np.lexsort(key.T[::-1])
    same = np.all(key[order[1:]] == key[order[:-1]], axis=1)
    first, second = order[:-1][same], order[1:][same]
    split = ~np.all(np.isclose(ua[first], ua[second]) & np.isclose(ub[first], ub[second]), axis=1)
    first, second = first[split], second[split]
    pairs = []
    for i, j in zip(first, second):
        steps = int(np.ceil(2.0 * size * max(np.linalg.norm(ub[i] - ua[i]), np.linalg.norm(ub[j] - ua[j])))) + 1
        t = (np.arange(steps) + 0.5)[:, None] / steps
        pairs.append(np.stack([_texel(ua[i] + t * (ub[i] - ua[i]), size), _texel(ua[j] + t * (ub[j] - ua[j]), size)],
                              axis=1))
    return np.concatenate(pairs) if pairs else np.zeros((0, 2), np.int64)


def _later(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(E,) whether point ``a`` comes after ``b`` in lexicographic order (x, then y, then z)."""
    later = np.zeros(len(a), bool)
    decided = np.zeros(len(a), bool)
    for c in range(3):
        later |= ~decided & (a[:, c] > b[:, c])
        decided |= a[:, c] != b[:, c]
    return later


def _texel(uv: np.ndarray, size: int) -> np.ndarray:
    xy = np.clip(np.floor(uv * size).astype(np.int64), 0, size - 1)
    return xy[:, 1] * size + xy[:, 0]


def stitch(image: np.ndarray, pairs: np.ndarray, filled: np.ndarray) -> np.ndarray:
    """(size*size,3) ``image`` (flat, y from v = 0) with both texels of every seam pair that are ``filled`` set to
    the mean of their pairs' means."""
    pairs = pairs[filled[pairs[:, 0]] & filled[pairs[:, 1]]]
    if not len(pairs):
        return image
    mean = 0.5 * (image[pairs[:, 0]] + image[pairs[:, 1]])
    at = pairs.reshape(-1)
    total = np.zeros_like(image)
    np.add.at(total, at, np.repeat(mean, 2, axis=0))
    count = np.bincount(at, minlength=len(image))
    out = image.copy()
    seen = count > 0
    out[seen] = total[seen] / count[seen, None]
    return out
