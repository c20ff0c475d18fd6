"""Keller's Instant Radiosity (SIGGRAPH 1997): VPLs where light paths from the lights bounce.

Lights are chosen in proportion to their power; a path leaves a VPL at every diffuse bounce up to the scene's
bounce limit (``light_paths.trace_paths``). The budget is the number of VPLs."""
from __future__ import annotations

from ..light_paths import trace_until


def place(context, settings):
    vpls, paths = trace_until(context.scene, context.tracer, context.lights, settings.vpls, context.rng,
                              context.max_bounces)
    return vpls, {"light_paths": paths, "vpls": len(vpls)}
