"""Direct lighting by next-event estimation: Cycles' ``Diffuse Direct`` and ``Glossy Direct`` passes.

For each shading point, ``samples`` light samples: a light chosen by the light it can bring there (``LightSet``'s
light tree), a point or direction on it, one shadow ray. The result is the outgoing radiance of a white Lambertian
surface, (1/pi) * integral L_i cos(theta) d omega, which is how Cycles defines the pass (light reflected by the
diffuse BSDF, divided by the diffuse colour).

When the points are the samples of pixels (the G-buffer), the caller can hand in the light-sample numbers: those of
all samples of a pixel then form one scrambled Sobol net (``sampling.stratified_2d``) dealt out in random order,
so a pixel's shadow rays cover the light evenly instead of clumping as independent numbers do.

The metallic lobe's light combines the light samples with as many samples of the lobe itself by multiple
importance sampling (Veach and Guibas 1995, the power heuristic), per light: a sharp lobe inside a light's solid
angle is found by its own samples, where light samples alone give f cos / pdf of 10^4 and more (single samples
that the filter spreads into squares). Lights that cannot evaluate their pdf for a given direction (``Light.mis``
None: points, spots, suns) keep light samples alone, and so does a rough coat (``Surface.rough_coat``), a lobe nearly
as broad as the diffuse one: its lobe samples and the light pdfs that weigh against them by MIS would take two thirds
of the direct light's time on walls of the Principled BSDF's default Specular (the imported USD Cornell box), for a
few per cent of the light.
"""
from __future__ import annotations

import numpy as np

from ..core.color import largest
from ..core.sampling import dot, group_sum, power_heuristic, stratified_2d
from ..materials.microfacet import GlossyLobe
from ..core.compiled import kernel
from ..materials.surface import bent, bump_shadowing

RAYS_PER_BATCH = 1 << 18  # light samples at once: a batch's arrays (about 200 bytes a sample) stay near 50 MB


def diffuse_direct(surface, lights, tracer, samples: int, rng: np.random.Generator) -> np.ndarray:
    """(K,3) direct diffuse radiance of a white Lambertian surface at each point (``direct_light`` without the
    glossy lobe)."""
    return direct_light(surface, lights, tracer, samples, rng)[0]


def direct_light(surface, lights, tracer, samples: int, rng: np.random.Generator,
                 numbers: tuple[np.ndarray, ...] | None = None, glossy: GlossyLobe | None = None,
                 through: np.ndarray | None = None):
    """(diffuse (K,3), glossy (K,3)): at each point of a ``Surface``, averaged over ``samples`` light samples, the
    direct radiance a white Lambertian surface reflects and, if ``glossy`` is given, the radiance its metallic lobe
    reflects toward the viewer (zero otherwise).

    Each light sample is one sample of a local light (chosen by the light tree) plus, if the world emits, one
    cosine-weighted sample of the world. ``numbers`` = (u1, u2, w1, w2[, c]), each (K, samples) or None: the
    uniform numbers for the local and the world samples and for the local light's choice, instead of independent
    ones. ``through``: a (K,3) array that
    takes the diffuse part of the light whose shadow ray went through glass (``materials.cutouts``), which Cycles
    counts as indirect (a transmission bounce); None leaves it in the first output."""
    k = len(surface)
    out, shine = np.zeros((k, 3)), np.zeros((k, 3))
    if k == 0 or len(lights) == 0 or samples <= 0:
        return out, shine
    glazed = None if through is None else np.zeros((k, 3))
    weighed = None if glossy is None else glossy.present & ~surface.rough_coat  # the points whose lobe takes MIS
    p = surface.position
    ng = surface.geometric_normal
    ns = surface.shading_normal
    step = max(1, RAYS_PER_BATCH // samples)
    # every sample's numbers drawn before the batches: how many batches there are does not change them
    given = (tuple(numbers or ()) + (None,) * 5)[:5]
    numbers_of = [rng.random(k * samples) if a is None else a.ravel() for a in given[:4]]
    jitter = (rng.random(k * samples) if given[4] is None else given[4].ravel()) if lights.local else None
    for lo in range(0, k, step):
        hi = min(k, lo + step)
        owner = np.repeat(np.arange(hi - lo), samples)  # the point of each light sample, within the batch
        # shadow rays leave through the side the geometric normal faces (``_accumulate`` keeps only those): one
        # offset origin per point
        at_p, at_ns = p[lo:hi], ns[lo:hi]  # the batch's points
        origin = tracer.offset_origin(at_p, ng[lo:hi])
        at = (lo, hi, owner, origin, at_p, ng[lo:hi], at_ns, surface.smooth_normal[lo:hi])
        u1, u2, w1, w2 = (a[lo * samples:hi * samples] for a in numbers_of)
        if lights.local:
            # stratify the light choice over the samples of one point
            strata = (np.tile(np.arange(samples), hi - lo) + jitter[lo * samples:hi * samples]) / samples
            wi, dist, weight, target_n, which, chance = lights.sample_incident(at_p, at_ns, strata, u1, u2, owner)
            _accumulate(out, shine, at, wi, dist, weight, target_n, tracer, glossy, weighed,
                        lambda rows: lights.local_pdf(at_p[owner[rows]], at_ns[owner[rows]], wi[rows], which[rows],
                                                      chance[rows]), glazed)
        if lights.world is not None:
            wi, dist, weight = lights.world.directions(at_p, at_ns, w1, w2, owner)
            _accumulate(out, shine, at, wi, dist, weight, None, tracer, glossy, weighed,
                        lambda rows: lights.world.mis(at_p[owner[rows]], at_ns[owner[rows]], wi[rows])[2], glazed)
        if glossy is not None:
            _lobe_samples(shine, at, lights, tracer, glossy, weighed, rng)
    if through is not None:
        through += glazed / samples
    return out / samples, shine / samples


def _accumulate(out, shine, at, wi, dist, weight, target_n, tracer, glossy, weighed, light_pdf, through=None):
    """out[lo:hi] += the light samples' contributions weight * cos / pi * V (cos with the bump shadowing term,
    ``surface.diffuse_cosine``), summed per point; shine[lo:hi] += weight * (f cos of the glossy lobe) * V * the
    MIS weight against the lobe's pdf (``light_pdf(rows)``: the light samples' own pdf, NaN for no MIS) at the points
    ``weighed``, 1 elsewhere. ``at`` = (lo, hi, the point of each sample within lo:hi, the shadow rays' origin at
    each point, and the position, geometric, shading and smooth normal of each sample's point); ``through`` (or
    ``out`` when None) takes the diffuse light of the rays that went through glass. ``weight``: (N,3), or
    ``Light.directions``' function of the rows, then asked for the unblocked samples' alone."""
    lo, hi, owner, origin, p, ng, ns, smooth = at
    cos = np.empty(len(wi))
    weigh = weight if callable(weight) else None
    sel = np.nonzero(_facing(owner, ng, ns, wi, np.zeros((0, 3)) if weigh else weight, cos))[0]
    turned = np.nonzero(bent(smooth, ns)[owner[sel]])[0]  # samples at points a normal map bent
    if len(turned):
        rows, points = sel[turned], owner[sel[turned]]
        cos[rows] *= bump_shadowing(smooth[points], ns[points], wi[rows])
        sel = sel[cos[sel] > 0.0]
    if len(sel) == 0:
        return
    on_geometry = None if target_n is None else target_n[sel]
    seen, glass, tint = tracer.visible_through(p, ng, wi[sel], dist[sel], on_geometry, origin, at=owner[sel],
                                               tinted=True)
    sel, glass, tint = sel[seen], glass[seen], None if tint is None else tint[seen]
    if weigh is None:
        weight = weight[sel]
    else:  # as ``_facing`` would have: only a weight positive and finite
        weight = weigh(sel)
        total = weight.sum(axis=1)
        good = np.nonzero((total > 0.0) & (total < np.inf))[0]
        sel, glass, weight, tint = sel[good], glass[good], weight[good], None if tint is None else tint[good]
    arrived = weight if tint is None else weight * tint  # coloured by the glass on the way
    light = arrived * (cos[sel] / np.pi)[:, None]
    if through is not None and glass.any():
        through[lo:hi] += group_sum(owner[sel[glass]], light[glass], hi - lo)
        light[glass] = 0.0
    out[lo:hi] += group_sum(owner[sel], light, hi - lo)
    if glossy is not None:
        point = owner[sel] + lo
        lit = np.nonzero(glossy.present[point])[0]
        value, p_lobe = glossy.evaluate(wi[sel[lit]], point[lit])
        mis = np.nonzero(weighed[point[lit]])[0]  # a rough coat's light samples stand alone
        value[mis] *= power_heuristic(light_pdf(sel[lit[mis]]), p_lobe[mis])[:, None]
        shine[lo:hi] += group_sum(owner[sel[lit]], arrived[lit] * value, hi - lo)


def _lobe_samples(shine, at, lights, tracer, glossy, weighed, rng):
    """shine[lo:hi] += MIS's other half: one direction from the glossy lobe per light sample at the points
    ``weighed`` (not at a rough coat), and the light of every light the ray finds (``Light.mis``) that is not
    hidden, times f cos / pdf and the MIS weight against that light's own pdf. The directions are kept to those the
    light samples can take (above the shading and the geometric surface)."""
    lo, hi, owner, origin, p, ng, ns, _ = at
    rows = np.nonzero(weighed[owner + lo])[0]
    if len(rows) == 0:
        return
    p, ng, ns = p[owner], ng[owner], ns[owner]  # each light sample's point
    u1, u2 = (u.ravel()[rows] for u in stratified_2d(hi - lo, len(owner) // (hi - lo), rng))  # a net per point
    w, f_cos_pdf, p_lobe = glossy.sample(u1, u2, owner[rows] + lo)
    keep = np.nonzero((p_lobe > 0.0) & (dot(ns[rows], w) > 0.0) & (dot(ng[rows], w) > 0.0))[0]
    rows, w, f_cos_pdf, p_lobe = rows[keep], w[keep], f_cos_pdf[keep], p_lobe[keep]
    if len(rows) == 0:
        return
    found = list(enumerate(lights.local))
    if lights.world is not None:
        found.append((None, lights.world))
    for index, light in found:
        answer = light.mis(p[rows], ns[rows], w)
        if answer is None:
            continue
        dist, radiance, pdf = answer[:3]
        hit = np.nonzero((pdf > 0.0) & (largest(radiance) > 0.0))[0]
        if index is not None:  # times the probability of choosing the light there
            pdf[hit] *= lights.selection(p[rows[hit]], ns[rows[hit]], np.full(len(hit), index))
        # a light on geometry: the shadow ray stops off its surface, as the light samples' do
        on_geometry = answer[3][hit] if len(answer) > 3 else None
        seen, _, tint = tracer.visible_through(p[rows[hit]], ng[rows[hit]], w[hit], dist[hit], on_geometry,
                                               origin[owner[rows[hit]]], tinted=True)
        hit = hit[seen]
        light_in = f_cos_pdf[hit] * radiance[hit] * power_heuristic(p_lobe[hit], pdf[hit])[:, None]
        if tint is not None:
            light_in *= tint[seen]
        shine[lo:hi] += group_sum(owner[rows[hit]], light_in, hi - lo)


@kernel
def _facing(owner, ng, ns, wi, weight, cos):
    """(N,) which light samples can bring light: direction ``wi`` above the shading normal (``cos`` takes
    max(0, ns . wi), the diffuse cosine before ``surface.bump_shadowing``) and the geometric normal of its point
    ``owner``, and a weight that is positive and finite (no NaN or infinity reaches a pixel; not tested for an empty
    ``weight``, one weighed later)."""
    keep = np.zeros(len(owner), np.bool_)
    weighed = len(weight) > 0
    for i in range(len(owner)):
        j = owner[i]
        c = ns[j, 0] * wi[i, 0] + ns[j, 1] * wi[i, 1] + ns[j, 2] * wi[i, 2]
        cos[i] = max(c, 0.0)
        total = weight[i, 0] + weight[i, 1] + weight[i, 2] if weighed else 1.0
        keep[i] = c > 0.0 and ng[j, 0] * wi[i, 0] + ng[j, 1] * wi[i, 1] + ng[j, 2] * wi[i, 2] > 0.0 and \
            total > 0.0 and total < np.inf
    return keep
