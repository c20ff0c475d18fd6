"""Rendering with virtual blue noise lighting (Li et al., HPG 2022, sec. 4): photon lights sampled, not summed.

At a shading point x, one *BSDF sample* and one *power-based light sample* estimate the light from the photon
lights, combined by multiple importance sampling with the power heuristic (eq. 5):

- power-based (eq. 4): light j with probability P_j / sum P (drawn down a tree of the lights with a number per
  level, ``_descend``, so that a sequence's next frame draws the same lights), then a direction toward a point of
  its disc (the light's support: ``photon_lights``), drawn with the profile of its share; the ray's hit y adds
  s_j(y) L_j, zero outside the support (s_j is the light's share of y, L_j its radiance). Deviation: Li et al. draw
  the direction uniform in the cone that holds the light's sphere, p_j(w) = P_j / sum P / (2 pi (1 - cos theta_j));
  most of that cone looks past the thin disc (36 % of the lit light samples meet it in cornell_area, 66 % toward the
  disc), and the disc's samples cut the gather's noise by 11 % there at the same time;
- BSDF: a direction w_r from the point's lobe (cosine-weighted for the diffuse one) traced to y_r; every light
  whose sphere holds y_r adds s_i(y_r) L_i.

*Adaptive camera path extension* (eq. 6-9): with the sample footprint a = |x - y|^2 / (p_BSDF(w) |cos theta_y|) and
light density rho_i (eq. 8), each light's weight is w_v = clamp((a rho_i - n_min) / (n_max - n_min), 0, 1); what the
lights do not cover, (1 - w_v), is found by extending the camera path from y: direct light at y by next-event
estimation, and y's own indirect light by the same estimator one level deeper. Points no light covers extend
fully (w_v = 0). The last allowed bounce uses the lights alone.

Per light the integrand w_v,i(w) s_i L_i f cos is one function of w for both strategies, so the MIS weights are
exact; the extension term is estimated from the BSDF sample with w_v averaged over the covering lights by their
shares (``_add_samples``). The result is the light reflected by a white Lambertian surface (Cycles' ``Diffuse
Indirect``) or, given a ``microfacet.GlossyLobe``, by the metallic lobe with its colour (``Glossy Indirect`` times
``Glossy Color``): the BSDF sample then follows visible normals and f cos is the GGX lobe's.

Glossy surfaces along the path: the photon lights hold diffusely reflected light only (no light sits on pure
metal, and none stores a directional emission profile), so a hit y with a metallic lobe always extends the camera
path through that lobe (next-event estimation with the lobe, and a sample pair one level deeper); the photons that
lit the walls via metal were traced through it (``paths.light_paths``). The light a camera point receives over one
sharp lobe straight from a light (a caustic) comes from the photons that took that way instead (``_caustic_light``,
as a photon map's caustics: Jensen 1996), where paths would have to line up the point, the lobe and a small light
by chance. With no diffuse surface in the scene at all there are no lights, and nothing indirect is rendered. Every
extended vertex goes on by Russian roulette on its throughput (``paths.vertices.roulette``), which stops most paths
through a faint clear coat early.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import partial

import numpy as np

from ...core.color import largest
from ...core.compiled import inline, kernel
from ...core.sampling import PathNumbers, basis, dot, group_sum
from ...lights.direct import direct_light
from ...materials.microfacet import GlossyLobe
from ...materials.surface import bounce_tinted
from ...paths.light_paths import SHARP
from ...paths.vertices import PathVertices, at_metal, merged, roulette
from ..base import option


TREE_SLACK = 4  # numbers for the light tree's levels past log2 N (lights on a surface make it deeper than that)


@dataclass
class SamplingSettings:
    # sample pairs (BSDF + light) per pixel; 0: one per camera sample (``gather_samples``), so the render's one
    # Samples setting raises the gather with the direct light and the anti-aliasing, which ``bench/sample_counts.py``
    # (``--pairs``) measures better at equal time than more pairs per camera sample
    samples: int = option(0, prop="vbnl_samples", label="Gather Samples", min=0, soft_max=1024,
                          description="Samples per pixel of the VBNL gather (a light sample and a BSDF sample each); "
                                      "0 = one per camera sample, so Samples alone sets the render's quality")
    # adaptive camera path extension (eq. 6-9)
    extension: bool = option(True, prop="path_extension", label="Path Extension",
                             description="Extend camera paths where the virtual lights are too sparse for the "
                                         "footprint (eq. 6-9)")
    n_min: float = 40.0
    n_max: float = 80.0
    # the light that comes to a camera point over one sharp glossy lobe from the photons' density
    # (``_caustic_light``); off, from paths alone, as a path tracer finds it (for comparisons)
    caustic_photons: bool = True


def gather(surface, lights, scene, tracer, light_set, rng: np.random.Generator, settings: SamplingSettings,
           max_depth: int, glossy: GlossyLobe | None = None,
           pixel: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(K,3) indirect light at the points of ``surface`` from the ``PhotonLights``, one sample pair per point:
    reflected by a white Lambertian surface, or by the metallic lobe ``glossy`` (with its colour) if given. In
    two parts, as the method contract asks: the light of paths that meet no metallic lobe past the point, and the
    light that comes over metal (a caustic's rare bright samples among it), which no filter may spread. A vertex's
    ``branch`` tells them apart: it is 0 until its path takes a metallic lobe (``PathVertices.branch``).

    ``pixel`` (K,), the pixel of each point: the pairs of a pixel (and the vertices their paths extend to) draw
    their numbers from nets it shares (``sampling.PathNumbers``) instead of independent ones, so that a pixel's
    BSDF directions and light points cover their squares evenly: cornell_area's indirect light as rendered at 64
    pairs, rMAE 0.035 against 0.063 with independent numbers, denoised 0.0147 against 0.0157
    (``bench/sample_counts.py cornell_area --samples 16 --light-samples 2 --pairs 64``). The numbers are keyed by
    the path and its depth, so a path that stops or goes on leaves every other path's numbers as they were: a
    slightly changed set of lights (the next frame of a sequence) changes the noise only where the light changed."""
    k = len(surface)
    out = np.zeros((2 * k, 3))  # rows [0, k): light that came over no metal; [k, 2k): light over metal
    if k == 0 or len(lights) == 0 or max_depth <= 0:
        return out[:k], out[k:]
    density = lights.density
    order, nodes = lights.tree(scene.bounds)
    seen = None  # the points whose caustics the photons hold: none without a sharp lobe's photon
    if settings.caustic_photons and glossy is None and max_depth > 1 and lights.caustic is not None and \
            lights.caustic.any():
        seen = _caustic_light(out, surface, lights)
    scale = _lobe_scale(glossy, k)
    level = [PathVertices(surface, np.arange(len(surface)), np.repeat(1.0 / scale[:, None], 3, axis=1), glossy)]
    paths = None if pixel is None else PathNumbers(pixel, rng)
    for depth in range(max_depth):
        numbers = partial(_numbers, paths, rng, depth)
        draws = rng if paths is None else paths.generator(depth)
        level = [v for v in level if len(v.owner)]
        if not level:
            break
        # a path with depth extra vertices may take light of at most max_depth - depth bounces from the lights
        radiance = lights.radiance_upto(max_depth - depth)
        power = np.maximum(lights.intensity_upto(max_depth - depth).sum(axis=1), 0.0)
        total_power = power.sum()
        choice = power / total_power if total_power > 0 else np.zeros_like(power)
        tree = (order, *splits(np.r_[0.0, np.cumsum(choice[order])], *nodes))
        extend = settings.extension and depth + 1 < max_depth
        following = []
        for v in level:
            following += _estimate(v, out, lights, scene, tracer, light_set, numbers, draws, settings, radiance,
                                   choice, tree, density, total_power, extend, seen if depth == 0 else None)
        level = merged(following)
    out *= np.concatenate([scale, scale])[:, None]
    return out[:k], out[k:]


def _lobe_scale(glossy: GlossyLobe | None, k: int) -> np.ndarray:
    """(K,) what the paths' throughput starts divided by and the light ends multiplied by: the largest channel of
    the metallic lobe's colour (1 for the white Lambertian, or where the lobe has no colour). Russian roulette
    (``paths.vertices.roulette``) then weighs a path by what it carries against its first lobe, as Cycles' does
    after choosing a closure by its weight. Against the throughput itself, a ground's 4 % specular layer stopped
    most paths through it and multiplied the rest by about 5: the sun over the helmet's sharp metal made one
    pixel of 1,041 in Combined, now 203."""
    if glossy is None:
        return np.ones(k)
    color = largest(glossy.color)
    return np.where(color > 0.0, color, 1.0)


def _numbers(paths: PathNumbers | None, rng, depth: int, count: int, owner: np.ndarray, branch: np.ndarray,
             stream: int, nets: bool = True):
    """(count, R) uniform numbers for the vertices ``branch`` of the paths ``owner`` at ``depth``: keyed ones (from
    the pixel's nets, or independent), or the generator's without pixels."""
    if paths is None:
        return rng.random((count, len(owner)))
    return (paths.numbers if nets else paths.independent)(count, owner, branch, depth, stream)


def _caustic_light(out, surface, lights) -> np.ndarray:
    """Adds to ``out``'s first half the light of the caustic photons at the points of ``surface`` (white Lambertian
    receivers): sum_j s_j(x) L_j of the lights' ``caustic_radiance``, a density estimate of the light that came
    over one sharp glossy lobe (Jensen 1996, sec. 3.1; ``paths.light_paths.SHARP``), smooth where paths would have
    to find a small bright light through that lobe: a sun in a sky seen in a helmet's metal throws rare samples of
    10^5 times the mean onto the ground, which a pass of 16 samples mostly misses or shows as fireflies
    (``bench/caustics.py``). Returns (K,) the points the lights cover, whose paths leave that light to the photons:
    no direct light at a sharp glossy hit of their first step (``_extended``)."""
    pair, light, share = lights.shares(surface.position, surface.shading_normal)
    out[:len(surface)] += group_sum(pair, share[:, None] * lights.caustic_radiance[light], len(surface))
    return np.bincount(pair, weights=share, minlength=len(surface)) > 0.0


def _estimate(v, out, lights, scene, tracer, light_set, numbers, rng, settings, radiance, choice, tree, density,
              total_power, extend, caustic=None):
    """Adds the light sample and the BSDF sample of the vertices ``v`` to ``out`` (each vertex's owner's row in
    the half of ``out`` its branch says); returns the vertices the camera path continues to (eq. 6-9 for the
    diffuse part at each hit, always for a metallic lobe there).
    ``numbers(count, owner, branch, stream)`` gives the uniform numbers of the vertices ``branch`` of the paths
    ``owner`` at this depth, ``rng`` the rest (a metallic hit's). ``caustic`` (K,): the vertices whose sharp
    glossy hits add no direct light, the photons' (``_caustic_light``).

    The rays of both samples are traced, shaded and looked up among the lights' spheres as one batch."""
    point, owner, branch, throughput = v.point, v.owner, v.branches, v.throughput
    # the BSDF's direction and the light's point each from one 2D net, then the light's choice
    u = numbers(4, owner, branch, 0)
    w, sampled, p_bsdf = v.sample(u[:2])
    levels = numbers(max(len(lights) - 1, 1).bit_length() + TREE_SLACK, owner, branch, 3, nets=False)
    lit, toward, drawn, p_light = _light_directions(point, lights, u[2:], levels, choice, tree, total_power)
    rows = np.concatenate([lit, np.nonzero(p_bsdf > 0.0)[0]])
    y, at, tint = bounce_tinted(scene, tracer, point, np.concatenate([toward[lit], w[rows[len(lit):]]]), rows)
    source = rows[at]  # the vertex each hit came from
    light_hit = np.nonzero(at < len(lit))[0]
    weight = throughput[source] * sampled[source]  # f cos / pdf for the BSDF samples
    pdf = p_bsdf[source]
    if len(light_hit):  # the light samples' f cos and the pdf of the BSDF sampling the same direction (MIS)
        f_cos, pdf[light_hit] = v.evaluate(toward[source[light_hit]], source[light_hit])
        weight[light_hit] = throughput[source[light_hit]] * f_cos
    if tint is not None:  # what coloured glass between the vertex and its hit leaves of the light
        weight *= tint
    hit_light = np.full(len(at), -1)
    hit_light[light_hit] = drawn[source[light_hit]]
    pair, light, share = _covering(lights, y)
    mean_share = _add_samples(out, _row(owner, branch, len(out) // 2), source, weight, hit_light, p_light, pdf,
                              toward, w, y.position, y.shading_normal, point.position, pair, light, share,
                              lights.position, lights.normal, lights.radius, choice, radiance, density,
                              float(settings.n_min), max(settings.n_max - settings.n_min, 1e-9), extend,
                              *lights.linear)
    if not extend:
        return []
    bsdf_hit = np.nonzero(hit_light < 0)[0]
    return _extended(y, bsdf_hit, owner[source], branch[source], weight, mean_share, light_set, tracer, numbers, rng,
                     out, None if caustic is None else caustic[source])


def _row(owner: np.ndarray, branch: np.ndarray, k: int) -> np.ndarray:
    """The rows of ``gather``'s (2K,3) output that vertices of ``owner`` and ``branch`` add to: a path that took a
    metallic lobe (branch > 0) adds to the second half."""
    return owner + k * (branch > 0)


def _light_directions(point, lights, u, levels, choice, tree, total_power):
    """Power-based light sampling (eq. 4): per point a light j with probability P_j / sum P (``_descend``, with
    the numbers ``levels``), then a point on its disc by its share's profile (``_toward_discs``), with the uniform
    numbers ``u`` (2, K). Returns (the points whose direction leaves their surface, the directions, j, the pdfs
    p_j(w))."""
    k = len(point)
    if total_power <= 0:
        return np.zeros(0, np.int64), np.zeros((k, 3)), np.zeros(k, np.int64), np.zeros(k)
    order, split, left, right = tree
    j = order[_descend(split, left, right, levels)]
    w, p_light = _toward_discs(point.position, j, lights.position, lights.normal, lights.radius, choice, u[0], u[1])
    lit = np.nonzero((dot(point.shading_normal, w) > 0.0) & (dot(point.geometric_normal, w) > 0.0) &
                     (p_light > 0.0))[0]
    return lit, w, j, p_light


def _covering(lights, y):
    """``PhotonLights.shares`` at the hits ``y`` that have a diffuse colour: the lights hold no light of a pure
    metal (s_j(y) = 0 there)."""
    diffuse = np.nonzero(largest(y.albedo) > 0.0)[0]
    if len(diffuse) == len(y):
        return lights.shares(y.position, y.shading_normal)
    pair, light, share = lights.shares(y.position[diffuse], y.shading_normal[diffuse])
    return diffuse[pair], light, share


def _extended(y, rows, owner, branch, carried, mean_share, light_set, tracer, numbers, rng, out, caustic=None):
    """Camera path extension (eq. 6-9) at the BSDF samples' hits ``rows`` of ``y`` (``owner``, ``branch``,
    ``carried``, ``mean_share`` and ``caustic``, whether a sharp glossy hit's direct light is the photons', given
    per hit): what the lights leave of the diffuse part, (1 - mean w_v), comes from the path continued at y, its
    direct light added to ``out`` now (next-event estimation); a metallic lobe at y is not in the lights at all and
    always continues. Either goes on by Russian roulette on its throughput (``paths.vertices.roulette``). Returns
    the vertices of the next level."""
    carry = carried[rows] * (1.0 - mean_share[rows])[:, None] * y.albedo[rows]
    go, boost = roulette(carry, rng, numbers(1, owner[rows], branch[rows], 1)[0])
    following = [PathVertices(y.take(rows[go]), owner[rows[go]], carry[go] * boost[:, None], None,
                              2 * branch[rows[go]])]
    at, k = following[0].owner, len(out) // 2
    given = tuple(numbers(5, at, branch[rows[go]], 2)[:, :, None])
    out += group_sum(_row(at, branch[rows[go]], k), following[0].throughput *
                     direct_light(following[0].point, light_set, tracer, 1, rng, numbers=given)[0], len(out))
    shiny = rows[y.glossy[rows]]
    if len(shiny):  # light over metal from here on
        following.append(at_metal(y, shiny, owner, carried, light_set, tracer, rng, out[k:], branch,
                                  None if caustic is None else caustic[shiny] & (y.roughness[shiny] < SHARP)))
    return following


def splits(cdf, lo, hi, mid, left, right):
    """The light tree (``PhotonLights.tree``'s nodes lo, hi, mid, left, right) as ``_descend`` walks it: per internal
    node the share of its power in its left half (0.5 where it has none), and its children; ``cdf`` (N + 1,) is the
    normalised cumulative power in tree order from 0."""
    total = cdf[hi] - cdf[lo]
    return np.where(total > 0.0, (cdf[mid] - cdf[lo]) / np.where(total > 0.0, total, 1.0), 0.5), left, right


@kernel
def _descend(split, left, right, u):
    """(K,) positions in the lights' tree order drawn with probability P_j / sum P: each descends the lights' tree
    from the root to the left or right in proportion to the two halves' power (``splits``: the left half's share
    ``split`` of each internal node, read once per level instead of three cumulative powers and a division: half
    the time). Every level takes a number of its own from ``u`` (levels, K); below the last, the last is rescaled
    to the part of [0, 1) it fell in.

    The probabilities are those of inverting the cumulative power with one number, but the draws are steady: when
    the powers change a little (the next frame of a sequence), a draw changes only where a level's number falls
    between a node's old and new split, while an inverted cumulative power moves every boundary past the first
    change, and most draws go to a light further along (elsewhere in space). A light added or removed (lights
    placed again around a moving object) changes the nodes above it, not the rest of the tree, since the tree is
    split by the codes, not by counts. In the moving light's example a 1 cm move of the lamp changes Diffuse
    Indirect by 1.0 % with the inverted cumulative power, 0.55 % with the tree, 0.52 % with the choice held at the
    unmoved lamp's powers."""
    levels = u.shape[0]
    out = np.zeros(u.shape[1], np.int64)
    if len(left) == 0:  # one light
        return out
    for i in range(u.shape[1]):
        node, level = 0, 0
        x = u[0, i]
        while node >= 0:
            share = split[node]
            if level < levels:
                x = u[level, i]
            last = level + 1 >= levels  # the next level rescales this number
            if x < share:
                node = left[node]
                x = x / share if last else x
            else:
                node = right[node]
                x = (x - share) / (1.0 - share) if last else x
            x = min(x, 1.0 - 1e-16)
            level += 1
        out[i] = -1 - node
    return out


@inline
def _disc_density(x0, x1, x2, d0, d1, d2, centre, normal, radius):
    """The solid-angle pdf with which ``_toward_discs`` draws the unit direction d from x, given its light (centre,
    normal, radius): where the ray meets the light's plane at q inside its disc, (1 - |q - c|^2 / r^2) /
    (pi r^2 / 2) x t^2 / |cos|; 0 where it misses the disc."""
    across = d0 * normal[0] + d1 * normal[1] + d2 * normal[2]
    if abs(across) < 1e-12:
        return 0.0
    t = ((centre[0] - x0) * normal[0] + (centre[1] - x1) * normal[1] + (centre[2] - x2) * normal[2]) / across
    q0, q1, q2 = x0 + t * d0 - centre[0], x1 + t * d1 - centre[1], x2 + t * d2 - centre[2]
    r2 = radius * radius
    inside = 1.0 - (q0 * q0 + q1 * q1 + q2 * q2) / r2
    if t <= 0.0 or inside <= 0.0:
        return 0.0
    return inside / (0.5 * np.pi * r2) * t * t / abs(across)


@kernel
def _toward_discs(position, drawn, centre, normal, radius, choice, u1, u2):
    """Per point, a direction toward its light ``drawn``: a point q on the light's disc (its support: the surface
    within its sphere, within ``SLAB`` radii of its tangent plane) with density (1 - rho^2 / r^2) / (pi r^2 / 2),
    the profile of its share, and the pdf of the direction, P_j / sum P x ``_disc_density`` (0 seen edge-on).
    Li et al. draw a direction uniform in the cone that holds the light's sphere (eq. 4), of which about a third
    meets the surface inside it in the Cornell box: the rest look past the disc's plane."""
    k = len(drawn)
    w, pdf = np.zeros((k, 3)), np.zeros(k)
    for i in range(k):
        j = drawn[i]
        n0, n1, n2 = normal[j, 0], normal[j, 1], normal[j, 2]
        t0, t1, t2, b0, b1, b2 = basis(n0, n1, n2)
        rho = radius[j] * np.sqrt(max(1.0 - np.sqrt(max(1.0 - u1[i], 0.0)), 0.0))
        c, s = rho * np.cos(2.0 * np.pi * u2[i]), rho * np.sin(2.0 * np.pi * u2[i])
        d0 = centre[j, 0] + c * t0 + s * b0 - position[i, 0]
        d1 = centre[j, 1] + c * t1 + s * b1 - position[i, 1]
        d2 = centre[j, 2] + c * t2 + s * b2 - position[i, 2]
        dist = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        if dist <= 0.0:
            continue
        d0, d1, d2 = d0 / dist, d1 / dist, d2 / dist
        w[i, 0], w[i, 1], w[i, 2] = d0, d1, d2
        pdf[i] = choice[j] * _disc_density(position[i, 0], position[i, 1], position[i, 2], d0, d1, d2, centre[j],
                                           normal[j], radius[j])
    return w, pdf


@kernel
def _power_heuristic(a, b):
    """``core.sampling.power_heuristic`` of one pair of pdfs."""
    if np.isnan(a):
        return 1.0
    a2, b2 = a * a, b * b
    return a2 / (a2 + b2 if a2 + b2 > 0.0 else 1.0)


@kernel
def _blend_weight(footprint, density, n_min, span, extend):
    """w_v of eq. 9 (1 where the path may not extend)."""
    if not extend:
        return 1.0
    return min(max((footprint * density - n_min) / span, 0.0), 1.0)


@kernel
def _add_samples(out, owner, source, weight, drawn, p_light, pdf, toward, w, y, normal, position, pair, light, share,
                 centre, facing, radius, choice, radiance, density, n_min, span, extend, slope, middle):
    """out[owner] += each hit's estimate; returns (H,) the mean w_v of the lights covering each BSDF sample's hit,
    by their shares (0 where none covers it or for a light sample), whatever light they hold: the lights' part is
    sum_i w_v,i s_i L_i and the extension's (1 - sum_i w_v,i s_i) L, which add up to L where the L_i are right on
    average. Weighed by the lights' radiance instead, a hit whose lights hold no photon (their light of this many
    bounces scattered over few of them) would be extended in full, and the light those lights hold on average
    counted twice: Diffuse Indirect 1.22x Cycles' in a room lit through a door left ajar.

    Hit h came from the vertex x = position[source[h]] (owner, p_light, toward and w are per vertex). A hit of a
    light sample (``drawn`` its light j >= 0, p_light its pdf, ``toward`` its direction, ``weight`` the path's
    throughput times f cos) adds s_j(y) L_j w_v f cos power_heuristic(p_light, pdf) / p_light; a hit of a BSDF
    sample (drawn -1, ``w`` its direction, ``weight`` the throughput times f cos / pdf) adds
    weight sum_i s_i(y) L_i w_v,i power_heuristic(pdf, p_i), p_i the pdf of light sampling toward light i from x.
    The footprint a = |x - y|^2 / (pdf |cos theta_y|) (eq. 7) sets w_v (eq. 9). ``pair``, ``light``, ``share``:
    the lights covering each hit, s_i(y) (none at a hit without a diffuse colour). A light's radiance at y is
    L_i (1 + slope_i . (y - middle_i)) (``PhotonLights.linear``)."""
    hits = len(drawn)
    footprint = np.empty(hits)
    for h in range(hits):
        s = source[h]
        d = toward[s] if drawn[h] >= 0 else w[s]
        d0, d1, d2 = y[h, 0] - position[s, 0], y[h, 1] - position[s, 1], y[h, 2] - position[s, 2]
        cos_y = normal[h, 0] * d[0] + normal[h, 1] * d[1] + normal[h, 2] * d[2]
        footprint[h] = (d0 * d0 + d1 * d1 + d2 * d2) / max(pdf[h] * abs(cos_y), 1e-300)
    mine, covered, shared, estimate = np.zeros(hits), np.zeros(hits), np.zeros(hits), np.zeros((hits, 3))
    for q in range(len(pair)):
        h, i = pair[q], light[q]
        lit = share[q] * max(1.0 + slope[i, 0] * (y[h, 0] - middle[i, 0]) + slope[i, 1] * (y[h, 1] - middle[i, 1])
                             + slope[i, 2] * (y[h, 2] - middle[i, 2]), 0.0)  # s_i(y) times L_i(y) / L_i
        if drawn[h] >= 0:
            if i == drawn[h]:
                mine[h] += lit
            continue
        s = source[h]
        p_i = choice[i] * _disc_density(position[s, 0], position[s, 1], position[s, 2], w[s, 0], w[s, 1], w[s, 2],
                                        centre[i], facing[i], radius[i])
        w_v = _blend_weight(footprint[h], density[i], n_min, span, extend)
        mis = _power_heuristic(pdf[h], p_i) * w_v
        r0, r1, r2 = radiance[i, 0] * lit, radiance[i, 1] * lit, radiance[i, 2] * lit
        estimate[h, 0] += r0 * mis
        estimate[h, 1] += r1 * mis
        estimate[h, 2] += r2 * mis
        covered[h] += share[q]
        shared[h] += w_v * share[q]
    mean_share = np.zeros(hits)
    for h in range(hits):
        j, s = drawn[h], source[h]
        if j >= 0:
            scale = mine[h] * _power_heuristic(p_light[s], pdf[h]) * \
                _blend_weight(footprint[h], density[j], n_min, span, extend) / p_light[s]
            for c in range(3):
                out[owner[s], c] += weight[h, c] * radiance[j, c] * scale
        else:
            if covered[h] > 0.0:
                mean_share[h] = shared[h] / max(covered[h], 1e-300)
            for c in range(3):
                out[owner[s], c] += weight[h, c] * estimate[h, c]
    return mean_share
