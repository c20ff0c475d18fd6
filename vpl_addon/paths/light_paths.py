"""Light paths: photons from the lights with a VPL left at every diffuse bounce (Keller, Instant Radiosity 1997).

Paths start with ``LightSet.emit`` (lights chosen in proportion to power, or by a given distribution such as the
camera-driven one of Segovia et al. sec. 4.1), bounce with cosine-weighted directions off the diffuse part or by
visible normals off a metallic lobe (``microfacet``), take the colour of the coloured glass they cross
(``materials.cutouts``), and end by Russian roulette (the diffuse lobe is chosen with
probability its largest albedo channel, the metallic one with its largest Glossy Color channel) or at the bounce
limit. The random numbers of a batch are
Latin-hypercube stratified over its paths. The VPL at a bounce carries the path's
incident power times albedo / pi (times ``surface.arrival_factor`` where a normal map bends the normal), and the
smooth normal; divided by the number of paths (``trace_until``), the whole set estimates the indirect light. A VPL
whose path came from its light over one sharp glossy lobe (light -> Roughness below ``SHARP`` -> here) also holds
the light a white Lambertian surface would reflect there (``VirtualLights.caustic``): a caustic photon in Jensen's
sense (*Global Illumination using Photon Maps*, 1996, sec. 3.1), the light that the photon lights' renderer
estimates from the photons' density instead of by paths that must find a small light through a sharp lobe
(``methods.vbnl.virtual_light_sampling``).
"""
from __future__ import annotations

import numpy as np

from ..core.color import largest
from ..core.sampling import LatinHypercube, cosine_hemisphere, dot
from ..gather.virtual_lights import STANDARD, VirtualLights
from ..materials.microfacet import GlossyLobe
from ..materials.surface import arrival_factor, shade

BATCH_PATHS = 1 << 15
FRESH, OVER_GLOSSY, DIFFUSED = 0, 1, 2  # what a light path did before its current segment (``trace_paths``)
# Roughness below which a glossy lobe's caustics are the photons' (``VirtualLights.caustic``): through a broader
# lobe the camera's paths find the lights well (the Principled BSDF box's metal band, Roughness 0.25 to 0.85: its
# Diffuse Indirect rMAE 0.100 by paths, 0.107 by photons), through a sharper one 0.1 % of their samples carry 82 %
# of the light (the helmet's metal under its sky's sun)
SHARP = 0.2


def trace_paths(scene, tracer, lights, count: int, rng: np.random.Generator, max_bounces: int,
                light_prob: np.ndarray | None = None, first_path: int = 0, start=None, record=None,
                start_hits=None, caustics: np.ndarray | None = None) -> VirtualLights:
    """VPLs of ``count`` light paths with at most ``max_bounces`` surface interactions (not yet divided by the
    number of paths). Path verification (``path_verification``) continues paths from a given segment with
    ``start = (origins, dirs, power, path ids, bounce)`` instead of emitting, and keeps every traced segment through
    ``record(bounce, origins, dirs, power, path ids, light)`` (``light``: the index of each emitted path's light in
    ``lights``, None past the emission). ``start_hits``: the given segments' hits when the caller traced them
    already (path verification's threshold test), so they are not traced twice. ``caustics``: (L,) bool, the
    lights whose paths leave caustic photons (``methods.vbnl.caustic_photons`` aims the others'); None: all."""
    if len(lights) == 0 or max_bounces <= 0 or (count <= 0 if start is None else len(start[0]) == 0):
        return VirtualLights.empty()
    rng = LatinHypercube(rng)
    glossy = scene.materials.glossy
    origins, dirs, power, path, first_bounce, light = _first_segments(
        lights, count, rng, light_prob, first_path, start, record is not None or caustics is not None)
    # per path: FRESH (no bounce yet), OVER_GLOSSY (one bounce, off a sharp glossy lobe) or DIFFUSED (any other);
    # a path continued from a given segment counts as diffused, its past unknown, as does one whose caustics are
    # not its own
    past = np.full(len(origins), FRESH if start is None else DIFFUSED, np.int8)
    if caustics is not None and start is None:
        past[~caustics[light]] = DIFFUSED
    found = []
    for bounce in range(first_bounce, max_bounces + 1):
        if len(origins) == 0:
            break
        if record is not None:
            record(bounce, origins, dirs, power, path, light if bounce == first_bounce else None)
        hits = start_hits if bounce == first_bounce and start_hits is not None else \
            tracer.intersect(origins, dirs, tinted=True)
        rows = np.nonzero(hits.hit)[0]
        surf, path, past = shade(scene, dirs, hits, rows), path[rows], past[rows]
        incident = power[rows] if hits.tint is None else power[rows] * hits.tint[rows]  # past coloured glass
        arrival = arrival_factor(surf)[:, None]  # a normal map's light, as Cycles sees it
        diffuse = surf.albedo * arrival
        found.append(_left_lights(surf, incident, diffuse, bounce, path,
                                  np.where((past == OVER_GLOSSY)[:, None], incident * arrival / np.pi, 0.0)))
        if bounce == max_bounces:
            break
        sel, dirs, weight, shiny = _scattered(surf, diffuse, rng, glossy)
        power = incident[sel] * weight
        origins = tracer.offset_origin(surf.position[sel], surf.geometric_normal[sel])
        path = path[sel]
        sharp = shiny & (surf.roughness[sel] < SHARP)
        past = np.where(sharp & (past[sel] == FRESH), OVER_GLOSSY, DIFFUSED).astype(np.int8)
    return VirtualLights.concat(found)


def _first_segments(lights, count, rng, light_prob, first_path, start, with_light):
    """(origins, dirs, power, path ids, first bounce, light) of the paths' first segments: ``start``'s, or ``count``
    emitted by ``lights`` (numbered from ``first_path``, bounce 1); ``light``, each emitted path's light, only
    ``with_light`` (else None)."""
    if start is not None:
        origins, dirs, power, path, first_bounce = start
        return origins, dirs, power, path, first_bounce, None
    light = None
    if with_light:
        origins, dirs, power, light = lights.emit(count, rng, light_prob, with_light=True)
    else:
        origins, dirs, power = lights.emit(count, rng, light_prob)
    return origins, dirs, power, np.arange(first_path, first_path + count), 1, light


def _left_lights(surf, incident, diffuse, bounce, path, caustic):
    """The standard VPLs a bounce leaves at the hits ``surf`` of paths ``path``: one at each that reflects diffusely
    (none on metal), with the smooth normal and the ``incident`` power times the ``diffuse`` reflectance / pi, and
    the ``caustic`` intensity (``VirtualLights.caustic``) of each hit."""
    lit = np.nonzero(largest(surf.albedo) > 0.0)[0]
    lights_left = len(lit)
    if lights_left == len(path):  # every hit: no copies
        lit = slice(None)
    return VirtualLights(surf.position[lit], surf.smooth_normal[lit], incident[lit] * diffuse[lit] / np.pi,
                         np.full(lights_left, bounce, np.int32), np.full(lights_left, STANDARD, np.int8), path[lit],
                         caustic[lit])


def _scattered(surf, diffuse, rng, glossy: bool):
    """(the hits whose paths go on, their directions, the weight f cos / pdf each carries, whether each took the
    glossy lobe) past a bounce at ``surf`` (``diffuse`` the diffuse reflectance): Russian roulette keeps a path on
    the diffuse lobe with probability its largest albedo channel (a cosine-weighted direction) and, with a
    ``glossy`` lobe, on the metallic one with its largest Glossy Color channel (``_glossy_bounces``); a direction
    below the true surface is absorbed."""
    choose_diffuse = np.clip(largest(surf.albedo), 0.0, 1.0)
    u = rng.random(len(choose_diffuse))
    keep = u < choose_diffuse
    new_dirs, _ = cosine_hemisphere(rng.random(keep.sum()), rng.random(keep.sum()), surf.shading_normal[keep])
    weight = diffuse[keep] / choose_diffuse[keep, None]
    bouncing = np.nonzero(keep)[0]
    shiny = np.zeros(len(bouncing), bool)
    if glossy:
        glossy_rows, dirs_g, weight_g = _glossy_bounces(surf, keep, u, choose_diffuse, rng)
        bouncing = np.concatenate([bouncing, glossy_rows])
        new_dirs = np.concatenate([new_dirs, dirs_g])
        weight = np.concatenate([weight, weight_g])
        shiny = np.concatenate([shiny, np.ones(len(glossy_rows), bool)])
    leaves = (dot(new_dirs, surf.geometric_normal[bouncing]) > 0.0) & (largest(weight) > 0.0)
    return bouncing[leaves], new_dirs[leaves], weight[leaves], shiny[leaves]


def _glossy_bounces(surf, keep, u, choose_diffuse, rng):
    """(hits, directions, f cos / pdf) of the paths that bounce off the metallic lobe (``GlossyLobe``, visible
    normals): of those the diffuse lobe does not keep (``keep``), each glossy hit with probability its largest Glossy
    Color channel (at most what the diffuse lobe leaves) of the same roulette number ``u``."""
    shiny = np.nonzero(~keep & surf.glossy)[0]
    lobe = GlossyLobe.of(surf, shiny)
    choose_glossy = np.minimum(largest(lobe.color), 1.0 - choose_diffuse[shiny])
    shiny_keep = u[shiny] < choose_diffuse[shiny] + choose_glossy
    lobe = lobe.take(shiny_keep)
    dirs, f_cos_pdf, _ = lobe.sample(rng.random(shiny_keep.sum()), rng.random(shiny_keep.sum()),
                                     np.arange(shiny_keep.sum()))
    return shiny[shiny_keep], dirs, f_cos_pdf / choose_glossy[shiny_keep, None]


def trace_until(scene, tracer, lights, target: int, rng, max_bounces: int, light_prob=None, record=None):
    """Standard VPLs from as many paths as it takes to leave about ``target`` of them: (vpls, paths traced).

    Paths are traced in batches sized from the VPLs per path seen so far; the weights are divided by the total
    number of paths. Gives up after 64 paths per wanted VPL (light that never reaches a surface)."""
    parts, paths, found = [], 0, 0
    batch = max(64, target // 4)
    while found < target and paths < 64 * target + 1024:
        count = min(batch, BATCH_PATHS)
        parts.append(trace_paths(scene, tracer, lights, count, rng, max_bounces, light_prob, first_path=paths,
                                 record=record))
        paths += count
        found += len(parts[-1])
        if found:
            batch = max(64, int((target - found) * paths / found) + 1)
    return VirtualLights.concat(parts).scaled(1.0 / max(paths, 1)), paths
