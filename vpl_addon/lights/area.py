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
    visible: bool = False  # camera rays see it (``Light.visible``): a field, so the light's record keeps it
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

    def _corner(self):
        """The rectangle's corner -axis_u/2 - axis_v/2 and its frame (``_frame``): what ``_setup`` takes."""
        x, y, z, lx, ly = self._frame()
        return self.center - 0.5 * self.axis_u - 0.5 * self.axis_v, np.stack([x, y, z]), lx, ly

    def _solid_angles(self, p):
        """(P,) the solid angle the rectangle subtends at each point (0 where degenerate)."""
        corner, frame, lx, ly = self._corner()
        return _solid_angles(np.asarray(p, np.float64), corner, frame, lx, ly)

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
        at = np.where(front, np.arange(len(p)), -1)[owner]  # each sample's point, or -1 behind the light
        corner, frame, lx, ly = self._corner()
        h = 0.5 * float(np.clip(self.spread, np.radians(1.0), np.pi))
        lambertian = h >= 0.5 * np.pi - 1e-6  # ``spread_profile``'s two cases
        norm = 1.0 if lambertian else np.tan(h) * np.sin(h) ** 2 - h + np.sin(h) * np.cos(h)
        _rectangle_samples(at, np.asarray(p, np.float64), corner, frame, lx, ly, u1, u2, self.normal, self.radiance,
                           lambertian, np.tan(h), norm, wi, dist, weight)
        return wi, dist, weight

    def seen(self, origins, dirs):
        """What the rays meet of the light (``_met``): their distances and the radiance they see."""
        t, radiance, _, _ = self._met(origins, dirs)
        return t, radiance

    def _met(self, p, w):
        """Where rays from p along w meet the light's plane in front of its emitting side and inside it: (distance,
        radiance seen, which rays do, the cosine at the light), distance and radiance 0 elsewhere."""
        facing = -dot(w, self.normal)  # cos at the light: it emits along its normal
        t = dot(p - self.center, self.normal) / np.where(facing > 0.0, facing, 1.0)
        q = p + t[:, None] * w - self.center
        a = dot(q, self.axis_u) / dot(self.axis_u, self.axis_u)  # in [-1/2, 1/2] across the light
        b = dot(q, self.axis_v) / dot(self.axis_v, self.axis_v)
        inside = 4.0 * (a * a + b * b) <= 1.0 if self.round else (np.abs(a) <= 0.5) & (np.abs(b) <= 0.5)
        hit = (facing > 0.0) & (t > 0.0) & inside & np.isfinite(t)
        radiance = np.where(hit[:, None], self.spread_profile(facing)[:, None] * self.radiance, 0.0)
        return np.where(hit, t, 0.0), radiance, hit, facing

    def mis(self, p, n, w):
        """``_met``, and the pdf: the spherical rectangle's 1 / solid angle, or for a disk the area sampling's d^2 /
        (cos A)."""
        t, radiance, hit, facing = self._met(p, w)
        pdf = np.zeros(len(p))
        if self.round:
            pdf[hit] = t[hit] ** 2 / np.maximum(facing[hit] * self.area, 1e-300)
        else:  # the spherical rectangle's set-up only where the ray finds the light
            solid = self._solid_angles(p[hit])
            pdf[hit] = np.where(solid > 0.0, 1.0 / np.maximum(solid, 1e-300), 0.0)
        return t, radiance, pdf

    def emit(self, count, rng, center, radius):
        origins = self.sample_points(rng.random(count), rng.random(count))
        dirs, cos = cosine_hemisphere(rng.random(count), rng.random(count), np.broadcast_to(self.normal, (count, 3)))
        return origins, dirs, self.spread_profile(cos)[:, None] * self.power


@kernel
def _setup(p, corner, frame, lx, ly):
    """The per-point part of Urena et al.'s Algorithm 1 up to the solid angle, at point p: the rectangle's corner
    (x0, y0) in its frame seen from p, p's signed height zs over the rectangle's plane (the algorithm works with
    z0 = -|zs|, the rectangle below the point), b0 and b1 (the z of the first and third edge normals), k and the
    solid angle (0 where degenerate)."""
    d0, d1, d2 = corner[0] - p[0], corner[1] - p[1], corner[2] - p[2]
    x0 = d0 * frame[0, 0] + d1 * frame[0, 1] + d2 * frame[0, 2]
    y0 = d0 * frame[1, 0] + d1 * frame[1, 1] + d2 * frame[1, 2]
    zs = d0 * frame[2, 0] + d1 * frame[2, 1] + d2 * frame[2, 2]
    z0 = -abs(zs)
    # the unit normals of the spherical quad's edges, in the frame: (0, z0, -y0), (-z0, 0, x1), (0, -z0, y1),
    # (z0, 0, -x0) over their lengths
    x1, y1 = x0 + lx, y0 + ly
    l0 = max(np.sqrt(z0 * z0 + y0 * y0), 1e-300)
    l1 = max(np.sqrt(z0 * z0 + x1 * x1), 1e-300)
    l2 = max(np.sqrt(z0 * z0 + y1 * y1), 1e-300)
    l3 = max(np.sqrt(z0 * z0 + x0 * x0), 1e-300)
    # the angles between neighbouring edges: arccos(-n_a . n_b), n0 . n1 = -y0 x1, n1 . n2 = x1 y1, n2 . n3 = -y1 x0,
    # n3 . n0 = x0 y0 over the lengths
    g0 = np.arccos(_clip(y0 * x1 / (l0 * l1), -1.0, 1.0))
    g1 = np.arccos(_clip(-x1 * y1 / (l1 * l2), -1.0, 1.0))
    g2 = np.arccos(_clip(y1 * x0 / (l2 * l3), -1.0, 1.0))
    g3 = np.arccos(_clip(-x0 * y0 / (l3 * l0), -1.0, 1.0))
    k = 2.0 * np.pi - g2 - g3
    solid = g0 + g1 - k
    if not (np.isfinite(solid) and solid > 1e-12):
        solid = 0.0
    return x0, y0, zs, -y0 / l0, y1 / l2, k, solid


@kernel
def _solid_angles(p, corner, frame, lx, ly):
    out = np.empty(len(p))
    for i in range(len(p)):
        out[i] = _setup(p[i], corner, frame, lx, ly)[6]
    return out


@kernel
def _rectangle_samples(at, p, corner, frame, lx, ly, u1, u2, normal, radiance, lambertian, tan_h, norm,
                       wi, dist, weight):
    """The samples of Urena et al.'s Algorithm 1 (``_sample_spherical_rectangle``): for each sample i of the
    point ``at[i]`` (-1: behind the light, left zero; a point's samples side by side, so its ``_setup`` is made
    once), the direction ``wi``, distance ``dist`` and weight L x solid angle x ``spread_profile``
    (``lambertian``: 1; else from tan(h) and its normalisation ``norm``). ``frame`` holds the rows x, y, z."""
    last = -1
    x0 = y0 = zs = b0 = b1 = k = solid = 0.0
    for i in range(len(at)):
        j = at[i]
        if j < 0:
            continue
        if j != last:
            x0, y0, zs, b0, b1, k, solid = _setup(p[j], corner, frame, lx, ly)
            last = j
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
