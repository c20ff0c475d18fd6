"""The glossy lobe of the Principled BSDF's metallic part, as Cycles evaluates it: GGX with F82-tint Fresnel and
multiple-scattering energy compensation.

- Distribution and masking (Walter et al. 2007; Heitz 2014, eq. 72): D(h) = a^2 / (pi (1 + (a^2 - 1) cos^2)^2),
  Lambda(w) = (sqrt(1 + a^2 tan^2) - 1) / 2, G2 = 1 / (1 + Lambda(v) + Lambda(l)); a = roughness^2.
- Fresnel: F82-tint (Kutz et al., "Novel aspects of the Adobe Standard Material"): Schlick's F0 + (1 - F0)(1 - mu)^5
  minus b mu (1 - mu)^6, where b makes F at mu = 1/7 equal tint x Schlick(1/7). Base Color is F0, Specular Tint the
  tint; a white tint gives plain Schlick.
- Sampling: visible normals (Heitz, "Sampling the GGX Distribution of Visible Normals", JCGT 2018), so the sample
  weight is F G2 / G1(v) and pdf(l) = D G1(v) / (4 cos_v).
- Energy compensation (Kulla and Conty, "Revisiting Physically Based Shading at Imageworks", 2017): the lobe is
  scaled by 1 + F_ms (1 - E(mu)) / E(mu) with F_ms = F_avg E_avg / (1 - F_avg (1 - E_avg)), E the single-scattering
  albedo at the view angle and E_avg its cosine-weighted mean. Cycles' ``Glossy Color`` is the lobe's estimated
  albedo (E + F_ms (1 - E)) mix(F0, 1, s(mu)), with s the lobe-averaged Schlick weight (1 - v.h)^5.
  E, E_avg and s are integrated here per roughness (``albedo_table``) instead of read from Cycles' tables.

Directions: ``v`` toward the viewer, ``l`` toward the light, ``n`` the shading normal, all unit (K,3). ``value`` is
f(v, l) cos(theta_l) per colour channel, without the material's metallic weight.
"""
from __future__ import annotations

from dataclasses import dataclass, fields
from functools import lru_cache

import numpy as np

from ..core.sampling import concentric_disk, dot, orthonormal_basis, stratified_2d

MIN_ALPHA = 1e-3  # sharper lobes are treated as this rough (Cycles switches to a mirror below a^2 = 5e-7)
MU_BAR = 1.0 / 7.0
TABLE_MU = 32  # view-angle steps of the albedo tables
TABLE_SAMPLES = 64  # per side: 64 x 64 stratified visible normals per table entry


def alpha(roughness: np.ndarray) -> np.ndarray:
    return np.maximum(np.asarray(roughness, np.float64) ** 2, MIN_ALPHA)


def schlick(f0: np.ndarray, mu: np.ndarray) -> np.ndarray:
    return f0 + (1.0 - f0) * ((1.0 - np.clip(mu, 0.0, 1.0)) ** 5)[:, None]


def f82_b(f0: np.ndarray, tint: np.ndarray) -> np.ndarray:
    """b of the F82-tint model: the edge darkening that makes F(1/7) = tint x Schlick(F0, 1/7)."""
    at_bar = f0 + (1.0 - f0) * (1.0 - MU_BAR) ** 5
    return at_bar * (1.0 - tint) / (MU_BAR * (1.0 - MU_BAR) ** 6)


def fresnel(f0: np.ndarray, b: np.ndarray, mu: np.ndarray) -> np.ndarray:
    """(K,3) F82-tint reflectance at cos ``mu`` between the view and the microfacet normal."""
    mu = np.clip(mu, 0.0, 1.0)
    return np.clip(schlick(f0, mu) - b * (mu * (1.0 - mu) ** 6)[:, None], 0.0, 1.0)


def _lambda(a2: np.ndarray, cos: np.ndarray) -> np.ndarray:
    cos2 = np.maximum(cos * cos, 1e-300)
    return 0.5 * (np.sqrt(1.0 + a2 * np.maximum(1.0 / cos2 - 1.0, 0.0)) - 1.0)


def _d(a2: np.ndarray, cos_h: np.ndarray) -> np.ndarray:
    return a2 / (np.pi * (1.0 + (a2 - 1.0) * cos_h * cos_h) ** 2)


def evaluate(n, v, l, a, f0, b):
    """(value (K,3) = F D G2 / (4 cos_v), pdf (K,) of ``sample`` choosing l): zero where either direction is
    below the shading normal."""
    cos_v, cos_l = dot(n, v), dot(n, l)
    ok = (cos_v > 0.0) & (cos_l > 0.0)
    h = v + l
    h = h / np.maximum(np.linalg.norm(h, axis=1, keepdims=True), 1e-300)
    a2 = a * a
    d = _d(a2, np.clip(dot(n, h), 0.0, 1.0))
    lam_v, lam_l = _lambda(a2, cos_v), _lambda(a2, cos_l)
    common = np.where(ok, d / (4.0 * np.maximum(cos_v, 1e-300)), 0.0)
    value = fresnel(f0, b, dot(v, h)) * (common / (1.0 + lam_v + lam_l))[:, None]
    return value, common / (1.0 + lam_v)


def sample(n, v, a, u1, u2):
    """(l, g, h): a direction l drawn from visible normals h, and g = G2 / G1(v) (K,), so that value / pdf =
    F(v.h) g. Rows whose l falls below the normal have g = 0."""
    t, s = orthonormal_basis(n)
    local = np.stack([dot(v, t), dot(v, s), dot(v, n)], axis=1)
    stretched = local * np.stack([a, a, np.ones_like(a)], axis=1)
    stretched /= np.maximum(np.linalg.norm(stretched, axis=1, keepdims=True), 1e-300)
    lensq = stretched[:, 0] ** 2 + stretched[:, 1] ** 2
    safe = np.maximum(np.sqrt(lensq), 1e-300)
    t1 = np.where((lensq > 1e-14)[:, None], np.stack([-stretched[:, 1], stretched[:, 0], np.zeros_like(a)], 1)
                  / safe[:, None], np.array([1.0, 0.0, 0.0]))
    t2 = np.cross(stretched, t1)
    x, y = concentric_disk(u1, u2)
    y = (1.0 - 0.5 * (1.0 + stretched[:, 2])) * np.sqrt(np.maximum(1.0 - x * x, 0.0)) + \
        0.5 * (1.0 + stretched[:, 2]) * y
    z = np.sqrt(np.maximum(1.0 - x * x - y * y, 0.0))
    hh = x[:, None] * t1 + y[:, None] * t2 + z[:, None] * stretched
    hh = np.stack([a * hh[:, 0], a * hh[:, 1], np.maximum(hh[:, 2], 0.0)], axis=1)
    hh /= np.maximum(np.linalg.norm(hh, axis=1, keepdims=True), 1e-300)
    h = hh[:, :1] * t + hh[:, 1:2] * s + hh[:, 2:] * n
    l = 2.0 * dot(v, h)[:, None] * h - v
    a2 = a * a
    cos_l = dot(n, l)
    lam_v, lam_l = _lambda(a2, dot(n, v)), _lambda(a2, cos_l)
    weight = np.where(cos_l > 0.0, (1.0 + lam_v) / (1.0 + lam_v + lam_l), 0.0)
    return l, weight, h


@lru_cache(maxsize=64)
def albedo_table(roughness: float) -> tuple[np.ndarray, np.ndarray, float]:
    """(E (TABLE_MU,), s (TABLE_MU,), E_avg) of the lobe with F = 1 at view cosines ``mu_grid()``: E the
    single-scattering albedo, s the lobe average of (1 - v.h)^5, E_avg = 2 int E mu dmu. Deterministic
    (stratified visible-normal samples), so every render and test sees the same numbers."""
    mu = mu_grid()
    count = TABLE_SAMPLES * TABLE_SAMPLES
    u, w = stratified_2d(1, count, np.random.default_rng(0))
    u1, u2 = np.tile(u.ravel(), len(mu)), np.tile(w.ravel(), len(mu))
    m = np.repeat(mu, count)
    v = np.stack([np.sqrt(1.0 - m * m), np.zeros_like(m), m], axis=1)
    n = np.tile([0.0, 0.0, 1.0], (len(m), 1))
    a = np.full(len(m), float(alpha(roughness)))
    _, weight, h = sample(n, v, a, u1, u2)
    e = weight.reshape(len(mu), count).mean(axis=1)
    schlick_part = (weight * (1.0 - np.clip(dot(v, h), 0.0, 1.0)) ** 5).reshape(len(mu), count).mean(axis=1)
    s = schlick_part / np.maximum(e, 1e-300)
    e_avg = float(np.sum(2.0 * e * mu) / TABLE_MU)  # midpoint rule on the grid's cell centres
    return e, s, e_avg


def mu_grid() -> np.ndarray:
    return (np.arange(TABLE_MU) + 0.5) / TABLE_MU


@dataclass
class Compensation:
    """Per point: the multiple-scattering factor of the lobe and Cycles' ``Glossy Color`` at the view angle."""

    scale: np.ndarray  # (K,3) 1 + F_ms (1 - E) / E
    color: np.ndarray  # (K,3) (E + F_ms (1 - E)) mix(F0, 1, s), without the metallic weight


def compensation(roughness: np.ndarray, f0: np.ndarray, b: np.ndarray, mu: np.ndarray) -> Compensation:
    scale = np.ones_like(f0)
    color = np.zeros_like(f0)
    mu = np.clip(mu, 0.0, 1.0)
    f_avg = np.clip(f0 + (1.0 - f0) / 21.0 - b / 126.0, 0.0, 1.0)  # hemispherical mean of the F82-tint curve
    for r in np.unique(roughness):
        rows = roughness == r
        e_tab, s_tab, e_avg = albedo_table(float(r))
        e = np.interp(mu[rows], mu_grid(), e_tab)[:, None]
        s = np.interp(mu[rows], mu_grid(), s_tab)[:, None]
        f_ms = f_avg[rows] * e_avg / np.maximum(1.0 - f_avg[rows] * (1.0 - e_avg), 1e-6)
        e = np.maximum(e, 1e-6)
        scale[rows] = 1.0 + f_ms * (1.0 - e) / e
        color[rows] = (e + f_ms * (1.0 - e)) * (f0[rows] + (1.0 - f0[rows]) * s)
    return Compensation(scale, color)


@dataclass
class GlossyLobe:
    """The metallic lobe at a set of points, seen from their viewers: f cos with the material's weight (metallic x
    the energy compensation) folded in, and Cycles' ``Glossy Color`` of each point."""

    normal: np.ndarray  # (K,3) shading normals
    view: np.ndarray  # (K,3) toward the viewer
    alpha: np.ndarray  # (K,)
    f0: np.ndarray  # (K,3)
    edge: np.ndarray  # (K,3)
    weight: np.ndarray  # (K,3) metallic x compensation scale
    color: np.ndarray  # (K,3) metallic x the compensated albedo estimate: Cycles' Glossy Color

    @staticmethod
    def of(surface) -> "GlossyLobe":
        view = -surface.incident
        shiny = np.nonzero(surface.metallic > 0.0)[0]  # the rest has no lobe: weight and colour stay 0
        comp = compensation(surface.roughness[shiny], surface.specular[shiny], surface.edge[shiny],
                            dot(surface.shading_normal[shiny], view[shiny]))
        m = surface.metallic[shiny, None]
        weight, color = np.zeros_like(surface.specular), np.zeros_like(surface.specular)
        weight[shiny], color[shiny] = m * comp.scale, m * comp.color
        return GlossyLobe(surface.shading_normal, view, alpha(surface.roughness), surface.specular, surface.edge,
                          weight, color)

    def take(self, rows) -> "GlossyLobe":
        return GlossyLobe(*(getattr(self, f.name)[rows] for f in fields(GlossyLobe)))

    @staticmethod
    def concat(parts: list["GlossyLobe"]) -> "GlossyLobe":
        return GlossyLobe(*(np.concatenate([getattr(p, f.name) for p in parts]) for f in fields(GlossyLobe)))

    def evaluate(self, l: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(f cos (R,3) with the weight, pdf (R,) of ``sample``) toward directions ``l`` (R,3) at points ``rows``."""
        value, pdf = evaluate(self.normal[rows], self.view[rows], l, self.alpha[rows], self.f0[rows],
                              self.edge[rows])
        return value * self.weight[rows], pdf

    def sample(self, u1: np.ndarray, u2: np.ndarray, rows: np.ndarray):
        """(l (R,3), f cos / pdf (R,3) with the weight, pdf (R,)) at points ``rows``."""
        n, v, a = self.normal[rows], self.view[rows], self.alpha[rows]
        l, g, h = sample(n, v, a, u1, u2)
        _, pdf = evaluate(n, v, l, a, self.f0[rows], self.edge[rows])
        f = fresnel(self.f0[rows], self.edge[rows], dot(v, h))
        return l, f * (g[:, None] * self.weight[rows]), np.where(g > 0.0, pdf, 0.0)
