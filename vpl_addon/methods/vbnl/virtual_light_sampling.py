"""Rendering with virtual blue noise lighting (Li et al., HPG 2022, sec. 4): photon lights sampled, not summed.

At a shading point x, one *BSDF sample* and one *power-based light sample* estimate the light from the photon
lights, combined by multiple importance sampling with the power heuristic (eq. 5):

- power-based (eq. 4): light j with probability P_j / sum P, then a direction uniform in the cone that holds its
  sphere, p_j(w) = P_j / sum P / (2 pi (1 - cos theta_j)); the ray's hit y adds s_j(y) L_j, zero outside the
  sphere (``photon_lights``: s_j is the light's share of y, L_j its radiance);
- BSDF: a direction w_r from the point's lobe (cosine-weighted for the diffuse one) traced to y_r; every light
  whose sphere holds y_r adds s_i(y_r) L_i.

*Adaptive camera path extension* (eq. 6-9): with the sample footprint a = |x - y|^2 / (p_BSDF(w) |cos theta_y|) and
light density rho_i (eq. 8), each light's weight is w_v = clamp((a rho_i - n_min) / (n_max - n_min), 0, 1); what the
lights do not cover, (1 - w_v), is found by extending the camera path from y: direct light at y by next-event
estimation, and y's own indirect light by the same estimator one level deeper. Points no light covers extend
fully (w_v = 0). The last allowed bounce uses the lights alone.

Per light the integrand w_v,i(w) s_i L_i f cos is one function of w for both strategies, so the MIS weights are
exact; the extension term is estimated from the BSDF sample with w_v averaged over the covering lights by their
radiance. The result is the light reflected by a white Lambertian surface (Cycles' ``Diffuse Indirect``) or, given
a ``microfacet.GlossyLobe``, by the metallic lobe with its colour (``Glossy Indirect`` times ``Glossy Color``): the
BSDF sample then follows visible normals and f cos is the GGX lobe's.

Glossy surfaces along the path: the photon lights hold diffusely reflected light only (no light sits on pure
metal, and none stores a directional emission profile), so a hit y with a metallic lobe always extends the camera
path through that lobe (next-event estimation with the lobe, and a sample pair one level deeper); the photons that
lit the walls via metal were traced through it (``paths.light_paths``). With no diffuse surface in the scene at all
there are no lights, and nothing indirect is rendered.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...core.sampling import dot, group_sum, power_heuristic, sample_cdf, uniform_cone
from ...lights.direct import direct_light
from ...materials.microfacet import GlossyLobe
from ...materials.surface import bounce
from ...paths.vertices import PathVertices, at_metal, merged


@dataclass
class SamplingSettings:
    samples: int = 16  # sample pairs (BSDF + light) per pixel: the budget knob
    extension: bool = True  # adaptive camera path extension (eq. 6-9)
    n_min: float = 40.0
    n_max: float = 80.0


def _one_minus_cos_cone(radius, dist):
    """1 - cos(theta) of the cone holding a sphere of ``radius`` at ``dist``, stable for tiny spheres; 2 (the whole
    sphere of directions) from inside."""
    s2 = np.minimum((radius / np.maximum(dist, 1e-300)) ** 2, 1.0)
    return np.where(dist <= radius, 2.0, s2 / (1.0 + np.sqrt(1.0 - s2)))


def _blend_weight(footprint, density, settings, extend):
    """w_v of eq. 9 (1 where the path may not extend)."""
    if not extend:
        return np.ones_like(footprint)
    span = max(settings.n_max - settings.n_min, 1e-9)
    return np.clip((footprint * density - settings.n_min) / span, 0.0, 1.0)


def _diffuse_part(surface) -> np.ndarray:
    """(K,) 1 where the surface has a diffuse colour: the photon lights hold only diffusely reflected light."""
    return (surface.albedo.max(axis=1) > 0.0).astype(np.float64)


def gather(surface, lights, scene, tracer, light_set, rng: np.random.Generator, settings: SamplingSettings,
           max_depth: int, glossy: GlossyLobe | None = None) -> np.ndarray:
    """(K,3) indirect light at the points of ``surface`` from the ``PhotonLights``, one sample pair per point:
    reflected by a white Lambertian surface, or by the metallic lobe ``glossy`` (with its colour) if given."""
    out = np.zeros((len(surface), 3))
    if len(surface) == 0 or len(lights) == 0 or max_depth <= 0:
        return out
    density = lights.density
    level = [PathVertices(surface, np.arange(len(surface)), np.ones((len(surface), 3)), glossy)]
    for depth in range(max_depth):
        level = [v for v in level if len(v.owner)]
        if not level:
            break
        # a path with depth extra vertices may take light of at most max_depth - depth bounces from the lights
        radiance = lights.radiance_upto(max_depth - depth)
        power = np.maximum(lights.intensity_upto(max_depth - depth).sum(axis=1), 0.0)
        total_power = power.sum()
        choice = power / total_power if total_power > 0 else np.zeros_like(power)
        cdf = np.cumsum(choice)
        extend = settings.extension and depth + 1 < max_depth
        following = []
        for v in level:
            following += _estimate(v, out, lights, scene, tracer, light_set, rng, settings, radiance, choice, cdf,
                                   density, total_power, extend)
        level = merged(following)
    return out


def _estimate(v, out, lights, scene, tracer, light_set, rng, settings, radiance, choice, cdf, density, total_power,
              extend):
    """Adds the light sample and the BSDF sample of the vertices ``v`` to ``out``; returns the vertices the
    camera path continues to (eq. 6-9 for the diffuse part at each hit, always for a metallic lobe there)."""
    point, owner, throughput = v.point, v.owner, v.throughput
    p, ng = point.position, point.geometric_normal

    # light sample (eq. 4), weighted against the BSDF pdf of the same direction
    if total_power > 0:
        j = sample_cdf(cdf, rng.random(len(p)))
        to = lights.position[j] - p
        dist = np.linalg.norm(to, axis=1)
        axis = to / np.maximum(dist, 1e-300)[:, None]
        cone = _one_minus_cos_cone(lights.radius[j], dist)
        w = uniform_cone(rng.random(len(p)), rng.random(len(p)), axis, 1.0 - cone)
        p_light = choice[j] / (2.0 * np.pi * cone)
        ok = np.nonzero((dot(point.shading_normal, w) > 0.0) & (dot(ng, w) > 0.0))[0]
        y, at = bounce(scene, tracer, point.take(ok), w[ok])
        at = ok[at]
        jj = j[at]
        f_cos, p_bsdf = v.evaluate(w[at], at)
        mine = lights.share_of(y.position, y.shading_normal, jj) * _diffuse_part(y)  # s_j(y)
        to_y = y.position - p[at]
        footprint = dot(to_y, to_y) / np.maximum(p_bsdf * np.abs(dot(y.shading_normal, w[at])), 1e-300)
        weight = mine * power_heuristic(p_light[at], p_bsdf) * _blend_weight(footprint, density[jj], settings,
                                                                              extend) / p_light[at]
        out += group_sum(owner[at], throughput[at] * f_cos * radiance[jj] * weight[:, None], len(out))

    # BSDF sample: every light whose sphere holds the hit point
    w, sampled, p_bsdf = v.sample(rng)
    go = np.nonzero(p_bsdf > 0.0)[0]
    y, at = bounce(scene, tracer, point.take(go), w[go])
    at = go[at]
    pair, light, mine = lights.shares(y.position, y.shading_normal)
    mine = mine * _diffuse_part(y)[pair]
    to_y = y.position - p[at]
    footprint = dot(to_y, to_y) / np.maximum(p_bsdf[at] * np.abs(dot(y.shading_normal, w[at])), 1e-300)
    cone = _one_minus_cos_cone(lights.radius[light], np.linalg.norm(lights.position[light] - p[at][pair], axis=1))
    p_light = choice[light] / (2.0 * np.pi * cone)
    w_v = _blend_weight(footprint[pair], density[light], settings, extend)
    light_radiance = radiance[light] * mine[:, None]
    estimate = group_sum(pair, light_radiance * (power_heuristic(p_bsdf[at][pair], p_light) * w_v)[:, None],
                         len(at))
    carried = throughput[at] * sampled[at]
    out += group_sum(owner[at], carried * estimate, len(out))
    if not extend:
        return []

    # camera path extension: what the lights leave of the diffuse part, (1 - mean w_v), comes from the path
    # continued at y; a metallic lobe at y is not in the lights at all and always continues
    brightness = light_radiance.sum(axis=1)
    covered = group_sum(pair, brightness[:, None], len(at))[:, 0]
    mean_share = np.where(covered > 0.0, group_sum(pair, (w_v * brightness)[:, None], len(at))[:, 0] /
                          np.maximum(covered, 1e-300), 0.0)
    carry = carried * (1.0 - mean_share)[:, None] * y.albedo
    go = np.nonzero(carry.max(axis=1) > 0.0)[0]
    following = [PathVertices(y.take(go), owner[at][go], carry[go])]
    out += group_sum(following[0].owner, following[0].throughput *
                     direct_light(following[0].point, light_set, tracer, 1, rng)[0], len(out))
    shiny = np.nonzero(y.glossy)[0]
    if len(shiny):
        following.append(at_metal(y, shiny, owner[at], carried, light_set, tracer, rng, out))
    return following
