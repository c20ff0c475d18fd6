"""Light paths: photons from the lights with a VPL left at every diffuse bounce (Keller, Instant Radiosity 1997).

Paths start with ``LightSet.emit`` (lights chosen in proportion to power, or by a given distribution such as the
camera-driven one of Segovia et al. sec. 4.1), bounce with cosine-weighted directions off the diffuse part or by
visible normals off a metallic lobe (``microfacet``), take the colour of the coloured glass they cross
(``materials.cutouts``), and end by Russian roulette (the diffuse lobe is chosen with
probability its largest albedo channel, the metallic one with its largest Glossy Color channel) or at the bounce
limit. The random numbers of a batch are
Latin-hypercube stratified over its paths. The VPL at a bounce carries the path's
incident power times albedo / pi (times ``surface.arrival_factor`` where a normal map bends the normal), and the
smooth normal; divided by the number of paths (``trace_until``), the whole set estimates the indirect light.
"""
from __future__ import annotations

import numpy as np

from ..core.color import largest
from ..core.sampling import LatinHypercube, cosine_hemisphere, dot
from ..gather.virtual_lights import STANDARD, VirtualLights
from ..materials.microfacet import GlossyLobe
from ..materials.surface import arrival_factor, shade

BATCH_PATHS = 1 << 15


def trace_paths(scene, tracer, lights, count: int, rng: np.random.Generator, max_bounces: int,
                light_prob: np.ndarray | None = None, first_path: int = 0, start=None, record=None,
                start_hits=None) -> VirtualLights:
    """VPLs of ``count`` light paths with at most ``max_bounces`` surface interactions (not yet divided by the
    number of paths). Path verification (``path_verification``) continues paths from a given segment with
    ``start = (origins, dirs, power, path ids, bounce)`` instead of emitting, and keeps every traced segment through
    ``record(bounce, origins, dirs, power, path ids, light)`` (``light``: the index of each emitted path's light in
    ``lights``, None past the emission). ``start_hits``: the given segments' hits when the caller traced them
    already (path verification's threshold test), so they are not traced twice."""
    if len(lights) == 0 or max_bounces <= 0 or (count <= 0 if start is None else len(start[0]) == 0):
        return VirtualLights.empty()
    rng = LatinHypercube(rng)
    glossy = scene.materials.glossy
    light = None
    if start is None and record is not None:
        origins, dirs, power, light = lights.emit(count, rng, light_prob, with_light=True)
    elif start is None:
        origins, dirs, power = lights.emit(count, rng, light_prob)
    else:
        origins, dirs, power, path, first_bounce = start
    if start is None:
        path, first_bounce = np.arange(first_path, first_path + count), 1
    found = []
    for bounce in range(first_bounce, max_bounces + 1):
        if len(origins) == 0:
            break
        if record is not None:
            record(bounce, origins, dirs, power, path, light if bounce == first_bounce else None)
        hits = start_hits if bounce == first_bounce and start_hits is not None else \
            tracer.intersect(origins, dirs, tinted=True)
        rows = np.nonzero(hits.hit)[0]
        surf = shade(scene, dirs, hits, rows)
        incident = power[rows] if hits.tint is None else power[rows] * hits.tint[rows]  # past coloured glass
        lit = np.nonzero(largest(surf.albedo) > 0.0)[0]  # no VPL where nothing is reflected diffusely (metal)
        lights_left = len(lit)
        if lights_left == len(rows):  # every hit: no copies
            lit = slice(None)
        diffuse = surf.albedo * arrival_factor(surf)[:, None]  # a normal map's light, as Cycles sees it
        found.append(VirtualLights(surf.position[lit], surf.smooth_normal[lit], incident[lit] * diffuse[lit] / np.pi,
                                   np.full(lights_left, bounce, np.int32), np.full(lights_left, STANDARD, np.int8),
                                   path[rows][lit]))
        if bounce == max_bounces:
            break
        choose_diffuse = np.clip(largest(surf.albedo), 0.0, 1.0)
        u = rng.random(len(rows))
        keep = u < choose_diffuse
        new_dirs, _ = cosine_hemisphere(rng.random(keep.sum()), rng.random(keep.sum()), surf.shading_normal[keep])
        weight = diffuse[keep] / choose_diffuse[keep, None]
        if glossy:
            shiny = np.nonzero(~keep & surf.glossy)[0]
            lobe = GlossyLobe.of(surf, shiny)
            choose_glossy = np.minimum(largest(lobe.color), 1.0 - choose_diffuse[shiny])
            shiny_keep = u[shiny] < choose_diffuse[shiny] + choose_glossy
            lobe = lobe.take(shiny_keep)
            dirs_g, f_cos_pdf, _ = lobe.sample(rng.random(shiny_keep.sum()), rng.random(shiny_keep.sum()),
                                               np.arange(shiny_keep.sum()))
            bouncing = np.concatenate([np.nonzero(keep)[0], shiny[shiny_keep]])
            new_dirs = np.concatenate([new_dirs, dirs_g])
            weight = np.concatenate([weight, f_cos_pdf / choose_glossy[shiny_keep, None]])
        else:
            bouncing = np.nonzero(keep)[0]
        leaves = (dot(new_dirs, surf.geometric_normal[bouncing]) > 0.0) & (largest(weight) > 0.0)
        sel = bouncing[leaves]  # below the true surface: absorbed
        dirs = new_dirs[leaves]
        power = incident[sel] * weight[leaves]
        origins = tracer.offset_origin(surf.position[sel], surf.geometric_normal[sel])
        path = path[rows][sel]
    return VirtualLights.concat(found)


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
