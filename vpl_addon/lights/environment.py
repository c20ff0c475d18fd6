"""The world as an equirectangular environment map (Blender's Environment Texture on the Background), sampled by
importance: a piecewise-constant 2D distribution over the texels in proportion to luminance x sin(theta), the
texel's solid angle (Pharr, Jakob, Humphreys, *Physically Based Rendering* 3rd ed., sec. 14.2.4: marginal over
rows, conditional within a row), each texel weighted by the brightest of its neighbours since the radiance is
looked up bilinearly and carries a texel's light into them. A tenth of the probability is spread in proportion to
solid angle alone, so every direction has a pdf > 0.

Directions follow Cycles' equirectangular convention (``kernel/geom`` ``direction_to_equirectangular``): for the
lookup direction d = R w (R: the Mapping node's rotation), u = 1/2 - atan2(d_y, d_x) / 2 pi, v = 1 - acos(d_z) / pi,
so +X is the middle of the image, +Z its top row, and image rows run from the bottom (v = 0) as in Blender.
"""
from __future__ import annotations

import numpy as np

from ..core.color import LUMINANCE
from ..core.sampling import sample_cdf
from ..materials.textures import sample_bilinear
from .light import Light, disc_facing

UNIFORM_SHARE = 0.1  # of the pdf spread by solid angle alone


class EnvironmentLight(Light):
    """Radiance (H,W,3) over the sphere of directions, already times the Background's strength; ``rotation``
    (3,3) takes a world direction to the map's lookup direction."""

    name = "world"

    def __init__(self, image, rotation=np.eye(3)):
        image = np.asarray(image, np.float64)
        self.image = np.maximum(np.nan_to_num(image, nan=0.0, posinf=0.0, neginf=0.0), 0.0)
        self.rotation = np.asarray(rotation, np.float64)
        h, w = self.image.shape[:2]
        theta = (np.arange(h) + 0.5) / h * np.pi  # row i (from the bottom) holds v in [i/h, (i+1)/h): theta = pi (1-v)
        sin = np.sin(theta)[::-1]
        lum = _reach(self.image @ LUMINANCE) * sin[:, None]
        weights = (1.0 - UNIFORM_SHARE) * lum / max(lum.sum(), 1e-300) + UNIFORM_SHARE * np.broadcast_to(
            sin[:, None] / (w * sin.sum()), (h, w))
        if lum.sum() <= 0.0:
            weights = np.broadcast_to(sin[:, None] / (w * sin.sum()), (h, w))
        self.texel_prob = weights / weights.sum()  # (h, w) probability of each texel
        rows = self.texel_prob.sum(axis=1)
        self.row_cdf = _cdf(rows)
        # each row's CDF over its texels, shifted by the row's index and laid end to end: one increasing array, so
        # a row's column is found by one search for row + u (no per-sample copy of the row)
        self.col_cdf = (np.stack([_cdf(r) for r in self.texel_prob]) + np.arange(h)[:, None]).ravel()
        # mean luminance over the sphere of directions, for choosing between the world and the other lights
        self.mean_luminance = float((self.image @ LUMINANCE * sin[:, None]).sum() / (w * sin.sum()))

    def flux_estimate(self, scene_radius):
        return self.mean_luminance * np.pi * np.pi * scene_radius ** 2

    def _uv(self, w):
        d = w @ self.rotation.T
        d = d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-300)
        u = np.mod(0.5 - np.arctan2(d[:, 1], d[:, 0]) / (2.0 * np.pi), 1.0)
        v = 1.0 - np.arccos(np.clip(d[:, 2], -1.0, 1.0)) / np.pi
        return u, v

    def radiance(self, w):
        """(N,3) radiance the world sends from directions w (N,3), bilinear as Cycles' Linear interpolation."""
        u, v = self._uv(w)
        return sample_bilinear(self.image, np.stack([u, v], axis=1))

    def pdf(self, w):
        """(N,) solid-angle pdf of ``sample`` choosing direction w: texel probability x texels / (2 pi^2 sin)."""
        h, wd = self.image.shape[:2]
        u, v = self._uv(w)
        col = np.minimum((u * wd).astype(np.int64), wd - 1)
        row = np.minimum((v * h).astype(np.int64), h - 1)
        sin = np.sin(np.pi * (1.0 - v))
        density = self.texel_prob[row, col] * h * wd / (2.0 * np.pi * np.pi)
        return np.where(sin > 1e-12, density / np.maximum(sin, 1e-12), 0.0)

    def sample(self, u1, u2):
        """Directions (N,3) drawn with ``pdf``, from uniform numbers u1, u2 (N,)."""
        h, wd = self.image.shape[:2]
        row, fv = _invert(self.row_cdf, u1)
        flat, fu = _invert(self.col_cdf, row + u2)
        col = np.minimum(flat - row * wd, wd - 1)
        u, v = (col + fu) / wd, (row + fv) / h
        theta, phi = np.pi * (1.0 - v), 2.0 * np.pi * (0.5 - u)
        d = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], axis=1)
        return d @ self.rotation  # back from the map's frame to the world (R is a rotation: R^-1 = R^T)

    def _sample_incident(self, p, n, u1, u2):
        wi = self.sample(u1, u2)
        pdf = self.pdf(wi)
        weight = np.where(pdf[:, None] > 0.0, self.radiance(wi) / np.maximum(pdf, 1e-300)[:, None], 0.0)
        return wi, np.full(len(p), np.inf), weight

    def mis(self, p, n, w):
        return np.full(len(p), np.inf), self.radiance(w), self.pdf(w)

    def emit(self, count, rng, center, radius):
        """Paths enter from the sampled directions, from a disc of the scene's radius across each: power
        L(w) pi R^2 / pdf(w), so the mean is the power the world sends through the disc."""
        towards = self.sample(rng.random(count), rng.random(count))
        pdf = self.pdf(towards)
        dirs = -towards
        origins = disc_facing(rng, dirs, center, radius)
        power = np.where(pdf[:, None] > 0.0, self.radiance(towards) * (np.pi * radius * radius)
                         / np.maximum(pdf, 1e-300)[:, None], 0.0)
        return origins, dirs, power


def _reach(lum):
    """(h,w) the largest luminance of each texel's 3 x 3 neighbourhood (around in u, clamped in v): the bilinear
    lookup carries a texel's light into its neighbours, so they are sampled as the brightest texel they see."""
    padded = np.pad(lum, ((1, 1), (0, 0)), mode="edge")
    padded = np.concatenate([padded[:, -1:], padded, padded[:, :1]], axis=1)
    h, w = lum.shape
    return np.max([padded[i:i + h, j:j + w] for i in range(3) for j in range(3)], axis=0)


def _invert(cdf, x):
    """(bin of x under the increasing ``cdf``, where x falls within that bin in [0, 1])."""
    index = sample_cdf(cdf, x)
    lo = np.where(index > 0, cdf[np.maximum(index - 1, 0)], 0.0)
    return index, np.clip((x - lo) / np.maximum(cdf[index] - lo, 1e-300), 0.0, 1.0)


def _cdf(weights):
    total = weights.sum()
    cdf = np.cumsum(weights) / total if total > 0 else (np.arange(len(weights)) + 1.0) / len(weights)
    cdf[-1] = 1.0
    return cdf
