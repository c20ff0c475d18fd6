"""Colour: luminance of linear RGB in Blender's scene space (Rec. 709 primaries), and the sRGB transfer function."""
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


def limit_scale(rgb: np.ndarray, limit: float) -> np.ndarray:
    """(N,) the factor that brings each row of ``rgb`` (N,3) down to ``limit`` in its largest channel, the colour
    kept: 1 where it is no brighter, and everywhere for ``limit`` 0 (no limit), as Cycles' clamping."""
    scale = np.ones(len(rgb))
    if limit > 0.0:
        level = largest(rgb)
        over = level > limit
        scale[over] = limit / level[over]
    return scale


def linear_to_srgb(c: np.ndarray) -> np.ndarray:
    """sRGB-encoded values of linear ones in [0, 1] (the inverse of ``srgb_to_linear``; clip first)."""
    c = np.asarray(c)
    return np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.maximum(c, 0.0031308) ** (1 / 2.4) - 0.055)


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """Linear values of sRGB-encoded ones (the IEC 61966-2-1 transfer function, as Blender's colour management)."""
    c = np.asarray(c)
    return np.where(c <= 0.04045, c / 12.92, ((np.maximum(c, 0.04045) + 0.055) / 1.055) ** 2.4).astype(c.dtype)
