"""Flat squares in a light pass (issue 70): the mark a filter leaves when it spreads one sample over its window.

A window of ``size`` x ``size`` pixels is a flat block when its largest inner pixel-to-pixel step is below a quarter
of the step across its border while that border step is a fifth of its level or more, on each of its four sides
(the median step along a side). A smooth gradient, single bright pixels or geometric edges along some of its
sides (a corner of the room) do not qualify; the filter's squares on the helmet under its HDR had border steps 27
to 1,680 times their inner ones, all around.
"""
from __future__ import annotations

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view as windows


def flat_blocks(image: np.ndarray, size: int) -> list[tuple[int, int]]:
    """The top-left corners (row, column) of the flat ``size`` x ``size`` windows of ``image`` (H,W,C), judged on
    its mean over the first three channels; windows touching the image's edge have no border and are not judged."""
    y = np.asarray(image, np.float64)[..., :3].mean(axis=-1)
    h, w = y.shape
    if h < size + 2 or w < size + 2:
        return []
    dx, dy = np.abs(np.diff(y, axis=1)), np.abs(np.diff(y, axis=0))
    rows, cols = np.mgrid[1:h - size, 1:w - size]
    inner = np.maximum(windows(dx, (size, size - 1)).max(axis=(-2, -1))[rows, cols],
                       windows(dy, (size - 1, size)).max(axis=(-2, -1))[rows, cols])
    down, across = windows(dx, size, axis=0), windows(dy, size, axis=1)  # columns of dx, rows of dy
    sides = (down[rows, cols - 1], down[rows, cols + size - 1], across[rows - 1, cols], across[rows + size - 1, cols])
    border = np.min([np.median(side, axis=-1) for side in sides], axis=0)
    level = windows(y, (size, size)).mean(axis=(-2, -1))[rows, cols]
    flat = (border > 0.2 * level) & (level > 0.0) & (inner < 0.25 * border)
    return [(int(i), int(j)) for i, j in zip(rows[flat], cols[flat])]
