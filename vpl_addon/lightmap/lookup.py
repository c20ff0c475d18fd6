"""A baked map read at UV points, as a game engine's texture unit reads a lightmap: bilinear between the four texel
centres around each point, clamped at the map's border. The colour-attribute target takes its value per mesh corner
so (``lookup``), and per vertex as the mean of the vertex's corners (``per_vertex``): the colour attribute then holds
the denoised, dilated, stitched map's light, not an unfiltered sample per vertex.

Texel (x, y) of a map whose row 0 is at v = 1 (``LightmapResult.images``) has its centre at
u = (x + 0.5) / width, v = 1 - (y + 0.5) / height.
"""
from __future__ import annotations

import numpy as np

from ..core.sampling import group_sum


def lookup(image: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """(N,C) ``image`` (H,W,C, row 0 at v = 1) at ``uv`` (N,2): bilinear, UVs outside [0, 1] clamped to the border,
    non-finite UVs read as (0, 0)."""
    height, width = image.shape[:2]
    uv = np.nan_to_num(np.asarray(uv, np.float64), nan=0.0, posinf=1.0, neginf=0.0)
    x = np.clip(uv[:, 0], 0.0, 1.0) * width - 0.5
    y = (1.0 - np.clip(uv[:, 1], 0.0, 1.0)) * height - 0.5
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    x0, y0 = x0.astype(np.int64), y0.astype(np.int64)
    xs, ys = np.clip([x0, x0 + 1], 0, width - 1), np.clip([y0, y0 + 1], 0, height - 1)
    top = image[ys[0], xs[0]] * (1.0 - fx) + image[ys[0], xs[1]] * fx
    bottom = image[ys[1], xs[0]] * (1.0 - fx) + image[ys[1], xs[1]] * fx
    return top * (1.0 - fy) + bottom * fy


def per_vertex(corner_values: np.ndarray, corner_vertex: np.ndarray, vertices: int) -> np.ndarray:
    """(vertices, C) the mean of each vertex's corners' values (zero for a vertex no corner uses)."""
    counts = np.bincount(corner_vertex, minlength=vertices)[:, None]
    return group_sum(corner_vertex, corner_values, vertices) / np.maximum(counts, 1)
