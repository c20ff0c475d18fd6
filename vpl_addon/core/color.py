"""Colour: luminance of linear RGB in Blender's scene space (Rec. 709 primaries)."""
from __future__ import annotations

import numpy as np

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])  # Rec. 709, the primaries of Blender's linear scene space


def luminance(rgb: np.ndarray) -> np.ndarray:
    """Luminance of the first three channels (RGB or RGBA), in float64."""
    return np.asarray(rgb, np.float64)[..., :3] @ LUMINANCE


def largest(rgb: np.ndarray) -> np.ndarray:
    """(N,) the largest of the three channels of each row of ``rgb`` (N,3): ``rgb.max(axis=1)``, NaN included, in
    one pass per channel (numpy reduces a last axis of three about 20 times slower)."""
    return np.maximum(np.maximum(rgb[:, 0], rgb[:, 1]), rgb[:, 2])
