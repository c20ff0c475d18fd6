"""Islands of a baked map grown into the empty texels around them, as Cycles' bake margin (``Extend``) does: a
texture filter (mipmaps, bilinear lookups) that reads across an island's edge then reads its own light, not the
background's black.

Each step fills every empty texel with a filled neighbour (of its eight) by the mean of its filled neighbours, so
the ring grows a texel a step, the islands' edge values carried outward.
"""
from __future__ import annotations

import numpy as np

NEIGHBOURS = tuple((dy, dx) for dy in (-1, 0, 1) for dx in (-1, 0, 1) if dy or dx)


def dilate(image: np.ndarray, filled: np.ndarray, margin: int) -> np.ndarray:
    """(H,W,C) ``image`` with its texels not ``filled`` (H,W bool) within ``margin`` texels of a filled one set
    from their filled neighbours, step by step; the filled ones as they are."""
    out = np.array(image, np.float64)
    filled = np.array(filled, bool)
    h, w = filled.shape
    for _ in range(max(0, int(margin))):
        if filled.all() or not filled.any():
            break
        total = np.zeros_like(out)
        count = np.zeros((h, w))
        padded = np.pad(out, ((1, 1), (1, 1), (0, 0)))
        mask = np.pad(filled, 1)
        for dy, dx in NEIGHBOURS:
            seen = mask[1 + dy:1 + dy + h, 1 + dx:1 + dx + w]
            total += np.where(seen[..., None], padded[1 + dy:1 + dy + h, 1 + dx:1 + dx + w], 0.0)
            count += seen
        grow = ~filled & (count > 0)
        out[grow] = total[grow] / count[grow, None]
        filled = filled | grow
    return out
