"""The glossy lobes of the Principled BSDF as Cycles evaluates them (``svm/closure.h``): the metallic lobe (GGX with
F82-tint Fresnel) and the dielectric specular layer (GGX with the real dielectric Fresnel), both with
multiple-scattering energy compensation. They share the distribution, masking and sampling; only the Fresnel
differs, so one lobe (``GlossyLobe``) carries their sum.

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
  E, E_avg and s are integrated here on a grid of roughnesses (``albedo_table``, interpolated, so textured
  roughness costs nothing more) instead of read from Cycles' tables. Here s is the average weighted by the lobe,
  int f s / int f, so that the albedo estimate is the compensated lobe's integral; Cycles' own s tables
  (``cycles_precompute.cpp``) average s over its visible-normal samples unweighted by G2 / G1 (and count samples
  that leave below the horizon as 0), which differs from this by up to about 10 % of s (a few per cent of the
  albedo) at rough or grazing views.
- Dielectric specular layer (Cycles' generalized Schlick Fresnel with exponent -eta): F = mix(F0 tint, 1, s) with
  s = clamp((F_real(v.h, eta) - F0_real) / (1 - F0_real), 0, 1), F_real the unpolarised Fresnel reflectance of a
  smooth dielectric (Walter et al. 2007, eq. 22), F0_real = ((eta - 1) / (eta + 1))^2, and F0 tint clamped to
  [0, 1]. Specular IOR Level l != 0.5 scales F0 by 2 l and sets eta from it (``specular_layer``). Its compensation
  uses F_ss = mix(F0 tint, 1, s(F_ss_real)), F_ss_real = 2 int F_real(mu) mu dmu (integrated numerically; Cycles
  uses Kulla and Conty's fit); its albedo A = (E + F_ms (1 - E)) mix(F0 tint, 1, s_bar), s_bar the lobe average of
  s, is its Glossy Color per unit weight and leaves 1 - max(A) to the diffuse lobe below it (``layer_albedo``).
  Cycles reads s_bar for eta < 1 from its eta > 1 table at 1 / eta (same F0); here it is the eta < 1 lobe's own,
  whose total internal reflection makes it change fast with the view angle: the bilinear tables are within 0.5 %
  of the lobe for eta > 1 but up to 4 % off for eta < 1 where the half vectors start to pass the critical angle.

Directions: ``v`` toward the viewer, ``l`` (``wl`` in the code) toward the light, ``n`` the shading normal, all
unit (K,3). ``value`` is f(v, l) cos(theta_l) per colour channel, without the material's weights.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property, lru_cache
from types import SimpleNamespace

import numpy as np

from ..core.color import largest
from ..core.compiled import inline, kept_tables, kernel
from ..core.rows import concat_fields, take_fields
from ..core.sampling import basis, dot, stratified_2d

MIN_ALPHA = 1e-3  # sharper lobes are treated as this rough (Cycles switches to a mirror below a^2 = 5e-7)
MU_BAR = 1.0 / 7.0
TABLE_MU = 32  # view-cosine steps of the albedo tables
TABLE_ROUGHNESS = 33  # roughness steps of the tables, 0 to 1
TABLE_SAMPLES = 2048  # stratified visible normals per table entry (a power of two: Sobol points)


def alpha(roughness: np.ndarray) -> np.ndarray:
    return np.maximum(np.asarray(roughness, np.float64) ** 2, MIN_ALPHA)


def schlick(f0: np.ndarray, mu: np.ndarray) -> np.ndarray:
    return f0 + (1.0 - f0) * ((1.0 - np.clip(mu, 0.0, 1.0)) ** 5)[:, None]


def f82_b(f0: np.ndarray, tint: np.ndarray) -> np.ndarray:
    """b of the F82-tint model: the edge darkening that makes F(1/7) = tint x Schlick(F0, 1/7) (``edge``)."""
    return _each(_edge_all, f0, tint)


@kernel
def edge(f0, tint):
    """``f82_b`` of one channel."""
    return (f0 + (1.0 - f0) * (1.0 - MU_BAR) ** 5) * (1.0 - tint) / (MU_BAR * (1.0 - MU_BAR) ** 6)


@kernel
def _edge_all(f0, tint, out):
    for i in range(len(out)):
        out[i] = edge(f0[i], tint[i])


def fresnel(f0: np.ndarray, b: np.ndarray, mu: np.ndarray) -> np.ndarray:
    """(K,3) F82-tint reflectance at cos ``mu`` (K,) between the view and the microfacet normal (``_f82``)."""
    return _each(_f82_all, f0, b, np.asarray(mu)[:, None])


def _each(loop, *arrays) -> np.ndarray:
    """A scalar kernel over numpy arrays: ``loop(*flat inputs, flat output)`` on the arrays broadcast against
    each other (float64 copies of their own), the output in their shape."""
    arrays = [np.array(x, np.float64) for x in np.broadcast_arrays(*arrays)]
    out = np.empty(arrays[0].shape)
    loop(*(x.reshape(-1) for x in arrays), out.reshape(-1))
    return out


@kernel
def _f82(f0, b, mu):
    """F82-tint reflectance of one channel: Schlick's F0 + (1 - F0)(1 - mu)^5 minus b mu (1 - mu)^6, clamped."""
    mu = min(max(mu, 0.0), 1.0)
    m = 1.0 - mu
    return min(max(f0 + (1.0 - f0) * m ** 5 - b * (mu * m ** 6), 0.0), 1.0)


@kernel
def _f82_all(f0, b, mu, out):
    for i in range(len(out)):
        out[i] = _f82(f0[i], b[i], mu[i])


def constant_reflectance_tint(colour) -> np.ndarray:
    """(3,) the F82 tint with F0 = ``colour`` whose Fresnel has the cosine-weighted hemispherical mean ``colour``:
    Cycles' Glossy BSDF, which has no Fresnel (its reflectance is its colour at every angle), as a metallic lobe. The
    curve is the colour at normal incidence, within 4 % of it out to 60 degrees for colours of 0.3 and up, dips
    near 71 degrees (to 0.90 of a colour of 0.3, 0.60 of 0.1) and turns white at grazing; black keeps a mean of 0.0044
    (tint 0). Bisection, 40 steps on 256 angles."""
    colour = np.clip(np.asarray(colour, np.float64).reshape(3), 0.0, 1.0)
    mu = (np.arange(256) + 0.5) / 256
    f0 = np.broadcast_to(colour, (256, 3))
    lo, hi = np.zeros(3), np.ones(3)
    for _ in range(40):
        tint = (lo + hi) / 2
        mean = 2.0 * (mu[:, None] * fresnel(f0, f82_b(colour, tint)[None], mu)).mean(axis=0)
        too_bright = mean > colour
        hi, lo = np.where(too_bright, tint, hi), np.where(too_bright, lo, tint)
    return (lo + hi) / 2


@kernel
def f0_from_ior(eta: np.ndarray) -> np.ndarray:
    """Normal-incidence reflectance ((eta - 1) / (eta + 1))^2 of a dielectric of relative IOR ``eta``."""
    return ((eta - 1.0) / (eta + 1.0)) ** 2


def dielectric_fresnel(cos_i: np.ndarray, eta: np.ndarray) -> np.ndarray:
    """Unpolarised reflectance of a smooth dielectric interface of relative IOR ``eta`` at cosine ``cos_i``
    (Walter et al. 2007, eq. 22); 1 under total internal reflection (eta < 1). Broadcasts like numpy."""
    return _each(_dielectric_all, cos_i, eta)


@kernel
def _dielectric(cos_i, eta):
    """``dielectric_fresnel`` of one cosine."""
    c = abs(cos_i)
    g2 = eta * eta - 1.0 + c * c
    if not g2 > 0.0:
        return 1.0
    g = np.sqrt(g2)
    a = (g - c) / max(g + c, 1e-300)
    b = (c * (g + c) - 1.0) / max(c * (g - c) + 1.0, 1e-300)
    return min(max(0.5 * a * a * (1.0 + b * b), 0.0), 1.0)


@kernel
def _dielectric_all(cos_i, eta, out):
    for i in range(len(out)):
        out[i] = _dielectric(cos_i[i], eta[i])


def specular_layer(ior: np.ndarray, level: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(F0, eta) of the Principled BSDF's dielectric layer from its IOR and Specular IOR Level, as Cycles adjusts
    them (``svm/closure.h``): IOR >= 1e-5 and level >= 0; at level 0.5 F0 = F0(IOR) and eta = IOR; otherwise
    F0 = F0(IOR) x 2 level and eta = (1 + sqrt F0) / (1 - sqrt F0) with F0 clamped to 0.99 there (inverted when
    IOR < 1). eta 1 (level 0, or IOR 1): no layer. F0 is returned unclamped; the lobe clamps F0 x tint to 1."""
    ior = np.maximum(np.asarray(ior, np.float64), 1e-5)
    level = np.maximum(np.asarray(level, np.float64), 0.0)
    adjust = level != 0.5
    f0 = f0_from_ior(ior) * np.where(adjust, 2.0 * level, 1.0)
    root = np.sqrt(np.clip(f0, 0.0, 0.99))
    eta = (1.0 + root) / (1.0 - root)
    eta = np.where(adjust, np.where(ior < 1.0, 1.0 / eta, eta), ior)
    return f0, eta


def _interpolation(f0: np.ndarray | float, real: np.ndarray) -> np.ndarray:
    """s of the generalized Schlick Fresnel: where the real reflectance sits between F0_real and 1."""
    return np.clip((real - f0) / np.maximum(1.0 - f0, 1e-12), 0.0, 1.0)


@kernel
def _layer_share(eta, mu):
    """s of the dielectric layer's reflectance mix(F0 tint, 1, s) at cos ``mu`` between the view and the
    microfacet normal: ``_interpolation`` of the real reflectance."""
    f0 = f0_from_ior(eta)
    return min(max((_dielectric(mu, eta) - f0) / max(1.0 - f0, 1e-12), 0.0), 1.0)


def _lambda(a2: np.ndarray, cos: np.ndarray) -> np.ndarray:
    return _each(_lambda_all, a2, cos)


@kernel
def _lam(a2, cos):
    """Smith's Lambda of GGX at alpha^2 ``a2`` and cos ``cos``: (sqrt(1 + a^2 tan^2) - 1) / 2."""
    cos2 = max(cos * cos, 1e-300)
    return 0.5 * (np.sqrt(1.0 + a2 * max(1.0 / cos2 - 1.0, 0.0)) - 1.0)


@kernel
def _lambda_all(a2, cos, out):
    for i in range(len(out)):
        out[i] = _lam(a2[i], cos[i])


def smith_g1(a2: np.ndarray, cos: np.ndarray) -> np.ndarray:
    """GGX's Smith masking G1 = 1 / (1 + Lambda) for alpha^2 ``a2`` at cos ``cos`` (Walter et al. 2007, eq. 34)."""
    return 1.0 / (1.0 + _lambda(a2, cos))


def evaluate(n, v, wl, a, f0, b):
    """(value (K,3) = F D G2 / (4 cos_v), pdf (K,) of ``sample`` choosing l): zero where either direction is
    below the shading normal."""
    k = len(wl)
    value, pdf = np.empty((k, 3)), np.empty(k)
    f0, b = (np.array(np.broadcast_to(x, (k, 3)), np.float64) for x in (f0, b))
    _evaluate(*(np.ascontiguousarray(x, np.float64) for x in (n, v, wl, a)), f0, b, value, pdf)
    return value, pdf


@kernel
def _ggx(n, v, wl, a):
    """At one point, toward one direction wl: (D G2 / (4 cos_v) (the lobe's f cos with F = 1), the pdf of
    ``_visible_normal`` drawing wl, D G1(v) / (4 cos_v), and v.h); zero where v or wl is below n."""
    cos_v = n[0] * v[0] + n[1] * v[1] + n[2] * v[2]
    cos_l = n[0] * wl[0] + n[1] * wl[1] + n[2] * wl[2]
    h0, h1, h2 = v[0] + wl[0], v[1] + wl[1], v[2] + wl[2]
    length = max(np.sqrt(h0 * h0 + h1 * h1 + h2 * h2), 1e-300)
    h0, h1, h2 = h0 / length, h1 / length, h2 / length
    a2 = a * a
    cos_h = min(max(n[0] * h0 + n[1] * h1 + n[2] * h2, 0.0), 1.0)
    d = a2 / (np.pi * (1.0 + (a2 - 1.0) * cos_h * cos_h) ** 2)
    lam_v, lam_l = _lam(a2, cos_v), _lam(a2, cos_l)
    common = d / (4.0 * max(cos_v, 1e-300)) if cos_v > 0.0 and cos_l > 0.0 else 0.0
    return common / (1.0 + lam_v + lam_l), common / (1.0 + lam_v), v[0] * h0 + v[1] * h1 + v[2] * h2


@kernel
def _evaluate(n, v, wl, a, f0, b, value, pdf):
    for i in range(len(wl)):
        f, pdf[i], vh = _ggx(n[i], v[i], wl[i], a[i])
        for c in range(3):
            value[i, c] = _f82(f0[i, c], b[i, c], vh) * f


def sample(n, v, a, u1, u2):
    """(l, g, h): a direction l drawn from visible normals h, and g = G2 / G1(v) (K,), so that value / pdf =
    F(v.h) g. Rows whose l falls below the normal have g = 0."""
    k = len(u1)
    wl, g, h = np.empty((k, 3)), np.empty(k), np.empty((k, 3))
    _sample(*(np.ascontiguousarray(x, np.float64) for x in (n, v, a, u1, u2)), wl, g, h)
    return wl, g, h


@kernel
def _visible_normal(n, v, a, u1, u2, wl, h):
    """Heitz's visible-normal sample at one point: writes l into ``wl`` and the microfacet normal into ``h``;
    returns g = G2 / G1(v) (0 where l falls below n). The frame about n is ``sampling.basis``, the disk point
    ``sampling.concentric_disk``'s."""
    t0, t1, t2, s0, s1, s2 = basis(n[0], n[1], n[2])
    x0 = a * (v[0] * t0 + v[1] * t1 + v[2] * t2)  # the view in the frame, stretched
    x1 = a * (v[0] * s0 + v[1] * s1 + v[2] * s2)
    cos_v = v[0] * n[0] + v[1] * n[1] + v[2] * n[2]
    x2 = cos_v
    length = max(np.sqrt(x0 * x0 + x1 * x1 + x2 * x2), 1e-300)
    x0, x1, x2 = x0 / length, x1 / length, x2 / length
    lensq = x0 * x0 + x1 * x1
    if lensq > 1e-14:
        inv = max(np.sqrt(lensq), 1e-300)
        e0, e1, e2 = -x1 / inv, x0 / inv, 0.0
    else:
        e0, e1, e2 = 1.0, 0.0, 0.0
    f0, f1, f2 = x1 * e2 - x2 * e1, x2 * e0 - x0 * e2, x0 * e1 - x1 * e0  # stretched x e
    da, db = 2.0 * u1 - 1.0, 2.0 * u2 - 1.0
    if abs(da) > abs(db):
        r, phi = da, (np.pi / 4.0) * (db / da)
    else:
        r, phi = db, (np.pi / 2.0 - (np.pi / 4.0) * (da / db) if db != 0.0 else 0.0)
    dx, dy = r * np.cos(phi), r * np.sin(phi)
    dy = (1.0 - 0.5 * (1.0 + x2)) * np.sqrt(max(1.0 - dx * dx, 0.0)) + 0.5 * (1.0 + x2) * dy
    dz = np.sqrt(max(1.0 - dx * dx - dy * dy, 0.0))
    m0 = a * (dx * e0 + dy * f0 + dz * x0)
    m1 = a * (dx * e1 + dy * f1 + dz * x1)
    m2 = max(dx * e2 + dy * f2 + dz * x2, 0.0)
    length = max(np.sqrt(m0 * m0 + m1 * m1 + m2 * m2), 1e-300)
    m0, m1, m2 = m0 / length, m1 / length, m2 / length
    h[0], h[1], h[2] = m0 * t0 + m1 * s0 + m2 * n[0], m0 * t1 + m1 * s1 + m2 * n[1], m0 * t2 + m1 * s2 + m2 * n[2]
    vh = v[0] * h[0] + v[1] * h[1] + v[2] * h[2]
    for c in range(3):
        wl[c] = 2.0 * vh * h[c] - v[c]
    a2 = a * a
    cos_l = n[0] * wl[0] + n[1] * wl[1] + n[2] * wl[2]
    lam_v, lam_l = _lam(a2, cos_v), _lam(a2, cos_l)
    return (1.0 + lam_v) / (1.0 + lam_v + lam_l) if cos_l > 0.0 else 0.0


@kernel
def _sample(n, v, a, u1, u2, wl, g, h):
    for i in range(len(u1)):
        g[i] = _visible_normal(n[i], v[i], a[i], u1[i], u2[i], wl[i], h[i])


def roughness_grid() -> np.ndarray:
    return np.linspace(0.0, 1.0, TABLE_ROUGHNESS)


def mu_grid() -> np.ndarray:
    """(TABLE_MU,) view cosines of the tables: the centres of equal steps in the cosine."""
    return (np.arange(TABLE_MU) + 0.5) / TABLE_MU


@lru_cache(maxsize=1)
def _lobe_samples() -> tuple[np.ndarray, np.ndarray]:
    """(g, v.h), each (roughness, mu, samples) float32: the weights G2/G1 and view-half cosines of stratified
    visible-normal samples of the F = 1 lobe at every table entry. Deterministic, so every render sees the same
    tables; any Fresnel's lobe average is a reduction over them."""
    rough, mu = roughness_grid(), mu_grid()
    count = TABLE_SAMPLES
    u, w = stratified_2d(1, count, np.random.default_rng(0))
    u1, u2 = np.tile(u.ravel(), len(mu)), np.tile(w.ravel(), len(mu))
    m = np.repeat(mu, count)
    v = np.stack([np.sqrt(1.0 - m * m), np.zeros_like(m), m], axis=1)
    n = np.tile([0.0, 0.0, 1.0], (len(m), 1))
    g = np.empty((len(rough), len(mu), count), np.float32)
    vh = np.empty_like(g)
    for i, r in enumerate(rough):  # a roughness at a time: smaller temporaries, and faster
        _, weight, h = sample(n, v, np.full(len(m), float(alpha(r))), u1, u2)
        g[i], vh[i] = weight.reshape(len(mu), count), np.clip(dot(v, h), 0.0, 1.0).reshape(len(mu), count)
    return g, vh


@lru_cache(maxsize=1)
def _metal_tables() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(E, s, E_avg) on the grid: single-scattering albedo (roughness, mu), the lobe average of (1 - v.h)^5 and
    E_avg = 2 int E mu dmu (roughness,); kept on disk (``kept_tables``)."""
    return kept_tables("metal", __file__, _integrated_metal_tables)


def _integrated_metal_tables() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    g, vh = _lobe_samples()
    e = g.mean(axis=2, dtype=np.float64)
    s = (g * (1.0 - vh) ** 5).mean(axis=2, dtype=np.float64) / np.maximum(e, 1e-300)
    e_avg = np.sum(2.0 * e * mu_grid(), axis=1) / TABLE_MU  # midpoint rule on the cells' centres
    return e, s, e_avg


ETA_DIGITS = 4  # the dielectric tables are made per eta rounded to this many decimals


def dielectric_fss(eta: float) -> float:
    """F_ss_real = 2 int_0^1 F_real(mu, eta) mu dmu, the cosine-weighted hemispherical mean of the dielectric
    Fresnel (midpoint rule on 4096 steps; Cycles' ``fresnel_dielectric_Fss`` is a fit of the same integral)."""
    mu = (np.arange(4096) + 0.5) / 4096
    return float(np.sum(2.0 * dielectric_fresnel(mu, eta) * mu) / 4096)


@lru_cache(maxsize=256)
def _dielectric_tables(eta: float) -> tuple[np.ndarray, float]:
    """(s_bar (roughness, mu), s of F_ss_real) of the dielectric layer of relative IOR ``eta``: a reduction over
    the shared lobe samples (about 30 ms once they exist), kept on disk (``kept_tables``)."""
    s_bar, s_ss = kept_tables(f"dielectric-{eta!r}", __file__, lambda: _integrated_dielectric_tables(eta))
    return s_bar, float(s_ss)


def _integrated_dielectric_tables(eta: float) -> tuple[np.ndarray, np.ndarray]:
    g, vh = _lobe_samples()
    f0 = float(f0_from_ior(eta))
    s_bar = np.empty(g.shape[:2])
    for i in range(len(g)):  # a roughness at a time
        s = _interpolation(f0, dielectric_fresnel(vh[i].astype(np.float64), eta))
        s_bar[i] = np.einsum("ij,ij->i", g[i], s) / g.shape[2]
    return s_bar / np.maximum(_metal_tables()[0], 1e-300), np.float64(_interpolation(f0, dielectric_fss(eta)))


def _at_roughness(table: np.ndarray, roughness: float) -> np.ndarray:
    """A table's rows (roughness first) interpolated linearly at one roughness."""
    x = min(max(float(roughness), 0.0), 1.0) * (TABLE_ROUGHNESS - 1)
    i = min(int(np.floor(x)), TABLE_ROUGHNESS - 2)
    fx = x - i
    return table[i] * (1.0 - fx) + table[i + 1] * fx


def albedo_table(roughness: float) -> tuple[np.ndarray, np.ndarray, float]:
    """(E (TABLE_MU,), s (TABLE_MU,), E_avg) of the lobe with F = 1 at view cosines ``mu_grid()``, interpolated in
    roughness from the grid."""
    e, s, e_avg = _metal_tables()
    return _at_roughness(e, roughness), _at_roughness(s, roughness), float(_at_roughness(e_avg, roughness))


@inline
def _tables_at(e_tab, e_avg_tab, s_tab, r, m):
    """(E, s, E_avg) at roughness ``r`` and view cosine ``m``: E and s read bilinearly from their (roughness, mu)
    tables, E_avg linearly at r, E at least 1e-6. A NaN roughness or cosine reads the tables' first entries, not
    memory outside them."""
    r, m = r if r == r else 0.0, m if m == m else 0.0
    x = min(max(r, 0.0), 1.0) * (TABLE_ROUGHNESS - 1)
    i = min(int(np.floor(x)), TABLE_ROUGHNESS - 2)
    fx = x - i
    y = min(max(min(max(m, 0.0), 1.0) * TABLE_MU - 0.5, 0.0), TABLE_MU - 1)
    j = min(int(np.floor(y)), TABLE_MU - 2)
    fy = y - j
    e = (e_tab[i, j] * (1 - fx) + e_tab[i + 1, j] * fx) * (1 - fy) + \
        (e_tab[i, j + 1] * (1 - fx) + e_tab[i + 1, j + 1] * fx) * fy
    s = (s_tab[i, j] * (1 - fx) + s_tab[i + 1, j] * fx) * (1 - fy) + \
        (s_tab[i, j + 1] * (1 - fx) + s_tab[i + 1, j + 1] * fx) * fy
    return max(e, 1e-6), s, e_avg_tab[i] * (1.0 - fx) + e_avg_tab[i + 1] * fx


@inline
def _kulla_conty(e, s, e_avg, f_avg, f):
    """(1 + F_ms (1 - E) / E, (E + F_ms (1 - E)) (f + (1 - f) s)) of one channel, F_ms = F_avg E_avg / (1 - F_avg
    (1 - E_avg))."""
    f_ms = f_avg * e_avg / max(1.0 - f_avg * (1.0 - e_avg), 1e-6)
    return 1.0 + f_ms * (1.0 - e) / e, (e + f_ms * (1.0 - e)) * (f + (1.0 - f) * s)


@inline
def _layer_row(e_tab, e_avg_tab, s_tab, s_ss, r, m, f0t, scale, color):
    """``_kulla_conty`` of the dielectric layer at one point into ``scale`` and ``color`` (3,): f = F0 x tint
    ``f0t`` (3,) clamped to [0, 1], F_avg = mix(f, 1, ``s_ss``)."""
    e, s, e_avg = _tables_at(e_tab, e_avg_tab, s_tab, r, m)
    for c in range(3):
        f = min(max(f0t[c], 0.0), 1.0)
        scale[c], color[c] = _kulla_conty(e, s, e_avg, f + (1.0 - f) * s_ss, f)


@kernel
def _below_layer(e_tab, e_avg_tab, s_tab, s_ss, rows, roughness, normal, incident, f0t, below):
    """``below`` at the points ``rows`` times 1 - max(A), clamped to [0, 1], with A the layer's albedo (``_layer_row``)
    at mu = clamp(-normal . incident, 0, 1)."""
    scale, color = np.empty(3), np.empty(3)
    for i in range(len(rows)):
        k = rows[i]
        mu = -(normal[k, 0] * incident[k, 0] + normal[k, 1] * incident[k, 1] + normal[k, 2] * incident[k, 2])
        _layer_row(e_tab, e_avg_tab, s_tab, s_ss, roughness[k], min(max(mu, 0.0), 1.0), f0t[k], scale, color)
        keep = min(max(1.0 - max(color[0], color[1], color[2]), 0.0), 1.0)
        for c in range(3):
            below[k, c] *= keep


@inline
def _f82_mean(f0, b):
    """The cosine-weighted hemispherical mean of the F82-tint curve of one channel, F0 + (1 - F0) / 21 - b / 126,
    clamped to [0, 1]."""
    return min(max(f0 + (1.0 - f0) / 21.0 - b / 126.0, 0.0), 1.0)


@kernel
def _add_lobe(e_tab, e_avg_tab, s_tab, s_ss, rows, slots, metallic, roughness, normal, incident, f0, edge, layer,
              weight, color):
    """One lobe of the points rows[i], seen from -``incident`` at shading normal ``normal``, into slot slots[i]: the
    metallic lobe (``layer`` False: F82-tint with F0 ``f0`` and b ``edge``, weight Metallic) or the dielectric layer
    (``layer`` True: ``f0`` its F0 x tint, weight 1 - Metallic). ``weight`` takes the lobe's weight times its
    compensation, ``color`` adds the weight times its albedo (Cycles' Glossy Color)."""
    scale, albedo = np.empty(3), np.empty(3)
    for i in range(len(rows)):
        k = rows[i]
        w = 1.0 - metallic[k] if layer else metallic[k]
        if not w > 0.0:
            continue
        mu = -(normal[k, 0] * incident[k, 0] + normal[k, 1] * incident[k, 1] + normal[k, 2] * incident[k, 2])
        if layer:
            _layer_row(e_tab, e_avg_tab, s_tab, s_ss, roughness[k], mu, f0[k], scale, albedo)
        else:
            e, s, e_avg = _tables_at(e_tab, e_avg_tab, s_tab, roughness[k], mu)
            for c in range(3):
                scale[c], albedo[c] = _kulla_conty(e, s, e_avg, _f82_mean(f0[k, c], edge[k, c]), f0[k, c])
        for c in range(3):
            weight[slots[i], c] = w * scale[c]
            color[slots[i], c] += w * albedo[c]


def _lobe_terms(surface, rows: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(metallic lobe's weight, layer's weight, Glossy Color), each (R,3), of a ``Surface``'s points ``rows`` (all
    if None), read where they are (``_add_lobe``): the weights with their compensation; zero for a lobe the point
    lacks."""
    rows = np.arange(len(surface.eta)) if rows is None else rows
    metal, layer, color = (np.zeros((len(rows), 3)) for _ in range(3))
    e_tab, s_metal, e_avg_tab = _metal_tables()
    metallic, roughness, normal, incident, specular, edge, dielectric = (
        np.ascontiguousarray(getattr(surface, f), np.float64) for f in
        ("metallic", "roughness", "shading_normal", "incident", "specular", "edge", "dielectric"))
    rows = np.asarray(rows, np.int64)
    _add_lobe(e_tab, e_avg_tab, s_metal, 0.0, rows, np.arange(len(rows)), metallic, roughness, normal, incident,
              specular, edge, False, metal, color)
    for group, s_bar_tab, s_ss in _by_eta(surface.eta[rows]):
        _add_lobe(e_tab, e_avg_tab, s_bar_tab, s_ss, rows[group], group, metallic, roughness, normal, incident,
                  dielectric, edge, True, layer, color)
    return metal, layer, color


def glossy_color(surface, rows: np.ndarray) -> np.ndarray:
    """(R,3) Cycles' Glossy Color (``GlossyLobe.color``) of a ``Surface``'s points ``rows``, read where they are: what
    Russian roulette weighs before a lobe is worth building for a point (``paths.vertices.at_metal``)."""
    return _lobe_terms(surface, rows)[2]


def _by_eta(eta: np.ndarray):
    """(rows, s_bar table, s of F_ss_real) per relative IOR among the points whose ``eta`` is not 1 (a layer), the IORs
    rounded to ``ETA_DIGITS`` decimals (``_dielectric_tables``); one group in the usual case without sorting keys."""
    layered = np.nonzero(eta != 1.0)[0]
    if len(layered) == 0:
        return
    lo, hi = np.round([eta[layered].min(), eta[layered].max()], ETA_DIGITS)
    key = None if lo == hi else np.round(eta[layered], ETA_DIGITS)
    for value in [lo] if key is None else np.unique(key):
        yield (layered if key is None else layered[key == value], *_dielectric_tables(float(value)))


def scale_below_layer(below: np.ndarray, roughness, f0t, eta, normal, incident) -> None:
    """Scales the diffuse albedo ``below`` (K,3) in place by 1 - max(A) where the points have a layer (eta not 1),
    A its albedo (``layer_albedo``) seen along ``incident`` (K,3) at shading normals ``normal``: in one pass, the
    layer's rows not copied."""
    e_tab, _, e_avg_tab = _metal_tables()
    arrays = tuple(np.ascontiguousarray(a, np.float64) for a in (roughness, normal, incident, f0t))
    for rows, s_bar_tab, s_ss in _by_eta(np.asarray(eta, np.float64)):
        _below_layer(e_tab, e_avg_tab, s_bar_tab, s_ss, rows, *arrays, below)


def layer_albedo(roughness: np.ndarray, f0t: np.ndarray, eta: np.ndarray, mu: np.ndarray) -> np.ndarray:
    """(K,3) albedo A of the dielectric layer per unit closure weight, seen at view cosines ``mu``, for layers of
    F0 x tint ``f0t`` (K,3) and relative IOR ``eta`` (K,) (1: no layer, A = 0): (E + F_ms (1 - E)) mix(F0 tint, 1,
    s_bar). The diffuse lobe below keeps 1 - max(A) of its weight (Cycles' ``closure_layering_weight``)."""
    return _lobe_terms(_seen_at(mu, roughness, metallic=0.0, dielectric=f0t, eta=eta))[2]


def compensation(roughness: np.ndarray, f0: np.ndarray, b: np.ndarray,
                 mu: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(scale, Glossy Color), each (K,3), of the metallic lobe alone (F0 ``f0``, F82 b ``b``) at view cosines ``mu``:
    its multiple-scattering factor 1 + F_ms (1 - E) / E and its albedo (E + F_ms (1 - E)) mix(F0, 1, s)."""
    scale, _, color = _lobe_terms(_seen_at(mu, roughness, metallic=1.0, specular=f0, edge=b))
    return scale, color


def _seen_at(mu, roughness, metallic, specular=0.0, edge=0.0, dielectric=0.0, eta=1.0) -> SimpleNamespace:
    """The fields ``_lobe_terms`` reads for points (K,) seen at view cosines ``mu`` (normal +z, incident (0, 0,
    -mu), so that the cosine is ``mu`` exactly, NaN included), as writable float64 copies: the types the engine's
    surfaces have, so that ``_add_lobe`` is not compiled again for read-only views."""
    mu = np.asarray(mu, np.float64)
    k = len(mu)

    def rows(value, *shape):
        return np.array(np.broadcast_to(np.asarray(value, np.float64), (k, *shape)))
    return SimpleNamespace(
        metallic=rows(metallic), roughness=rows(roughness), shading_normal=rows([0.0, 0.0, 1.0], 3),
        incident=np.stack([np.zeros(k), np.zeros(k), -mu], axis=1), specular=rows(specular, 3),
        edge=rows(edge, 3), dielectric=rows(dielectric, 3), eta=rows(eta))


@dataclass
class GlossyLobe:
    """The glossy lobes at a set of points, seen from their viewers: the metallic lobe (weight Metallic x its
    compensation) plus the dielectric layer (weight (1 - Metallic) x its compensation), f cos with the weights
    folded in, and Cycles' ``Glossy Color`` of each point (Metallic x the metal's albedo + (1 - Metallic) x A).
    Both lobes have the same D, G2 and visible-normal sampling, so one sample serves their sum; only the Fresnel
    differs."""

    normal: np.ndarray  # (K,3) shading normals
    view: np.ndarray  # (K,3) toward the viewer
    alpha: np.ndarray  # (K,)
    f0: np.ndarray  # (K,3) metal
    edge: np.ndarray  # (K,3) metal
    weight: np.ndarray  # (K,3) metallic x compensation scale
    f0t: np.ndarray  # (K,3) dielectric layer: F0 x Specular Tint, clamped to [0, 1]
    eta: np.ndarray  # (K,) dielectric layer (1: none)
    layer: np.ndarray  # (K,3) (1 - metallic) x the layer's compensation scale
    color: np.ndarray  # (K,3) Cycles' Glossy Color

    @staticmethod
    def of(surface, rows: np.ndarray | None = None) -> "GlossyLobe":
        """The lobes of a ``Surface``'s points, or of its points ``rows`` (the fields the lobe reads, not a copy of
        the whole surface); weights and Glossy Color by ``_lobe_terms``."""
        weight, layer, color = _lobe_terms(surface, rows)
        fields = ("incident", "shading_normal", "roughness", "specular", "edge", "dielectric", "eta")
        incident, normal, roughness, specular, edge, dielectric, eta = \
            (getattr(surface, f) if rows is None else getattr(surface, f)[rows] for f in fields)
        return GlossyLobe(normal, -incident, alpha(roughness), specular, edge, weight, np.clip(dielectric, 0.0, 1.0),
                          eta, layer, color)

    @cached_property
    def present(self) -> np.ndarray:
        """(K,) bool: whether the point has either lobe (computed once: direct light asks per batch)."""
        return (largest(self.weight) > 0.0) | (largest(self.layer) > 0.0)

    def take(self, rows) -> "GlossyLobe":
        return take_fields(self, rows)

    @staticmethod
    def concat(parts: list["GlossyLobe"]) -> "GlossyLobe":
        return concat_fields(GlossyLobe, parts)

    def evaluate(self, wl: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(f cos (R,3) with the weights, pdf (R,) of ``sample``) toward directions ``wl`` (R,3) at points ``rows``."""
        rows = np.arange(len(self.eta))[rows]
        value, pdf = np.empty((len(rows), 3)), np.empty(len(rows))
        _lobe_evaluate(*self._arrays(), rows, np.ascontiguousarray(wl, np.float64), value, pdf)
        return value, pdf

    def sample(self, u1: np.ndarray, u2: np.ndarray, rows: np.ndarray):
        """(l (R,3), f cos / pdf (R,3) with the weights, pdf (R,)) at points ``rows``."""
        rows = np.arange(len(self.eta))[rows]
        wl, weight, pdf = np.empty((len(rows), 3)), np.empty((len(rows), 3)), np.empty(len(rows))
        _lobe_sample(*self._arrays(), rows, np.asarray(u1, np.float64), np.asarray(u2, np.float64), wl, weight, pdf)
        return wl, weight, pdf

    def _arrays(self):
        return tuple(np.ascontiguousarray(getattr(self, name), np.float64) for name in
                     ("normal", "view", "alpha", "f0", "edge", "weight", "f0t", "eta", "layer"))


@kernel
def _lobe_fresnel(f0, edge, weight, f0t, eta, layer, vh, scale, out):
    """out = ``scale`` x both lobes' Fresnel at v.h ``vh``, with their weights (one point's rows)."""
    share = _layer_share(eta, vh) if eta != 1.0 else 0.0
    for c in range(3):
        f = _f82(f0[c], edge[c], vh) * weight[c]
        if eta != 1.0:
            f += (f0t[c] + (1.0 - f0t[c]) * share) * layer[c]
        out[c] = f * scale


@kernel
def _lobe_evaluate(normal, view, alpha, f0, edge, weight, f0t, eta, layer, rows, wl, value, pdf):
    for i in range(len(rows)):
        r = rows[i]
        f, pdf[i], vh = _ggx(normal[r], view[r], wl[i], alpha[r])
        _lobe_fresnel(f0[r], edge[r], weight[r], f0t[r], eta[r], layer[r], vh, f, value[i])


@kernel
def _lobe_sample(normal, view, alpha, f0, edge, weight, f0t, eta, layer, rows, u1, u2, wl, out, pdf):
    h = np.empty(3)
    for i in range(len(rows)):
        r = rows[i]
        g = _visible_normal(normal[r], view[r], alpha[r], u1[i], u2[i], wl[i], h)
        _, p, _ = _ggx(normal[r], view[r], wl[i], alpha[r])
        pdf[i] = p if g > 0.0 else 0.0
        vh = view[r, 0] * h[0] + view[r, 1] * h[1] + view[r, 2] * h[2]
        _lobe_fresnel(f0[r], edge[r], weight[r], f0t[r], eta[r], layer[r], vh, g, out[i])
