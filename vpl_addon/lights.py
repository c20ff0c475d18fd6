"""Light sources in Blender's units, and their sampling toward a shading point (next-event estimation).

Units follow Cycles (``scene/light.cpp``, ``kernel/light/*.h``), checked against Cycles' ``Diffuse Direct`` pass
by ``tests/test_cycles_direct.py``:

* point and spot, power P [W]: radiant intensity I = P / (4 pi) [W/sr]; with radius R the light is a sphere of
  radiance I / (pi R^2). A spot is a point light cut by a cone, not renormalised to it.
* area, power P [W] over area A: one-sided Lambertian emitter of radiance P / (pi A).
* sun, strength S [W/m^2]: irradiance S on a surface facing it, spread over a disc of the given angle.
* emissive triangles: radiance = Emission Color x Strength, emitted from both sides.
* world: constant radiance = Background Color x Strength from every direction.

``sample_incident(p, n, u1, u2, owner)`` returns, for light samples at shading points p with normals n (sample i at
point ``owner[i]``), unit directions toward the light, the distance to the sampled light point (inf for distant
lights), and L_e / pdf in solid angle: the estimator of the direct diffuse term is then
``le_over_pdf * max(0, n.wi) / pi * V``. A sample that cannot receive light (behind a one-sided area light) may
come back as a zero direction with zero weight.

``emit(count, rng, center, radius)`` starts light paths (Keller's Instant Radiosity): origins, unit directions and
the power each carries (emitted radiance over the joint pdf of position and direction, so the mean over paths is the
light's total power). Distant lights (sun, world) emit from a disc covering the scene's bounding sphere.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .sampling import (concentric_disk, cosine_hemisphere, dot, normalize, orthonormal_basis, sample_cdf,
                       triangle_barycentrics, uniform_cone, uniform_sphere)

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])


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


def _disc_facing(rng, dirs, center, radius):
    """Origins on discs of the given radius perpendicular to each travel direction, upstream of the scene."""
    x, y = concentric_disk(rng.random(len(dirs)), rng.random(len(dirs)))
    t, b = orthonormal_basis(dirs)
    return center + radius * (x[:, None] * t + y[:, None] * b) - 2.0 * radius * dirs


class Light:
    """Base of the light types: a name, total power for light selection and incident sampling."""

    name: str

    @property
    def is_active(self) -> bool:
        """Emits and is well defined: a light with NaN or infinite numbers (a broken transform), or without a
        direction, is inert rather than a source of NaN."""
        flux = self.flux_estimate(1.0)
        numbers = [v for v in vars(self).values() if isinstance(v, (float, np.ndarray))]
        directions = [getattr(self, k) for k in ("direction", "normal") if isinstance(getattr(self, k, None),
                                                                                  np.ndarray)]
        return bool(np.isfinite(flux) and flux > 0.0 and all(np.isfinite(v).all() for v in numbers)
                    and all(np.linalg.norm(d) > 0.0 for d in directions))

    def flux_estimate(self, scene_radius: float) -> float:
        """Approximate emitted power (luminance-weighted), used only to choose between lights."""
        raise NotImplementedError

    def bounds(self) -> tuple[np.ndarray, float]:
        """Centre and radius of a sphere around the emitter (local lights only)."""
        raise NotImplementedError

    def importance(self, p: np.ndarray, scene_radius: float) -> np.ndarray:
        """(N,) rough irradiance the light brings to points p, ignoring shadows and orientation: power over
        4 pi max(d^2, r^2). Only used to choose which light to sample at each point."""
        center, r = self.bounds()
        d2 = dot(p - center, p - center)
        return np.full(len(p), self.flux_estimate(scene_radius)) / (4.0 * np.pi * np.maximum(d2, r * r + 1e-30))

    def sample_incident(self, p, n, u1, u2, owner=None):
        """Light samples toward shading points: ``owner`` (N,) gives the point of ``p`` (P,3) each sample (u1[i],
        u2[i]) belongs to (None: sample i is at point i). A light whose sampling has a per-point part (the
        spherical rectangle) computes it once per point."""
        if owner is not None:
            p, n = p[owner], n[owner]
        return self._sample_incident(p, n, u1, u2)

    def _sample_incident(self, p, n, u1, u2):
        raise NotImplementedError

    def mis(self, p: np.ndarray, n: np.ndarray, w: np.ndarray):
        """What a ray from points p (shading normals n) along unit directions w finds of the light, for multiple
        importance sampling of a glossy lobe against ``sample_incident``: (distance (P,), emitted radiance (P,3),
        the solid-angle pdf of ``sample_incident`` choosing w (P,)), radiance and pdf 0 where the ray misses it.
        None for a light that cannot say: its samples keep their full weight and lobe samples ignore it."""
        return None

    def emit(self, count, rng, center, radius):
        raise NotImplementedError


@dataclass
class PointLight(Light):
    name: str
    position: np.ndarray
    power: np.ndarray  # RGB watts (colour x energy)
    radius: float = 0.0
    soft_falloff: bool = True  # Blender's default: the light acts as a disc facing the shading point

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


@dataclass
class SunLight(Light):
    name: str
    direction: np.ndarray  # direction the light travels (the sun object's -Z)
    strength: np.ndarray  # RGB W/m^2
    angle: float = 0.0  # angular diameter of the sun disc

    def __post_init__(self):
        self.direction = normalize(np.asarray(self.direction, np.float64))
        self.strength = np.maximum(np.nan_to_num(np.asarray(self.strength, np.float64), nan=0.0, posinf=0.0), 0.0)
        self.angle = float(np.clip(np.nan_to_num(self.angle), 0.0, np.pi))

    def flux_estimate(self, scene_radius):
        return float(self.strength @ LUMINANCE) * np.pi * scene_radius ** 2

    def importance(self, p, scene_radius):
        return np.full(len(p), float(self.strength @ LUMINANCE))

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

    def emit(self, count, rng, center, radius):
        half = 0.5 * self.angle
        axis = np.broadcast_to(self.direction, (count, 3))
        if half <= 1e-6:
            dirs = axis.copy()
        else:
            dirs = uniform_cone(rng.random(count), rng.random(count), axis, np.cos(half))
        origins = _disc_facing(rng, dirs, center, radius)
        return origins, dirs, np.broadcast_to(self.strength * np.pi * radius * radius, (count, 3)).copy()


@dataclass
class AreaLight(Light):
    name: str
    center: np.ndarray
    axis_u: np.ndarray  # full edge (or diameter) vector along the light's local X
    axis_v: np.ndarray  # full edge (or diameter) vector along local Y
    normal: np.ndarray  # emitting side: the light object's local -Z
    power: np.ndarray  # RGB watts
    round: bool = False  # disk / ellipse instead of square / rectangle
    spread: float = np.pi  # full angle of the emission cone; below pi light is focused along the normal

    def __post_init__(self):
        self.center = np.asarray(self.center, np.float64)
        self.axis_u = np.asarray(self.axis_u, np.float64)
        self.axis_v = np.asarray(self.axis_v, np.float64)
        self.normal = normalize(np.asarray(self.normal, np.float64))
        self.power = np.maximum(np.nan_to_num(np.asarray(self.power, np.float64), nan=0.0, posinf=0.0), 0.0)

    @property
    def area(self) -> float:
        a = float(np.linalg.norm(self.axis_u) * np.linalg.norm(self.axis_v))
        return a * np.pi / 4.0 if self.round else a

    @property
    def radiance(self) -> np.ndarray:
        return self.power / (np.pi * self.area)

    def bounds(self):
        return self.center, 0.5 * float(np.hypot(np.linalg.norm(self.axis_u), np.linalg.norm(self.axis_v)))

    def importance(self, p, scene_radius):
        """As for any light, but nothing behind the emitting side (one-sided)."""
        return np.where(dot(p - self.center, self.normal) > 0.0, super().importance(p, scene_radius), 0.0)

    def spread_profile(self, cos_phi: np.ndarray) -> np.ndarray:
        """Cycles' spread: max(0, tan h - tan phi) / (tan h sin^2 h - h + sin h cos h), h = spread / 2, which
        keeps the emitted power; 1 (pure Lambertian) at 180 degrees."""
        h = 0.5 * float(np.clip(self.spread, np.radians(1.0), np.pi))
        if h >= 0.5 * np.pi - 1e-6:
            return np.ones_like(cos_phi)
        c = np.clip(cos_phi, 1e-9, 1.0)
        tan_phi = np.sqrt(1.0 - c * c) / c
        norm = np.tan(h) * np.sin(h) ** 2 - h + np.sin(h) * np.cos(h)
        return np.maximum(np.tan(h) - tan_phi, 0.0) / norm

    def flux_estimate(self, scene_radius):
        ok = self.area > 0.0 and np.isfinite(self.center).all() and np.isfinite(self.normal).all()
        return float(self.power @ LUMINANCE) if ok else 0.0

    def sample_points(self, u1, u2):
        if self.round:
            x, y = concentric_disk(u1, u2)
            x, y = 0.5 * x, 0.5 * y
        else:
            x, y = u1 - 0.5, u2 - 0.5
        return self.center + x[:, None] * self.axis_u + y[:, None] * self.axis_v

    def sample_incident(self, p, n, u1, u2, owner=None):
        if self.round:
            return super().sample_incident(p, n, u1, u2, owner)
        return self._sample_spherical_rectangle(p, u1, u2, owner)

    def _sample_incident(self, p, n, u1, u2):
        q = self.sample_points(u1, u2)
        to_l = q - p
        d2 = dot(to_l, to_l)
        dist = np.sqrt(d2)
        wi = to_l / np.maximum(dist, 1e-300)[:, None]
        cos_l = np.maximum(dot(-wi, self.normal), 0.0)  # one-sided
        factor = cos_l * self.spread_profile(cos_l) * self.area / np.maximum(d2, 1e-300)
        return wi, dist, factor[:, None] * self.radiance

    def _frame(self):
        """The rectangle's unit edge directions x, y, its normal z = x cross y, and its edge lengths."""
        lx, ly = np.linalg.norm(self.axis_u), np.linalg.norm(self.axis_v)
        x, y = self.axis_u / lx, self.axis_v / ly
        return x, y, np.cross(x, y), lx, ly

    def _spherical_rectangle(self, p):
        """The per-point part of Urena et al.'s sampling (their Algorithm 1 up to the solid angle), (P,) each: the
        rectangle's corner (x0, y0) in its frame seen from each point, the point's signed height zs over the
        rectangle's plane (the algorithm works with z0 = -|zs|, the rectangle below the point), b0, b1, k and the
        solid angle (0 where degenerate)."""
        x, y, z, lx, ly = self._frame()
        d = (self.center - 0.5 * self.axis_u - 0.5 * self.axis_v) - p
        x0, y0, zs = d @ x, d @ y, d @ z
        z0 = -np.abs(zs)
        zero = np.zeros_like(z0)

        def unit(a, b, c):
            v = np.stack([a, b, c], axis=-1)
            return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-300)

        # normals of the spherical quad's edges in the local frame (x, y, z)
        n0, n1, n2, n3 = unit(zero, z0, -y0), unit(-z0, zero, x0 + lx), unit(zero, -z0, y0 + ly), unit(z0, zero, -x0)
        g0, g1, g2, g3 = (np.arccos(np.clip(-dot(a, b), -1, 1)) for a, b in ((n0, n1), (n1, n2), (n2, n3), (n3, n0)))
        k = 2.0 * np.pi - g2 - g3
        solid = g0 + g1 - k
        solid = np.where(np.isfinite(solid) & (solid > 1e-12), solid, 0.0)
        return x0, y0, zs, n0[:, 2], n2[:, 2], k, solid

    def _sample_spherical_rectangle(self, p, u1, u2, owner=None):
        """Uniform in the solid angle the rectangle subtends (Urena, Fajardo, King: "An Area-Preserving
        Parametrization for Spherical Rectangles", EGSR 2013): L_e / pdf = L x solid angle, no 1/d^2 spikes.
        The per-point part is computed once per point of ``p``, the rest per sample (``owner`` as in
        ``Light.sample_incident``); the light is one-sided, so samples at points behind it get nothing (zero
        weight and direction) and cost nothing."""
        owner = np.arange(len(p)) if owner is None else owner
        wi, dist, weight = np.zeros((len(owner), 3)), np.zeros(len(owner)), np.zeros((len(owner), 3))
        front = dot(p - self.center, self.normal) > 0.0
        rows = np.nonzero(front[owner])[0]
        if len(rows) == 0:
            return wi, dist, weight
        per_point = self._spherical_rectangle(p[front])
        at = (np.cumsum(front) - 1)[owner[rows]]  # each sample's point among those in front
        x0, y0, zs, b0, b1, k, solid = (value[at] for value in per_point)
        u1, u2 = u1[rows], u2[rows]
        x, y, z, lx, ly = self._frame()
        x1, y1, z0 = x0 + lx, y0 + ly, -np.abs(zs)
        au = u1 * solid + k
        with np.errstate(divide="ignore", invalid="ignore"):
            fu = (np.cos(au) * b0 - b1) / np.sin(au)
            cu = np.clip(np.sign(fu) / np.sqrt(fu * fu + b0 * b0), -1.0, 1.0)
            xu = np.clip(-(cu * z0) / np.sqrt(np.maximum(1.0 - cu * cu, 1e-300)), x0, x1)
            dd = np.sqrt(xu * xu + z0 * z0)
            h0 = y0 / np.sqrt(dd * dd + y0 * y0)
            h1 = y1 / np.sqrt(dd * dd + y1 * y1)
            hv = h0 + u2 * (h1 - h0)
            yv = np.where(hv * hv < 1.0 - 1e-6, hv * dd / np.sqrt(np.maximum(1.0 - hv * hv, 1e-300)), y1)
        local = np.stack([np.nan_to_num(xu, copy=False), np.nan_to_num(yv, copy=False), zs], axis=1)
        to_l = local @ np.stack([x, y, z])
        dist[rows] = np.linalg.norm(to_l, axis=1)
        wi[rows] = to_l / np.maximum(dist[rows], 1e-300)[:, None]
        cos_l = np.maximum(dot(-wi[rows], self.normal), 0.0)
        weight[rows] = np.where(cos_l > 0.0, solid * self.spread_profile(cos_l), 0.0)[:, None] * self.radiance
        return wi, dist, weight

    def mis(self, p, n, w):
        """The ray meets the light's plane in front of its emitting side and inside it; the pdf is the spherical
        rectangle's 1 / solid angle, or for a disk the area sampling's d^2 / (cos A)."""
        facing = -dot(w, self.normal)  # cos at the light: it emits along its normal
        t = dot(p - self.center, self.normal) / np.where(facing > 0.0, facing, 1.0)
        q = p + t[:, None] * w - self.center
        a = dot(q, self.axis_u) / dot(self.axis_u, self.axis_u)  # in [-1/2, 1/2] across the light
        b = dot(q, self.axis_v) / dot(self.axis_v, self.axis_v)
        inside = 4.0 * (a * a + b * b) <= 1.0 if self.round else (np.abs(a) <= 0.5) & (np.abs(b) <= 0.5)
        hit = (facing > 0.0) & (t > 0.0) & inside & np.isfinite(t)
        radiance = np.where(hit[:, None], self.spread_profile(facing)[:, None] * self.radiance, 0.0)
        pdf = np.zeros(len(p))
        if self.round:
            pdf[hit] = t[hit] ** 2 / np.maximum(facing[hit] * self.area, 1e-300)
        else:  # the spherical rectangle's set-up only where the ray finds the light
            solid = self._spherical_rectangle(p[hit])[-1]
            pdf[hit] = np.where(solid > 0.0, 1.0 / np.maximum(solid, 1e-300), 0.0)
        return np.where(hit, t, 0.0), radiance, pdf

    def emit(self, count, rng, center, radius):
        origins = self.sample_points(rng.random(count), rng.random(count))
        dirs, cos = cosine_hemisphere(rng.random(count), rng.random(count), np.broadcast_to(self.normal, (count, 3)))
        return origins, dirs, self.spread_profile(cos)[:, None] * self.power


class EmissiveTriangles(Light):
    """All triangles whose material emits, as one light: triangle chosen by power, point uniform on it."""

    name = "emissive triangles"

    def __init__(self, triangles, normals, radiance):
        self.triangles = np.asarray(triangles, np.float64)
        self.normals = np.asarray(normals, np.float64)
        self.radiance = np.asarray(radiance, np.float64)
        e1 = self.triangles[:, 1] - self.triangles[:, 0]
        e2 = self.triangles[:, 2] - self.triangles[:, 0]
        self.areas = 0.5 * np.linalg.norm(np.cross(e1, e2), axis=1)
        weight = self.areas * (self.radiance @ LUMINANCE)
        self.total = float(weight.sum())
        self.cdf = np.cumsum(weight) / self.total if self.total > 0 else np.ones(len(weight))
        self.prob = weight / self.total if self.total > 0 else np.zeros(len(weight))

    @staticmethod
    def from_scene(scene) -> "EmissiveTriangles | None":
        emission = scene.materials.emission[scene.material]
        sel = emission.max(axis=1) > 0.0
        if not sel.any():
            return None
        return EmissiveTriangles(scene.triangles[sel], scene.geometric_normals[sel], emission[sel])

    def flux_estimate(self, scene_radius):
        return 2.0 * np.pi * self.total  # both sides

    def bounds(self):
        pts = self.triangles.reshape(-1, 3)
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        return 0.5 * (lo + hi), 0.5 * float(np.linalg.norm(hi - lo))

    def _sample_incident(self, p, n, u1, u2):
        idx = sample_cdf(self.cdf, u1)
        # reuse u1 within the chosen CDF bin for the point: keeps one random pair per sample
        lo = np.where(idx > 0, self.cdf[np.maximum(idx - 1, 0)], 0.0)
        w = np.maximum(self.cdf[idx] - lo, 1e-300)
        u1r = np.clip((u1 - lo) / w, 0.0, 1.0 - 1e-12)
        b1, b2 = triangle_barycentrics(u1r, u2)
        tri = self.triangles[idx]
        q = tri[:, 0] + b1[:, None] * (tri[:, 1] - tri[:, 0]) + b2[:, None] * (tri[:, 2] - tri[:, 0])
        to_l = q - p
        d2 = dot(to_l, to_l)
        dist = np.sqrt(d2)
        wi = to_l / np.maximum(dist, 1e-300)[:, None]
        cos_l = np.abs(dot(wi, self.normals[idx]))
        pdf_area = self.prob[idx] / np.maximum(self.areas[idx], 1e-300)
        factor = cos_l / np.maximum(d2 * pdf_area, 1e-300)
        return wi, dist, factor[:, None] * self.radiance[idx], self.normals[idx]

    def emit(self, count, rng, center, radius):
        idx = sample_cdf(self.cdf, rng.random(count))
        b1, b2 = triangle_barycentrics(rng.random(count), rng.random(count))
        tri = self.triangles[idx]
        origins = tri[:, 0] + b1[:, None] * (tri[:, 1] - tri[:, 0]) + b2[:, None] * (tri[:, 2] - tri[:, 0])
        side = np.where(rng.random(count) < 0.5, 1.0, -1.0)[:, None] * self.normals[idx]
        dirs, _ = cosine_hemisphere(rng.random(count), rng.random(count), side)
        # radiance x pi (cosine lobe) x area / p(triangle), times 2 for the side chosen with probability 1/2
        power = self.radiance[idx] * (2.0 * np.pi * self.areas[idx] / np.maximum(self.prob[idx], 1e-300))[:, None]
        origins = origins + side * (1e-7 * max(radius, 1e-30))
        return origins, dirs, power


class WorldLight(Light):
    """Constant background radiance, sampled with the cosine lobe of the receiver."""

    name = "world"

    def __init__(self, radiance):
        self.radiance = np.asarray(radiance, np.float64)

    def flux_estimate(self, scene_radius):
        return float(self.radiance @ LUMINANCE) * np.pi * np.pi * scene_radius ** 2

    def _sample_incident(self, p, n, u1, u2):
        wi, cos = cosine_hemisphere(u1, u2, n)
        factor = np.pi / np.maximum(cos, 1e-12)
        return wi, np.full(len(p), np.inf), factor[:, None] * self.radiance

    def mis(self, p, n, w):
        """Every ray that leaves finds the world: pdf cos / pi about the shading normal."""
        cos = dot(n, w)
        return (np.full(len(p), np.inf), np.broadcast_to(self.radiance, (len(p), 3)),
                np.maximum(cos, 0.0) / np.pi)

    def emit(self, count, rng, center, radius):
        dirs = uniform_sphere(rng.random(count), rng.random(count))
        origins = _disc_facing(rng, dirs, center, radius)
        return origins, dirs, np.broadcast_to(self.radiance * 4.0 * np.pi * np.pi * radius * radius,
                                              (count, 3)).copy()


class LightSet:
    """Every emitter of a scene. Light paths start from all of them, chosen in proportion to estimated power.
    Next-event estimation picks among the *local* ones (all but the world) by their importance at the shading
    point (``selection``), while the world, which a
    cosine-weighted ray samples as well as anything can, gets its own sample at every light sample (the way
    Cycles' BSDF sample finds the sky), so a bright sun does not starve the sky of samples."""

    def __init__(self, scene=None, lights=None, center=np.zeros(3), radius=1.0):
        if scene is not None:
            lo, hi = scene.bounds
            radius = max(0.5 * float(np.linalg.norm(hi - lo)), 1e-12)
            center = 0.5 * (lo + hi)
            lights = list(scene.lights)
            emissive = EmissiveTriangles.from_scene(scene)
            if emissive is not None:
                lights.append(emissive)
            if scene.world.max() > 0.0:
                lights.append(WorldLight(scene.world))
        self.center, self.radius = center, radius
        flux = np.array([max(l.flux_estimate(radius), 0.0) for l in lights], np.float64)
        self.lights = [l for l, f in zip(lights, flux) if f > 0.0]
        self.prob = _normalized(flux[flux > 0.0])
        self.world = next((l for l in self.lights if isinstance(l, WorldLight)), None)
        self.local = [l for l in self.lights if l is not self.world]

    def __len__(self):
        return len(self.lights)

    def only(self, index: int) -> "LightSet":
        """The same set restricted to light ``index``."""
        return LightSet(lights=[self.lights[index]], center=self.center, radius=self.radius)

    def emit(self, count: int, rng: np.random.Generator, prob: np.ndarray | None = None, with_light: bool = False):
        """``count`` light-path starts, lights chosen with ``prob`` (default: by power); power is divided by the
        selection probability, so the mean over paths estimates the total emitted power. ``with_light`` adds the
        index of each start's light (path verification follows a light's paths when it moves)."""
        prob = self.prob if prob is None else prob
        cdf = np.cumsum(prob)
        cdf[-1] = 1.0
        choice = sample_cdf(cdf, rng.random(count))
        origins, dirs, power = np.zeros((count, 3)), np.zeros((count, 3)), np.zeros((count, 3))
        for index, light in enumerate(self.lights):
            m = np.nonzero(choice == index)[0]
            if len(m):
                o, d, w = light.emit(len(m), rng, self.center, self.radius)
                origins[m], dirs[m], power[m] = o, d, w / prob[index]
        return (origins, dirs, power, choice) if with_light else (origins, dirs, power)

    def sample_incident(self, p, n, u_select, u1, u2, owner=None):
        """One sample of a local light per sample: (wi, dist, L_e / pdf including 1/p_select, normal at the light
        point or None, the index of each sample's light among the local ones). ``owner`` as in
        ``Light.sample_incident`` (the points p, n, the samples u). The normal is zero where the light point is not
        on scene geometry (analytic lights), None if no light is on geometry."""
        owner = np.arange(len(p)) if owner is None else owner
        if len(self.local) == 1:
            out = self.local[0].sample_incident(p, n, u1, u2, owner)
            return out[0], out[1], out[2], out[3] if len(out) == 4 else None, np.zeros(len(owner), np.int64)
        count = len(owner)
        wi, dist, weight, target_n = np.zeros((count, 3)), np.zeros(count), np.zeros((count, 3)), None
        prob = self.selection(p)
        choice = np.minimum((np.cumsum(prob[owner], axis=1) < u_select[:, None]).sum(axis=1), len(self.local) - 1)
        for index, light in enumerate(self.local):
            m = np.nonzero(choice == index)[0]
            if len(m) == 0:
                continue
            points, at = np.unique(owner[m], return_inverse=True)  # per-point work only where the light is chosen
            out = light.sample_incident(p[points], n[points], u1[m], u2[m], at)
            wi[m], dist[m], weight[m] = out[0], out[1], out[2] / prob[owner[m], index][:, None]
            if len(out) == 4:
                target_n = np.zeros((count, 3)) if target_n is None else target_n
                target_n[m] = out[3]
        return wi, dist, weight, target_n, choice

    def local_pdf(self, p, n, w, which):
        """(K,) the solid-angle pdf with which ``sample_incident`` draws direction w from point p (normal n), with
        the light ``which`` (index among the local lights) chosen: its selection probability times its own pdf;
        NaN where that light cannot say (``Light.mis`` None)."""
        out = np.full(len(p), np.nan)
        prob = self.selection(p)
        for index, light in enumerate(self.local):
            m = np.nonzero(which == index)[0]
            found = light.mis(p[m], n[m], w[m]) if len(m) else None
            if found is not None:
                out[m] = prob[m, index] * found[2]
        return out

    def selection(self, p: np.ndarray) -> np.ndarray:
        """(N, L) probabilities of choosing each local light at points p: in proportion to its importance there
        (a light tree's idea in its simplest form: near a small lamp, the lamp), with 10 % spread uniformly so no
        light that could matter is starved."""
        if len(self.local) <= 1:  # no choice to make
            return np.ones((len(p), len(self.local)))
        imp = np.stack([light.importance(p, self.radius) for light in self.local], axis=1)
        total = imp.sum(axis=1, keepdims=True)
        share = np.where(total > 0, imp / np.where(total > 0, total, 1.0), 1.0 / len(self.local))
        return 0.9 * share + 0.1 / len(self.local)


def _normalized(weights: np.ndarray) -> np.ndarray:
    return weights / weights.sum() if len(weights) and weights.sum() > 0 else weights
