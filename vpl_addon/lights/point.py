"""Point and spot lights in Cycles' units: power P [W], radiant intensity I = P / (4 pi) [W/sr]; with radius R a
sphere (or, with soft falloff, a disc facing the point) of radiance I / (pi R^2). A spot is a point light cut by
a cone, not renormalised to it."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..core.color import LUMINANCE
from ..core.sampling import cosine_hemisphere, dot, normalize, uniform_cone, uniform_sphere
from .light import Light


def smoothstep(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def _round_light_sample(p, center, radius, soft, u1, u2):
    """Cone sampling of a round light of radius R seen from p: (wi, dist, 2 pi (1 - cos a) / (pi R^2)).

    ``soft`` (Cycles' default "soft falloff") makes the light a disc that always faces p, cone half-angle
    atan(R/d); otherwise it is a sphere, asin(R/d). The last value times the light's intensity is L_e / pdf.
    """
    to_c = center - p
    d2 = dot(to_c, to_c)
    d = np.sqrt(d2)
    axis = to_c / np.maximum(d, 1e-300)[:, None]
    if radius <= 0.0:
        return axis, d, 1.0 / np.maximum(d2, 1e-300)
    r2 = radius * radius
    if soft:
        sin2 = r2 / np.maximum(d2 + r2, 1e-300)
    else:
        sin2 = np.minimum(r2 / np.maximum(d2, 1e-300), 1.0)
    one_minus_cos = sin2 / (1.0 + np.sqrt(1.0 - sin2))  # 1 - cos(a) without cancellation
    wi = uniform_cone(u1, u2, axis, 1.0 - one_minus_cos)
    b = dot(wi, to_c)
    if soft:  # the facing disc lies at distance d along the axis
        dist = d / np.maximum(b / np.maximum(d, 1e-300), 1e-12)
    else:  # near side of the sphere (law of cosines); inside it the light is right here
        dist = np.maximum(b - np.sqrt(np.maximum(r2 - (d2 - b * b), 0.0)), 0.0)
    return wi, dist, 2.0 * one_minus_cos / r2


@dataclass
class PointLight(Light):
    name: str
    position: np.ndarray
    power: np.ndarray  # RGB watts (colour x energy)
    radius: float = 0.0
    soft_falloff: bool = True  # Blender's default: the light acts as a disc facing the shading point
    visible: bool = False  # camera rays see it (``Light.visible``): a field, so the light's record keeps it

    def __post_init__(self):
        self.position = np.asarray(self.position, np.float64)
        self.power = np.maximum(np.nan_to_num(np.asarray(self.power, np.float64), nan=0.0, posinf=0.0), 0.0)
        self.radius = max(float(np.nan_to_num(self.radius)), 0.0)

    @property
    def intensity(self) -> np.ndarray:
        return self.power / (4.0 * np.pi)

    def flux_estimate(self, scene_radius):
        return float(self.power @ LUMINANCE) if np.isfinite(self.position).all() else 0.0

    def bounds(self):
        return self.position, self.radius

    def attenuation(self, out_dirs: np.ndarray) -> np.ndarray:
        """Emission profile along directions leaving the light (1 for a point light)."""
        return np.ones(len(out_dirs))

    def _sample_incident(self, p, n, u1, u2):
        wi, dist, factor = _round_light_sample(p, self.position, self.radius, self.soft_falloff, u1, u2)
        return wi, dist, (factor * self.attenuation(-wi))[:, None] * self.intensity

    def seen(self, origins, dirs):
        """As Cycles draws a point or spot light the camera sees (measured): of radiance I / (pi R^2) times the
        spot's cone toward the ray, a sphere of radius R, or with soft falloff a disc of radius R facing the ray's
        origin."""
        if self.radius <= 0.0:
            return None
        to_c = self.position - origins
        b = dot(dirs, to_c)
        d2 = dot(to_c, to_c)
        r2 = self.radius * self.radius
        if self.soft_falloff:  # the facing disc's plane through the centre, normal to the centre's direction
            t = d2 / np.where(b > 0.0, b, 1.0)
            hit = (b > 0.0) & (t * t - d2 <= r2)  # |q - c|^2 = t^2 - d^2 on that plane
        else:
            disc = b * b - d2 + r2  # the quadratic's discriminant / 4
            root = np.sqrt(np.maximum(disc, 0.0))
            t = np.where(b - root > 0.0, b - root, b + root)  # inside the sphere: its far side
            hit = (disc >= 0.0) & (t > 0.0)
        radiance = (self.attenuation(-dirs) / (np.pi * r2))[:, None] * self.intensity
        return np.where(hit, t, 0.0), np.where(hit[:, None], radiance, 0.0)

    def emit(self, count, rng, center, radius):
        if self.radius > 0.0:  # a uniformly emitting sphere: point on it, cosine direction outward
            normal = uniform_sphere(rng.random(count), rng.random(count))
            dirs, _ = cosine_hemisphere(rng.random(count), rng.random(count), normal)
            origins = self.position + self.radius * normal
        else:
            dirs = uniform_sphere(rng.random(count), rng.random(count))
            origins = np.broadcast_to(self.position, (count, 3)).copy()
        return origins, dirs, self.attenuation(dirs)[:, None] * self.power


@dataclass
class SpotLight(PointLight):
    direction: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, -1.0]))
    spot_size: float = np.pi / 4  # full cone angle
    spot_blend: float = 0.15
    # inverse of the light object's 3x3 world matrix: non-uniform scale reshapes the cone (None: unscaled)
    inverse_basis: np.ndarray | None = None

    def __post_init__(self):
        super().__post_init__()
        self.direction = normalize(np.asarray(self.direction, np.float64))

    def orientation(self):
        """Within half the spot size of its direction; a scaled spot (elliptic cone) everywhere."""
        if self.inverse_basis is not None:
            return super().orientation()
        return self.direction, min(0.5 * float(self.spot_size), np.pi), 0.0

    def attenuation(self, out_dirs):
        """Cycles' cone: smoothstep((cos a - cos(size/2)) / ((1 - cos(size/2)) blend)), a = angle to the axis,
        measured in the light's local frame (so a scaled spot has an elliptic cone)."""
        cos_half = np.cos(0.5 * self.spot_size)
        if self.inverse_basis is None:
            cos_a = dot(out_dirs, self.direction)
        else:
            cos_a = -normalize(out_dirs @ np.asarray(self.inverse_basis).T)[:, 2]
        smooth = (1.0 - cos_half) * self.spot_blend
        if smooth <= 0.0:
            return (cos_a > cos_half).astype(np.float64)
        return smoothstep((cos_a - cos_half) / smooth)
