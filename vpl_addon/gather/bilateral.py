"""Geometry-aware cross-bilateral filter that removes the tile pattern of interleaved sampling.

Each pixel averages the 2t x 2t window around it, which holds every VPL subset exactly four times (so a flat area
weighs all subsets alike, and a pixel at a corner, whose neighbours on other surfaces are refused, still finds
most of them), weighting a neighbour by how well it lies on the pixel's own surface: its distance from the pixel's
tangent plane (relative to the pixel's footprint on the surface) and the agreement of normals. Neighbours across
depth or orientation discontinuities get little weight, so light does not bleed around corners (Segovia et al.
2006; Hedman et al. 2017 sec. 4).
"""
from __future__ import annotations

import numpy as np

PLANE_SIGMA = 2.0  # tangent-plane distance, in pixel footprints, at which a neighbour's weight falls to 1/e
NORMAL_POWER = 16  # weight ~ (n . n')^power


def deinterleave(image: np.ndarray, position: np.ndarray, normal: np.ndarray, valid: np.ndarray,
                 footprint: np.ndarray, tile: int) -> np.ndarray:
    """Filter (H,W,C) ``image`` guided by per-pixel position, normal, footprint (world size of a pixel there)
    and validity (pixels without a surface neither give nor receive)."""
    if tile <= 1:
        return image
    h, w = image.shape[:2]
    offsets = [(dy, dx) for dy in range(-tile, tile) for dx in range(-tile, tile)]
    pad = ((tile, tile), (tile, tile))

    def padded(a):
        return np.pad(a, pad + ((0, 0),) * (a.ndim - 2), mode="constant")

    img_p, pos_p, nor_p, val_p = padded(image), padded(position), padded(normal), padded(valid.astype(float))
    acc = np.zeros_like(image, dtype=np.float64)
    wsum = np.zeros((h, w))
    scale = np.maximum(footprint * PLANE_SIGMA, 1e-30)
    for dy, dx in offsets:
        sl = (slice(tile + dy, tile + dy + h), slice(tile + dx, tile + dx + w))
        plane = np.einsum("hwc,hwc->hw", normal, pos_p[sl] - position) / scale
        agree = np.clip(np.einsum("hwc,hwc->hw", normal, nor_p[sl]), 0.0, 1.0) ** NORMAL_POWER
        weight = val_p[sl] * np.exp(-plane * plane) * agree
        acc += weight[..., None] * img_p[sl]
        wsum += weight
    out = np.where(wsum[..., None] > 0, acc / np.maximum(wsum, 1e-300)[..., None], image)
    return np.where(valid[..., None], out, image)
