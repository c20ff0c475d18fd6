"""Keller's Instant Radiosity (SIGGRAPH 1997): VPLs where light paths from the lights bounce.

Lights are chosen in proportion to their power; a path leaves a VPL at every diffuse bounce up to the scene's
bounce limit (``light_paths.trace_paths``). The budget is the number of VPLs.

In a sequence the light paths are kept from frame to frame (``path_verification.LightPathStore``, Moreau et al.):
when only objects moved, just the paths that cross their bounding boxes are traced again from the first crossing
segment; when nothing moved, nothing is traced; a changed light or material traces every path again."""
from __future__ import annotations

import numpy as np

from ..light_paths import trace_until
from ..path_verification import LightPathStore


def place(context, settings):
    vpls, paths = trace_until(context.scene, context.tracer, context.lights, settings.vpls, context.rng,
                              context.max_bounces)
    return vpls, {"light_paths": paths, "vpls": len(vpls)}


def start(context, settings) -> LightPathStore:
    return LightPathStore()


def advance(store: LightPathStore, context, settings, motion):
    scene, tracer = context.scene, context.tracer
    everything = not store.paths or motion.first or motion.lights_changed or motion.shading_changed or \
        (bool(motion.moved_objects) and not settings.path_reuse)
    if everything:
        store.trace(scene, tracer, context.lights, settings.vpls, context.rng, context.max_bounces)
        traced = store.paths
    elif motion.moved_objects:
        extent = float(np.linalg.norm(np.subtract(*scene.bounds)))
        traced = store.verify(scene, tracer, context.lights, motion.boxes, context.rng, context.max_bounces,
                              margin=1e-5 * extent)
    else:
        traced = store.rays_last_frame = 0
    vpls = store.lights()
    return vpls, {"light_paths": traced, "paths_kept": store.paths, "vpls": len(vpls),
                  "light_path_rays": store.rays_last_frame, "reused": traced == 0}
