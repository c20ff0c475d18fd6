"""Sampling / resampling of VPLs by the power they bring to the camera (Segovia et al. 2006, sec. 3.2 and 4).

The power of each VPL is estimated by connecting it to M camera points (M = 10 in the paper), one from each of M
bands of the image; a CDF over power plus a small uniform floor (so no VPL that could light the image has
probability zero) is sampled N' times; each kept VPL is weighted by (times chosen) / (N' q), which keeps the set
an unbiased estimate of what the full set gave (importance resampling, Talbot et al. 2005). The N' draws are
systematic (one random offset, N' evenly spaced points of the CDF): every VPL is still chosen N' q times on
average, with far less spread than independent draws."""
from __future__ import annotations

import numpy as np

from ...core.color import LUMINANCE
from ...gather.summing import sum_pairs


def camera_power(vpls, camera_points, m: int, tracer, d_min: float, rng) -> np.ndarray:
    """(N,) luminance each VPL sends to the image, estimated from ``m`` camera points per VPL."""
    n = len(vpls)
    if n == 0 or len(camera_points) == 0 or m <= 0:
        return np.zeros(n)
    rep = np.repeat(np.arange(n), m)
    j = camera_points.choose_stratified(n, m, rng)
    light = sum_pairs(camera_points.surface, j, vpls, rep, tracer, d_min, rep, n) @ LUMINANCE
    return camera_points.hit_fraction * light / m


def resample(power: np.ndarray, count: int, floor: float, rng):
    """Draw ``count`` VPLs with probability q ~ power + floor * mean(power).

    Returns (unique indices, weight per kept VPL = times chosen / (count q))."""
    n = len(power)
    if n == 0 or count <= 0:
        return np.zeros(0, np.int64), np.zeros(0)
    mean = float(power.mean())
    weight = power + floor * mean if mean > 0.0 else np.ones(n)
    q = weight / weight.sum()
    cdf = np.cumsum(q)
    cdf[-1] = 1.0
    draws = np.minimum(np.searchsorted(cdf, (np.arange(count) + rng.random()) / count, side="right"), n - 1)
    index, times = np.unique(draws, return_counts=True)
    return index, times / (count * q[index])
