"""The world as a light: constant radiance = Background Color x Strength from every direction."""
from __future__ import annotations

import numpy as np

from ..core.color import LUMINANCE
from ..core.sampling import cosine_hemisphere, dot, uniform_sphere
from .light import Light, disc_facing


class WorldLight(Light):
    """Constant background radiance, sampled with the cosine lobe of the receiver."""

    name = "world"

    def __init__(self, radiance):
        self.constant = np.asarray(radiance, np.float64)

    def radiance(self, w):
        """(N,3) radiance the world sends from directions w (N,3): the same from all of them."""
        return np.broadcast_to(self.constant, (len(w), 3))

    def flux_estimate(self, scene_radius):
        return float(self.constant @ LUMINANCE) * np.pi * np.pi * scene_radius ** 2

    def _sample_incident(self, p, n, u1, u2):
        wi, cos = cosine_hemisphere(u1, u2, n)
        factor = np.pi / np.maximum(cos, 1e-12)
        return wi, np.full(len(p), np.inf), factor[:, None] * self.constant

    def mis(self, p, n, w):
        """Every ray that leaves finds the world: pdf cos / pi about the shading normal."""
        cos = dot(n, w)
        return (np.full(len(p), np.inf), self.radiance(w),
                np.maximum(cos, 0.0) / np.pi)

    def emit(self, count, rng, center, radius):
        dirs = uniform_sphere(rng.random(count), rng.random(count))
        origins = disc_facing(rng, dirs, center, radius)
        return origins, dirs, np.broadcast_to(self.constant * 4.0 * np.pi * np.pi * radius * radius,
                                              (count, 3)).copy()
