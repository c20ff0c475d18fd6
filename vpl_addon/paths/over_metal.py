"""Glossy transport for summed VPLs: camera paths continued through metal until the VPL gather can take over.

A VPL is a diffuse point light reached by a straight shadow ray, so the gather (``gather.summing``) finds only light
that comes to a point straight from a diffuse surface. Two kinds of light are left out where the scene has metal:

- at a diffuse point x, light arriving over metal (y metallic): the lights' own light the metal reflects to x (a
  glossy caustic: light -> y -> x) and the light of diffuse surfaces it reflects (z -> y -> x);
- at a metallic point, all of its indirect light (Cycles' ``Glossy Indirect``).

Both are estimated by extending the camera path as a path tracer would (Kajiya 1986), one sample per vertex: a
direction of its lobe (cosine-weighted for a white Lambertian or diffuse one, visible normals for a metallic one,
``microfacet``); at a metallic hit y, its direct light by next-event estimation with multiple importance sampling
(``lights.direct.direct_light``), and the path goes on through y's lobe; at a diffuse hit z reached over metal, z's
reflected light: its direct light plus what the VPLs bring it straight (the caller's gather), and the path goes on
from z through its diffuse lobe to find z's own light over metal (a wall lit by a bright patch the metal floor
throws, seen in that floor). A diffuse hit straight from a diffuse vertex is the gather's own (the VPLs stand for
it), so it is not counted, and the path goes no further there. Every vertex past the start goes on by Russian
roulette on its throughput (``vertices.roulette``), as Cycles' paths do. This is the extension the photon lights'
renderer makes at metal (``methods.vbnl.virtual_light_sampling``, Li et al. 2022 sec. 4), with the VPL gather where
that one samples its lights.

Bounces are counted as Cycles counts them (direct light at the start point is 0): a vertex k steps from the start
brings direct light of k bounces, the VPLs there light of at least k + 1; what the scene's bounce limit excludes is
not added (the VPLs' own bounces are not checked against it)."""
from __future__ import annotations

from typing import Callable

import numpy as np

from ..core.color import largest
from ..core.sampling import group_sum
from ..lights.direct import direct_light
from ..materials.microfacet import GlossyLobe
from ..materials.surface import Surface, bounce
from .vertices import PathVertices, at_metal, merged, roulette

# steps a path may take past its start; light further on is dropped (only metal facing metal gets that far)
CHAIN = 4


def over_metal(surface: Surface, lobe: GlossyLobe | None, scene, tracer, lights, rng: np.random.Generator,
               vpl_light: Callable[[Surface], np.ndarray], max_bounces: int) -> np.ndarray:
    """(K,3) indirect light the points of ``surface`` receive over metal: reflected by a white Lambertian surface
    (``lobe`` None: what the gather leaves out of ``Diffuse Indirect``) or by the metallic ``lobe`` with its
    colour (its whole ``Glossy Indirect`` times ``Glossy Color``).

    ``vpl_light(points)`` is the caller's gather: the light of the VPLs at diffuse ``points`` (a white Lambertian
    receiver)."""
    out = np.zeros((len(surface), 3))
    if len(surface) == 0 or not scene.materials.glossy or max_bounces <= 0:
        return out
    level = [PathVertices(surface, np.arange(len(surface)), np.ones((len(surface), 3)), lobe)]
    for step in range(1, min(CHAIN, max_bounces) + 1):
        following = []
        for v in level:
            dirs, sampled, pdf = v.sample(rng.random((2, len(v))))
            y, at = bounce(scene, tracer, v.point, dirs)
            owner = v.owner[at]
            carried = v.throughput[at] * np.where((pdf[at] > 0.0)[:, None], sampled[at], 0.0)
            if v.lobe is not None:  # diffuse ends reached over metal
                carry = carried * y.albedo
                ends, boost = roulette(carry, rng)
                end = PathVertices(y.take(ends), owner[ends], carry[ends] * boost[:, None])
                light = direct_light(end.point, lights, tracer, 1, rng)[0]
                if step + 1 <= max_bounces:
                    light = light + vpl_light(end.point)
                out += group_sum(end.owner, end.throughput * light, len(out))
                following.append(end)
            shiny = np.nonzero(y.glossy & (largest(carried) > 0.0))[0]
            following.append(at_metal(y, shiny, owner, carried, lights, tracer, rng, out))
        level = merged(following)
        if not level:
            break
    return out
