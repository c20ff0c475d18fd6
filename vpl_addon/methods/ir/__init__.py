"""Keller's Instant Radiosity (SIGGRAPH 1997): VPLs where light paths from the lights bounce.

Lights are chosen in proportion to their power; a path leaves a VPL at every diffuse bounce up to the scene's
bounce limit (``paths.light_paths.trace_paths``). The budget is the number of VPLs.

In a sequence the light paths are kept from frame to frame (``sequence.path_verification.LightPathStore``, Moreau et
al.): paths follow the lights that moved (distribution maps, sec. 3.1), those that cross the bounding boxes of moved
objects are verified from the first crossing segment (sec. 3.2) with the error threshold of eq. 2 (sec. 3.3,
``MethodSettings.path_threshold``); when nothing moved, nothing is traced; a changed material traces every path."""
from __future__ import annotations

from ...paths.light_paths import trace_until
from ...sequence.path_verification import LightPathStore, follow
from ..base import Method


def place(context, settings):
    vpls, paths = trace_until(context.scene, context.tracer, context.lights, settings.vpls, context.rng,
                              context.max_bounces)
    return vpls, {"light_paths": paths, "vpls": len(vpls)}


def start(context, settings) -> LightPathStore:
    return LightPathStore()


def advance(store: LightPathStore, context, settings, motion):
    traced = follow(store, context, motion, settings.vpls, settings.path_reuse, settings.path_threshold)
    vpls = store.lights()
    return vpls, {"light_paths": traced, "paths_kept": store.paths, "vpls": len(vpls),
                  "light_path_rays": store.rays_last_frame, "reused": traced == 0}


METHOD = Method(
    "ir", "Instant Radiosity", "Keller 1997: VPLs where light paths from the lights bounce",
    place, start=start, advance=advance, view_independent=True, reuses_light_paths=True)
