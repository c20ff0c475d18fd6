"""Area lights in Cycles' units: power P [W] over area A, a one-sided Lambertian emitter of radiance P / (pi A);
rectangles are sampled by solid angle (spherical rectangles), discs and ellipses by area."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.color import LUMINANCE
from ..core.sampling import concentric_disk, cosine_hemisphere, dot, normalize
from ..core.compiled import kernel
from .light import Light


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
    planar = True  # one-sided, in the plane of its centre and axes

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

    def orientation(self):
        """One-sided along its normal, within half the spread of it (at most 90 degrees)."""
        return self.normal, 0.0, min(0.5 * float(np.clip(self.spread, 0.0, np.pi)), 0.5 * np.pi)

    def intensity_estimate(self):
        """Along the normal: radiance x area x the spread's profile there, P / pi for a Lambertian emitter."""
        return self.flux_estimate(1.0) / np.pi * float(self.spread_profile(np.ones(1))[0])

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
        if not front.any():
            return wi, dist, weight
        at = np.where(front, np.cumsum(front) - 1, -1)[owner]  # each sample's point among those in front, or -1
        x, y, z, lx, ly = self._frame()
        h = 0.5 * float(np.clip(self.spread, np.radians(1.0), np.pi))
        lambertian = h >= 0.5 * np.pi - 1e-6  # ``spread_profile``'s two cases
        norm = 1.0 if lambertian else np.tan(h) * np.sin(h) ** 2 - h + np.sin(h) * np.cos(h)
        _rectangle_samples(at, np.stack(self._spherical_rectangle(p[front]), axis=1), u1, u2, np.stack([x, y, z]),
                           lx, ly, self.normal, self.radiance, lambertian, np.tan(h), norm, wi, dist, weight)
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


@kernel
def _rectangle_samples(at, per_point, u1, u2, frame, lx, ly, normal, radiance, lambertian, tan_h, norm,
                       wi, dist, weight):
    """The per-sample part of Urena et al.'s Algorithm 1, fused (``_sample_spherical_rectangle``): for each sample i
    of the point ``at[i]`` (-1: behind the light, left zero), the direction ``wi``, distance ``dist`` and weight
    L x solid angle x ``spread_profile`` (``lambertian``: 1; else from tan(h) and its normalisation ``norm``).
    ``per_point`` (P,7): ``_spherical_rectangle``'s x0, y0, zs, b0, b1, k, solid; ``frame`` the rows x, y, z."""
    for i in range(len(at)):
        j = at[i]
        if j < 0:
            continue
        x0, y0, zs, b0, b1, k, solid = (per_point[j, 0], per_point[j, 1], per_point[j, 2], per_point[j, 3],
                                        per_point[j, 4], per_point[j, 5], per_point[j, 6])
        z0 = -abs(zs)
        au = u1[i] * solid + k
        fu = (np.cos(au) * b0 - b1) / np.sin(au)
        cu = _clip(np.sign(fu) / np.sqrt(fu * fu + b0 * b0), -1.0, 1.0)
        xu = _clip(-(cu * z0) / np.sqrt(max(1.0 - cu * cu, 1e-300)), x0, x0 + lx)
        dd = np.sqrt(xu * xu + z0 * z0)
        y1 = y0 + ly
        h0 = y0 / np.sqrt(dd * dd + y0 * y0)
        h1 = y1 / np.sqrt(dd * dd + y1 * y1)
        hv = h0 + u2[i] * (h1 - h0)
        yv = hv * dd / np.sqrt(max(1.0 - hv * hv, 1e-300)) if hv * hv < 1.0 - 1e-6 else y1
        xu = 0.0 if np.isnan(xu) else xu
        yv = 0.0 if np.isnan(yv) else yv
        length = 0.0
        for c in range(3):
            wi[i, c] = xu * frame[0, c] + yv * frame[1, c] + zs * frame[2, c]
            length += wi[i, c] * wi[i, c]
        length = np.sqrt(length)
        dist[i] = length
        for c in range(3):
            wi[i, c] /= max(length, 1e-300)
        cos_l = max(-(wi[i, 0] * normal[0] + wi[i, 1] * normal[1] + wi[i, 2] * normal[2]), 0.0)
        if cos_l > 0.0:
            if lambertian:
                profile = 1.0
            else:
                c = _clip(cos_l, 1e-9, 1.0)
                profile = max(tan_h - np.sqrt(1.0 - c * c) / c, 0.0) / norm
            for c in range(3):
                weight[i, c] = solid * profile * radiance[c]


@kernel
def _clip(value, lo, hi):
    """np.clip of one number (NaN stays NaN)."""
    return lo if value < lo else (hi if value > hi else value)
