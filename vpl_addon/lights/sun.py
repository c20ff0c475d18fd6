"""The sun in Cycles' units: strength S [W/m^2] is the irradiance on a surface facing it, spread over a disc of
the given angle."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.color import LUMINANCE
from ..core.sampling import dot, normalize, uniform_cone
from .light import Light, disc_facing
from .light_tree import horizon_bound


@dataclass
class SunLight(Light):
    name: str
    direction: np.ndarray  # direction the light travels (the sun object's -Z)
    strength: np.ndarray  # RGB W/m^2
    angle: float = 0.0  # angular diameter of the sun disc
    visible: bool = False  # camera rays see it (``Light.visible``): a field, so the light's record keeps it
    distant = True

    def __post_init__(self):
        self.direction = normalize(np.asarray(self.direction, np.float64))
        self.strength = np.maximum(np.nan_to_num(np.asarray(self.strength, np.float64), nan=0.0, posinf=0.0), 0.0)
        self.angle = float(np.clip(np.nan_to_num(self.angle), 0.0, np.pi))

    def flux_estimate(self, scene_radius):
        return float(self.strength @ LUMINANCE) * np.pi * scene_radius ** 2

    def irradiance_bound(self, n: np.ndarray) -> np.ndarray:
        """(N,) the most irradiance [W/m^2] (luminance) the sun can bring to surfaces of normals n: its strength
        times the largest cosine between n and a direction of its disc (the light tree's importance of a
        distant light)."""
        half = 0.5 * self.angle
        return float(self.strength @ LUMINANCE) * horizon_bound(-dot(n, self.direction), np.cos(half), np.sin(half))

    def _sample_incident(self, p, n, u1, u2):
        count = len(p)
        axis = np.broadcast_to(-self.direction, (count, 3))
        half = 0.5 * self.angle
        if half <= 1e-6:
            return axis.copy(), np.full(count, np.inf), np.broadcast_to(self.strength, (count, 3)).copy()
        one_minus_cos = 2.0 * np.sin(0.5 * half) ** 2
        wi = uniform_cone(u1, u2, axis, 1.0 - one_minus_cos)
        # radiance S / (pi sin^2 half) over the cone gives irradiance S at normal incidence
        scale = 2.0 * one_minus_cos / np.sin(half) ** 2
        return wi, np.full(count, np.inf), np.broadcast_to(self.strength * scale, (count, 3)).copy()

    def seen(self, origins, dirs):
        """The sun's disc as Cycles draws it where the camera sees the sky: radiance S / (pi sin^2 half), at an
        infinite distance (measured); None for a sun of angle 0."""
        half = 0.5 * self.angle
        if half <= 1e-6:
            return None
        inside = -dot(dirs, self.direction) >= np.cos(half)
        radiance = self.strength / (np.pi * np.sin(half) ** 2)
        return np.where(inside, np.inf, 0.0), np.where(inside[:, None], radiance, 0.0)

    def emit(self, count, rng, center, radius):
        half = 0.5 * self.angle
        axis = np.broadcast_to(self.direction, (count, 3))
        if half <= 1e-6:
            dirs = axis.copy()
        else:
            dirs = uniform_cone(rng.random(count), rng.random(count), axis, np.cos(half))
        origins = disc_facing(rng, dirs, center, radius)
        return origins, dirs, np.broadcast_to(self.strength * np.pi * radius * radius, (count, 3)).copy()
