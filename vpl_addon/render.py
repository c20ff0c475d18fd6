"""The pipeline of one frame: Scene -> Tracer -> G-buffer blocks -> direct light -> passes.

Pixels are processed in blocks, concurrently on all cores, so memory stays flat at any resolution and sample
count; each block draws its random numbers from ``(seed, block)`` so a render is deterministic. ``progress(fraction, text)`` is called after
each block and may return False to cancel (ESC in Blender), which raises ``Cancelled``.
"""
from __future__ import annotations

import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from . import passes as P
from .direct import diffuse_direct
from .gbuffer import GBuffer
from .lights import LightSet
from .tracer import Tracer


class Cancelled(Exception):
    """The user cancelled the render."""


@dataclass
class RenderSettings:
    samples: int = 64  # camera samples per pixel (G-buffer)
    light_samples: int = 4  # next-event samples per camera sample for direct light
    seed: int = 0
    passes: tuple[str, ...] = (P.COMBINED, P.DIFFUSE_DIRECT, P.DIFFUSE_COLOR, P.EMIT)
    block_pixels: int = 4096

    def __post_init__(self):
        if self.samples < 1:
            raise ValueError(f"samples must be at least 1 (got {self.samples})")
        if self.light_samples < 0:
            raise ValueError(f"light samples must not be negative (got {self.light_samples})")
        unknown = [p for p in self.passes if p not in P.CHANNELS]
        if unknown:
            raise ValueError(f"unknown pass {unknown[0]!r}; known passes: {', '.join(P.ALL)}")


@dataclass
class RenderResult:
    passes: dict[str, np.ndarray]  # name -> (H,W,C) float32, row 0 at the top
    seconds: dict[str, float] = field(default_factory=dict)  # stage -> wall seconds
    rays: int = 0
    warnings: list[str] = field(default_factory=list)


def render(scene, settings: RenderSettings, progress: Callable[[float, str], bool] | None = None) -> RenderResult:
    cam = scene.camera
    w, h = cam.width, cam.height
    result = RenderResult(passes={})
    for name, count in scene.dropped.items():
        result.warnings.append(f"object {name!r}: {count} degenerate or non-finite triangles skipped")
    t0 = time.perf_counter()
    tracer = Tracer(scene.triangles)
    lights = LightSet(scene)
    if len(lights) == 0:
        result.warnings.append("the scene has no lights: direct and indirect light are black")
    result.seconds["build"] = time.perf_counter() - t0

    want = set(settings.passes) | {P.COMBINED}
    need_direct = bool({P.DIFFUSE_DIRECT, P.COMBINED} & want) and len(lights) > 0
    images = {name: np.zeros((w * h, P.CHANNELS[name]), np.float64) for name in want}
    starts = list(range(0, w * h, settings.block_pixels))
    timing = {"gbuffer": 0.0, "direct": 0.0}
    cancelled = threading.Event()

    def shade_block(number: int):
        """Everything for one block of pixels; blocks run concurrently (numpy and embree release the GIL)."""
        if cancelled.is_set():
            return 0.0, 0.0
        pixels = np.arange(starts[number], min(starts[number] + settings.block_pixels, w * h))
        rng = np.random.default_rng([settings.seed, number])
        t = time.perf_counter()
        gbuf = GBuffer.build(scene, tracer, pixels, settings.samples, rng)
        t_gbuffer = time.perf_counter() - t
        direct = diffuse_direct(gbuf.surface, lights, tracer, settings.light_samples, rng) if need_direct else 0.0
        t_direct = time.perf_counter() - t - t_gbuffer
        images[P.COMBINED][pixels, :3] = gbuf.splat(gbuf.surface.albedo * direct + gbuf.surface.emission)
        images[P.COMBINED][pixels, 3] = gbuf.coverage
        if P.DIFFUSE_DIRECT in want:
            images[P.DIFFUSE_DIRECT][pixels] = gbuf.splat(np.broadcast_to(direct, gbuf.surface.albedo.shape))
        if P.DIFFUSE_COLOR in want:
            images[P.DIFFUSE_COLOR][pixels] = gbuf.splat(gbuf.surface.albedo)
        if P.EMIT in want:
            images[P.EMIT][pixels] = gbuf.splat(gbuf.surface.emission)
        return t_gbuffer, t_direct

    try:
        with ThreadPoolExecutor(tracer.threads) as pool:
            for done, (t_gbuffer, t_direct) in enumerate(pool.map(shade_block, range(len(starts))), start=1):
                timing["gbuffer"] += t_gbuffer
                timing["direct"] += t_direct
                if progress is not None and progress(done / len(starts), "direct light") is False:
                    cancelled.set()
        if cancelled.is_set():
            raise Cancelled()
    finally:
        tracer.close()
    result.seconds.update(timing)  # summed over threads: CPU-seconds of each stage
    result.rays = tracer.rays_traced
    result.passes = {name: images[name].reshape(h, w, -1).astype(np.float32) for name in want
                     if name in settings.passes or name == P.COMBINED}
    P.check(result.passes, "direct lighting")
    return result
