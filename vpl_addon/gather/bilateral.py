"""Geometry-aware cross-bilateral filter that removes the tile pattern of interleaved sampling.

Each pixel averages the 2t x 2t window around it, which holds every VPL subset exactly four times (so a flat area
weighs all subsets alike, and a pixel at a corner, whose neighbours on other surfaces are refused, still finds
most of them), weighting a neighbour by how well it lies on the pixel's own surface: its distance from the pixel's
tangent plane (relative to the pixel's footprint on the surface) and the agreement of normals. Neighbours across
depth or orientation discontinuities get little weight, so light does not bleed around corners (Segovia et al.
2006; Hedman et al. 2017 sec. 4).

The filter runs once per frame, after the blocks: a compiled kernel (``core.compiled``) filters bands of rows on a
thread pool, one band per thread.
"""
from __future__ import annotations

import math
import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from scipy.ndimage import rank_filter, uniform_filter

from ..core.color import largest
from ..core.compiled import kernel

PLANE_SIGMA = 2.0  # tangent-plane distance, in pixel footprints, at which a neighbour's weight falls to 1/e
NORMAL_POWER = 16  # weight ~ (n . n')^power
UNDERFLOW = 746.0  # exp(-x) is 0 in float64 beyond this
BRIGHT = 4.0  # a pixel brighter than this many times the light around it keeps the excess (``bright_apart``)


def deinterleave(image: np.ndarray, position: np.ndarray, normal: np.ndarray, valid: np.ndarray,
                 footprint: np.ndarray, tile: int, threads: int | None = None) -> np.ndarray:
    """Filter (H,W,C) ``image`` guided by per-pixel position, normal, footprint (world size of a pixel there)
    and validity (pixels without a surface neither give nor receive), on ``threads`` threads (None: every core)."""
    if tile <= 1:
        return image
    h = image.shape[0]
    image = np.ascontiguousarray(image, np.float64)
    guides = (np.ascontiguousarray(position, np.float64), np.ascontiguousarray(normal, np.float64),
              np.ascontiguousarray(valid, np.bool_), np.ascontiguousarray(footprint, np.float64))
    out = np.empty_like(image)
    bands = max(1, min(threads or os.cpu_count() or 1, h))
    edges = np.linspace(0, h, bands + 1).astype(int)

    def band(i):
        _filter_rows(image, *guides, int(tile), PLANE_SIGMA, NORMAL_POWER, edges[i], edges[i + 1], out)
    if bands == 1:
        band(0)
    else:
        with ThreadPoolExecutor(bands) as pool:
            list(pool.map(band, range(bands)))
    return out


def bright_apart(image: np.ndarray, tile: int, interleaved: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """(H,W,3) ``image`` in two parts that sum to it: what the filter may spread, and the excess of each pixel
    brighter (by its largest channel) than ``BRIGHT`` times the light around it, kept where it is. A rare bright
    sample (a caustic's, over metal) then stays one bright pixel, as in a path tracer's picture, instead of
    becoming a square of its light the size of the 2t x 2t window; on black it is kept whole, so that not even a
    faint square is left. The light around a pixel is its window's background (``_background``), or for
    ``interleaved`` light the mean of the eight nearest pixels of its own VPL subset (t apart), which its tile
    pattern makes alike, so that the pattern is all spread. A smooth image is all spread."""
    level = largest(image.reshape(-1, 3)).reshape(image.shape[:2])
    around = _subset_mean(level, tile) if interleaved else _background(level, tile)
    bright = level > BRIGHT * around
    scale = np.ones_like(level)
    scale[bright] = BRIGHT * around[bright] / level[bright]
    spread = image * scale[..., None]
    return spread, image - spread


def _background(level: np.ndarray, tile: int) -> np.ndarray:
    """The light that a few rare bright samples lie on: the mean of (H,W) ``level`` over each pixel's 2t x 2t
    window, every pixel clipped to the fourth brightest of its own window. Three samples in a window then do not
    raise each other's share of the spread light, which would leave the faint squares of their overlap."""
    side = 2 * max(int(tile), 1)
    fourth = rank_filter(level, rank=-4, size=side, mode="nearest")
    return uniform_filter(np.minimum(level, fourth), size=side, mode="nearest")


def _subset_mean(level: np.ndarray, tile: int) -> np.ndarray:
    """The mean of (H,W) ``level`` over the eight pixels t apart around each pixel (edges repeated)."""
    t = max(int(tile), 1)
    h, w = level.shape
    padded = np.pad(level, t, mode="edge")
    total = sum(padded[t + dy:t + dy + h, t + dx:t + dx + w] for dy in (-t, 0, t) for dx in (-t, 0, t))
    return np.maximum(total - level, 0.0) / 8.0


@kernel
def _power(x, n):
    """x^n for an integer n >= 0, by squaring."""
    result = 1.0
    while n > 0:
        if n & 1:
            result *= x
        x *= x
        n >>= 1
    return result


@kernel
def _filter_rows(image, position, normal, valid, footprint, tile, sigma, power, first, last, out):
    """Rows [first, last) of the filtered image into ``out``: each valid pixel the weighted mean of the valid pixels
    of its 2t x 2t window, weights exp(-(n . (x' - x) / (sigma footprint))^2) clamp(n . n', 0, 1)^power; a pixel
    with no weight, or not valid, keeps its value."""
    h, w, channels = image.shape
    acc = np.empty(channels)
    for y in range(first, last):
        for x in range(w):
            if not valid[y, x]:
                out[y, x] = image[y, x]
                continue
            acc[:] = 0.0
            total = 0.0
            scale = max(footprint[y, x] * sigma, 1e-30)
            n0, n1, n2 = normal[y, x, 0], normal[y, x, 1], normal[y, x, 2]
            for yy in range(max(y - tile, 0), min(y + tile, h)):
                for xx in range(max(x - tile, 0), min(x + tile, w)):
                    if not valid[yy, xx]:
                        continue
                    plane = (n0 * (position[yy, xx, 0] - position[y, x, 0]) +
                             n1 * (position[yy, xx, 1] - position[y, x, 1]) +
                             n2 * (position[yy, xx, 2] - position[y, x, 2])) / scale
                    agree = min(max(n0 * normal[yy, xx, 0] + n1 * normal[yy, xx, 1] + n2 * normal[yy, xx, 2], 0.0),
                                1.0)
                    if agree == 0.0 or plane * plane > UNDERFLOW:  # a weight of 0 either way
                        continue
                    weight = math.exp(-plane * plane) * _power(agree, power)
                    for c in range(channels):
                        acc[c] += weight * image[yy, xx, c]
                    total += weight
            for c in range(channels):
                out[y, x, c] = acc[c] / total if total > 0.0 else image[y, x, c]
