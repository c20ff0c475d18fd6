"""The pipeline of one frame: Scene -> Tracer -> (method places VPLs) -> G-buffer blocks -> direct light and the
gather -> filter -> passes.

A camera with a ``region`` (Blender's render border) renders that rectangle of the frame only, plus the pixels
the filter reads around it; the passes are the region's size. Pixels are processed in blocks, concurrently on all
cores, so memory stays flat at any resolution and sample count; each block draws its random numbers from ``(seed,
block)`` so a render is deterministic (a border's blocks are not the frame's: its pixels are the frame's up to
noise). ``progress(fraction, text)`` is called after each block and may return False to cancel (ESC in Blender),
which raises ``Cancelled``; ``shown(row, rgba)``, if given, receives each band of output rows as soon as all its
pixels are done (their Combined so far: direct light, emission and background; the filtered indirect light is added
to the whole frame at the end), as Cycles shows its finished tiles.
Work a pass does not need is skipped: no lights, no shadow rays and no VPLs; no ``Diffuse Indirect`` requested (or
method "none"), no VPLs; no metallic material, nothing glossy; each data pass (``paths.data_passes``) only when
asked for.

The light passes are, as in Cycles, divided by their colour: the sum over a pixel's samples of light times colour
over the sum of colour (``Diffuse Direct`` / ``Diffuse Indirect`` by ``Diffuse Color``, ``Glossy Direct`` /
``Glossy Indirect`` by ``Glossy Color``), so a pixel half wall and half background or metal holds the wall's light,
not half of it, and ``light pass x colour pass`` is the pixel's share of ``Combined``. The diffuse passes are zero
where no sample has a diffuse colour (pure metal, as in Cycles). Camera rays that miss see the world
(``Environment``), which ``Combined`` shows unless the film is transparent (``core.passes``).
"""
from __future__ import annotations

import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace
from functools import partial
from typing import Callable

import numpy as np

from .core import passes as P
from .core.color import largest
from .core.denoise import DenoiseCancelled, DenoiserMissing, check as check_denoising, denoise, prefilter_for, \
    available as denoiser_available
from .core.memory import trim_heap
from .core.sampling import group_sum, pixel_nets
from .core.tracer import Tracer
from .gather.bilateral import deinterleave
from .gather.summing import GatherSettings, clamp_distance, gather
from .lights import LightSet
from .lights.direct import direct_light
from .materials.cutouts import cutouts
from .materials.microfacet import GlossyLobe
from .methods import METHODS, MethodContext, MethodSettings, place
from .paths.data_passes import Mist, data_passes, first_surfaces_needed
from .paths.gbuffer import GBuffer
from .paths.over_metal import over_metal


def _method(name: str):
    """The method ``name`` of ``methods.METHODS``, None for "none": the one place the render looks a method up."""
    return METHODS.get(name)


class Cancelled(Exception):
    """The user cancelled the render."""


@dataclass
class RenderSettings:
    # camera samples per pixel (G-buffer) and next-event samples per camera sample for direct light: 16 x 2, chosen
    # by ``bench/sample_counts.py`` (bench/README.md, "Camera and light samples"): with the render denoised, the
    # VPLs' indirect light is the picture's error, and 64 x 8 took 1.4-4.1x as long for the same rMAE. vbnl gathers
    # one sample pair per camera sample unless told otherwise, so ``samples`` is the render's one quality knob
    # (bench/README.md, "One knob")
    samples: int = 16
    light_samples: int = 2
    seed: int = 0
    # a sequence's seed of this frame for placing lights (None: ``seed``); the pixels keep ``seed`` in every frame,
    # as Cycles without an animated seed, so their noise does not flicker
    placement_seed: int | None = None
    passes: tuple[str, ...] = (P.COMBINED, P.DIFFUSE_DIRECT, P.DIFFUSE_COLOR, P.EMIT)
    method: str = "vbnl"  # how virtual lights are placed: vbnl, bidir, ir, or none (no indirect light)
    indirect_samples: int = 1  # camera samples per pixel that gather from the VPLs (the filter averages a tile)
    placement: MethodSettings = field(default_factory=MethodSettings)
    gather: GatherSettings = field(default_factory=GatherSettings)
    max_bounces: int | None = None  # None: the scene's bounce limit
    # Film > Transparent: on, the background is 0 in Combined and alpha the coverage (the references' film); off
    # (Blender's default), Combined shows the world where camera rays miss, with alpha 1
    film_transparent: bool = True
    # Combined denoised by OIDN (``core.denoise``) guided by Denoising Albedo / Normal, as Cycles' render denoiser;
    # the light passes stay the estimates (as Cycles'), ``Noisy Image`` holds Combined before
    denoise: bool = False
    # how: Cycles' Denoising Prefilter and Quality (``core.denoise``), its render denoiser's defaults
    denoise_prefilter: str = "ACCURATE"
    denoise_quality: str = "HIGH"
    # the indirect light in Combined denoised apart from the rest, and the two added (``core.denoise``): up to 12 %
    # lower rMAE than Combined denoised whole, as Cycles and a compositor Denoise node on Noisy Image do it
    denoise_indirect_apart: bool = True
    threads: int | None = None  # CPU threads that trace and shade (None: every core); the pixels do not change
    mist: Mist = field(default_factory=Mist)  # the world's mist settings (the Mist pass)
    ao_distance: float = 10.0  # the world's AO distance (the Ambient Occlusion pass)
    block_pixels: int = 4096

    def __post_init__(self):
        if self.samples < 1:
            raise ValueError(f"samples must be at least 1 (got {self.samples})")
        if self.light_samples < 0:
            raise ValueError(f"light samples must not be negative (got {self.light_samples})")
        if self.indirect_samples < 1:
            raise ValueError(f"indirect samples must be at least 1 (got {self.indirect_samples})")
        if self.method != "none" and self.method not in METHODS:
            raise ValueError(f"unknown method {self.method!r}; choose one of none, {', '.join(METHODS)}")
        check_denoising(self.denoise_prefilter, self.denoise_quality)
        if self.placement.vpls < 1:
            raise ValueError(f"the VPL budget must be at least 1 (got {self.placement.vpls})")
        unknown = [p for p in self.passes if p not in P.CHANNELS]
        if unknown:
            raise ValueError(f"unknown pass {unknown[0]!r}; known passes: {', '.join(P.ALL + P.DATA)} and "
                             f"Cryptomatte's {', '.join(P.cryptomatte_passes(kind, 2)[0] for kind in P.CRYPTOMATTE)}"
                             f" to {P.CRYPTOMATTE_PASSES - 1:02d}")


@dataclass
class RenderResult:
    passes: dict[str, np.ndarray]  # name -> (H,W,C) float32, row 0 at the top
    seconds: dict[str, float] = field(default_factory=dict)  # stage -> seconds (blocks: summed over threads)
    rays: int = 0
    threads: int = 1  # CPU threads it ran on
    warnings: list[str] = field(default_factory=list)
    info: dict = field(default_factory=dict)  # what the method reports (paths traced, reverse share, ...)


GLOSSY_SAMPLING = 2.0  # a rough coat's gathering samples against its share of the reflectance (``glossy_samples``)


def _divide(light: np.ndarray, color: np.ndarray) -> np.ndarray:
    """Light over colour per channel, zero where the colour is (Cycles' pass division)."""
    return np.where(color > 0.0, light / np.where(color > 0.0, color, 1.0), 0.0)


def denoise_combined(combined: np.ndarray, albedo: np.ndarray, normal: np.ndarray, threads: int | None, progress,
                     warnings: list[str], what: str, prefilter: str, quality: str, samples: int,
                     indirect: np.ndarray | None = None) -> None:
    """Combined's colour (H,W,4) denoised in place (``core.denoise``, with Cycles' ``prefilter`` and ``quality``)
    with the guides (H,W,3), the means of ``samples`` camera samples per pixel (``core.denoise.prefilter_for``), and
    its ``indirect`` light (H,W,3), if given, apart from the rest (``core.denoise``'s *indirect light apart*); its
    progress told as "denoising" (``progress`` may cancel it: ``Cancelled``); a black picture stays black (OIDN would
    leave traces of 1e-6); without OIDN on this system, one warning in ``warnings`` that names ``what`` is not
    denoised, and the image as it is."""
    if not combined[..., :3].any():
        return
    told = None if progress is None else (lambda done: progress(done, "denoising"))
    if told is not None and told(0.0) is False:
        raise Cancelled()
    apart = indirect if indirect is not None and indirect.any() else None
    try:
        combined[..., :3] = denoise(combined[..., :3], albedo, normal, threads, told, prefilter_for(prefilter, samples),
                                    quality, apart)
    except DenoiseCancelled:
        raise Cancelled() from None
    except DenoiserMissing as err:
        warnings.append(f"{err}: {what} is not denoised")


def glossy_samples(gbuf, surface, lobe, samples: int) -> np.ndarray:
    """(P,) gathering samples of the glossy lobe per pixel, of ``samples`` for the diffuse one: each camera sample on
    a rough coat (``Surface.rough_coat``) asks for the lobe's share of its reflectance (the largest channel of Glossy
    Color against that plus Diffuse Color's) times ``GLOSSY_SAMPLING``, one on another glossy lobe for all; a pixel
    takes the mean of its samples' asks, at least one sample. Which samples gather depends on the G-buffer alone, so
    each pixel's mean over its first ones stays unbiased. A rough clear coat (Glossy Color 0.024 against a Diffuse
    Color of 0.49, seen head-on) then takes 2 samples of 16, not half of the gathering's time; a sharper lobe sees
    more of the room's contrast in each sample (the living room's roughness 0.3-0.5 coats had 4x the spread of
    rMAE over seeds with fewer samples), so it keeps them all."""
    glossy, diffuse = largest(lobe.color), largest(surface.albedo)
    ask = np.minimum(GLOSSY_SAMPLING * glossy / np.maximum(glossy + diffuse, 1e-300), 1.0)
    ask[surface.glossy & ~surface.rough_coat] = 1.0
    mean = np.bincount(gbuf.sample // gbuf.spp, ask, len(gbuf.pixels)) / gbuf.spp
    return np.clip(np.ceil(samples * mean), 1, samples).astype(np.int64)


def pixel_footprint(camera, position: np.ndarray) -> np.ndarray:
    """World-space width of one pixel at the given points (perspective: grows with distance)."""
    size = (camera.window[1] - camera.window[0]) / camera.width
    if camera.orthographic:
        return np.full(len(position), size)
    return np.linalg.norm(position - camera.position, axis=1) * size


def render(scene, settings: RenderSettings, progress: Callable[[float, str], bool] | None = None,
           sequence=None, shown: Callable[[int, np.ndarray], None] | None = None) -> RenderResult:
    """One frame; ``sequence`` (a ``sequence.state.SequenceState``) carries the method's state from the previous
    frame."""
    result = RenderResult(passes={})

    def guard(stage, arrays):  # a bad value fails the render naming the method and the stage that made it
        P.check(arrays, f"method {settings.method!r}, stage {stage!r}")
    for name, count in scene.dropped.items():
        result.warnings.append(f"object {name!r}: {count} degenerate or non-finite triangles skipped")
    t0 = time.perf_counter()
    tracer = Tracer(scene.triangles, threads=settings.threads, cutouts=cutouts(scene), seed=settings.seed) \
        if sequence is None else sequence.begin(scene, threads=settings.threads)
    lights = LightSet(scene)
    if len(lights) == 0:
        result.warnings.append("the scene has no lights: direct and indirect light are black")
    result.seconds["build"] = time.perf_counter() - t0

    want = set(settings.passes) | {P.COMBINED}
    if settings.denoise:
        want |= {P.DENOISING_ALBEDO, P.DENOISING_NORMAL}
    need_glossy = scene.materials.glossy and bool((set(P.GLOSSY) | {P.COMBINED}) & want)
    need_direct = bool({P.DIFFUSE_DIRECT, P.GLOSSY_DIRECT, P.COMBINED} & want) and len(lights) > 0
    bounces = scene.max_bounces if settings.max_bounces is None else settings.max_bounces
    need_background = lights.world is not None and (P.ENVIRONMENT in want or not settings.film_transparent)
    need_indirect = bool({P.DIFFUSE_INDIRECT, P.COMBINED} & want) and len(lights) > 0 and \
        settings.method != "none" and bounces > 0 and len(scene.triangles) > 0
    # the gather's filter evens out the interleaving for a picture left as rendered; before OIDN it costs more than
    # it removes (it blends the light of nearby surfaces, which OIDN's guides keep apart): without it the denoised
    # Combined is 13 to 37 % closer to the references with vbnl, 2 to 9 % with the others (bench/README.md)
    filtering = need_indirect and settings.gather.filter and settings.gather.interleave > 1 and \
        not (settings.denoise and denoiser_available())
    # a render border: its pixels only, and the filter's reach around it, so that it filters them as in the frame
    cam = scene.camera.around(settings.gather.interleave if filtering else 0)
    _, _, w, h = cam.pixel_region
    vpls, d_min, permutation, context = None, 0.0, None, None
    vbnl = settings.placement.vbnl  # its automatic light paths follow the camera samples (``light_paths``)
    placement = replace(settings.placement, vbnl=replace(vbnl, photons=vbnl.light_paths(w * h * settings.samples)))
    method = _method(settings.method)
    sampled = getattr(method, "gather", None)  # the method's own gather, if it samples
    try:
        if need_indirect:
            t0 = time.perf_counter()
            placement_seed = settings.seed if settings.placement_seed is None else settings.placement_seed
            context = MethodContext(scene, tracer, lights, np.random.default_rng([placement_seed, 1 << 20]), bounces,
                                    np.random.default_rng([settings.seed, 1 << 21]),
                                    None if sequence is None else partial(sequence.still, scene))
            if sequence is None:
                vpls, result.info = place(settings.method, context, placement)
            else:
                vpls, result.info = sequence.place(method, context, placement)
            guard("place", {"VPL intensity": vpls.intensity})
            if sampled is None:
                d_min = clamp_distance(scene.surface_area, placement.vpls, settings.gather.clamp)
                permutation = context.rng.permutation(len(vpls))
            result.seconds["place"] = time.perf_counter() - t0
            # light over metal needs no VPL (the lights' own light the metal reflects)
            need_indirect = len(vpls) > 0 or (sampled is None and scene.materials.glossy)

        # the frame's arrays in float32, as the passes are written (a block's sums are made in float64): a
        # 1920 x 1080 frame's pixels take 8 bytes a channel less
        images = {name: np.zeros((w * h, P.CHANNELS[name]), np.float32) for name in want | {P.DIFFUSE_COLOR}}
        indirect = np.zeros((w * h, 3), np.float32)
        # the light of shadow rays through glass: Cycles' Diffuse Indirect (a transmission bounce), by pixel
        glazed = np.zeros((w * h, 3), np.float32) if need_direct and bounces > 0 and scene.materials.glass.any() \
            else None
        # glossy indirect light and its colour summed over the gathering samples; Glossy Color (all samples)
        shine, shine_color, glossy_color = (np.zeros((w * h, 3), np.float32) for _ in range(3))
        # the filter's guides for each lobe (0 diffuse, 1 metallic): the summed position and normal of the pixel's
        # gathering samples of that lobe, and their number (float32: a guide needs no more, and 1920 x 1080 holds
        # 0.24 GB less); none without the filter
        guide_position, guide_normal = (np.zeros((2, w * h, 3), np.float32) if filtering else None for _ in range(2))
        guide_count = np.zeros((2, w * h), np.float32) if filtering else None
        data_wanted = want - set(P.ALL)
        first_surfaces = first_surfaces_needed(data_wanted)
        starts = list(range(0, w * h, settings.block_pixels))
        timing = {"gbuffer": 0.0, "direct": 0.0, "gather": 0.0}
        cancelled = threading.Event()
        if sampled is None:
            gather_spp, repeats = min(settings.indirect_samples, settings.samples), 1
        else:  # the method's sample pairs per pixel, spread over the camera samples
            pairs = method.gather_samples(placement, settings.samples)
            gather_spp = min(pairs, settings.samples)
            repeats = -(-pairs // gather_spp)

        def summed(points, glossy, pixel, rng):
            """The VPLs' light at camera points (white Lambertian, or the metallic lobe ``glossy``): the interleaved
            gather, each point with its pixel's VPL subset, plus the light that comes over metal
            (``paths.over_metal``); a metallic lobe sees VPLs only over its paths."""
            xy = np.stack([pixel % cam.width, pixel // cam.width], 1)  # the frame's tiles, border or not

            def vpl_light(ends, owner):
                return gather(ends, xy[owner], vpls, tracer, settings.gather, d_min, permutation)
            light = over_metal(points, glossy, scene, tracer, lights, rng, vpl_light, bounces)
            return light if glossy is not None else light + vpl_light(points, np.arange(len(points)))

        def shade_block(number: int):
            """Everything for one block of pixels; blocks run concurrently (numpy and embree release the GIL)."""
            if cancelled.is_set():
                return {}
            pixels = np.arange(starts[number], min(starts[number] + settings.block_pixels, w * h))
            rng = np.random.default_rng([settings.seed, number])
            marks = {"start": time.perf_counter()}
            gbuf = GBuffer.build(scene, tracer, cam.frame_pixels(pixels), settings.samples, rng, first_surfaces)
            surf = gbuf.surface
            guard("G-buffer", {P.DIFFUSE_COLOR: surf.albedo, P.EMIT: surf.emission})
            lobe = GlossyLobe.of(surf) if need_glossy else None
            diffuse = (largest(surf.albedo) > 0.0)[:, None]  # the diffuse passes see only diffuse surfaces
            marks["gbuffer"] = time.perf_counter()
            if need_direct:
                # the light samples of a pixel: scrambled nets, dealt to its camera samples in random order
                numbers = []
                for needed in (bool(lights.local), lights.world is not None):  # a net for each kind of light
                    numbers += pixel_nets(gbuf.sample // gbuf.spp, settings.light_samples, rng) if needed else \
                        [None, None]
                through = None if glazed is None else np.zeros_like(surf.albedo)
                direct, glossy = direct_light(surf, lights, tracer, settings.light_samples, rng,
                                              numbers=tuple(numbers), glossy=lobe, through=through)
                guard("direct light", {P.DIFFUSE_DIRECT: direct, P.GLOSSY_DIRECT: glossy})
            else:
                direct, glossy, through = np.zeros_like(surf.albedo), np.zeros_like(surf.albedo), None
            marks["direct"] = time.perf_counter()
            if need_indirect:
                rows = gbuf.first(diffuse[:, 0], gather_spp)  # the gathering samples of each lobe
                sub = surf.take(rows)
                if sampled is None:
                    light = summed(sub, None, gbuf.pixel_of_hit[rows], rng)
                else:
                    many = np.repeat(rows, repeats)
                    light = sampled(sub if repeats == 1 else surf.take(many), vpls, context, placement, rng,
                                    pixel=gbuf.sample[many] // gbuf.spp)
                    light = light.reshape(len(rows), repeats, 3).mean(axis=1)
                guard("gather", {P.DIFFUSE_INDIRECT: light})
                if lobe is not None:
                    shiny = gbuf.first(surf.glossy, glossy_samples(gbuf, surf, lobe, gather_spp))
                    if sampled is None:
                        reflected = summed(surf.take(shiny), lobe.take(shiny), gbuf.pixel_of_hit[shiny], rng)
                    else:
                        many = np.repeat(shiny, repeats)
                        reflected = sampled(surf.take(many), vpls, context, placement, rng,
                                            glossy=lobe.take(many),
                                            pixel=gbuf.sample[many] // gbuf.spp)
                        reflected = reflected.reshape(len(shiny), repeats, 3).mean(axis=1)
                    guard("gather", {P.GLOSSY_INDIRECT: reflected})
                    at = gbuf.sample[shiny] // gbuf.spp
                    shine[pixels] = group_sum(at, gbuf.tinted(reflected, shiny), len(pixels))
                    shine_color[pixels] = group_sum(at, gbuf.tinted(lobe.color[shiny], shiny), len(pixels))
                at = gbuf.sample[rows] // gbuf.spp  # Cycles' pass: the pixel's albedo-weighted mean light
                albedo = gbuf.tinted(sub.albedo, rows)
                indirect[pixels] = _divide(group_sum(at, albedo * light, len(pixels)),
                                           group_sum(at, albedo, len(pixels)))
                for kind, guides in enumerate(((rows, shiny) if lobe is not None else (rows,)) if filtering else ()):
                    local = gbuf.sample[guides] // gbuf.spp
                    guide_position[kind, pixels] = group_sum(local, surf.position[guides], len(pixels))
                    guide_normal[kind, pixels] = group_sum(local, surf.shading_normal[guides], len(pixels))
                    guide_count[kind, pixels] = np.bincount(local, minlength=len(pixels))
            marks["gather"] = time.perf_counter()
            lamps = gbuf.lamps()  # the lights the camera sees
            images[P.COMBINED][pixels, :3] = gbuf.splat(surf.albedo * direct + glossy + surf.emission, True) + lamps
            images[P.COMBINED][pixels, 3] = gbuf.coverage if settings.film_transparent else 1.0
            if need_background:
                background = gbuf.background(lights.world)
                guard("G-buffer", {P.ENVIRONMENT: background})
                if not settings.film_transparent:
                    images[P.COMBINED][pixels, :3] += background
                if P.ENVIRONMENT in want:
                    images[P.ENVIRONMENT][pixels] = background
            images[P.DIFFUSE_COLOR][pixels] = gbuf.splat(surf.albedo, True)
            if P.DIFFUSE_DIRECT in want:
                images[P.DIFFUSE_DIRECT][pixels] = _divide(gbuf.splat(surf.albedo * direct, True),
                                                           images[P.DIFFUSE_COLOR][pixels])
            if through is not None:
                guard("direct light", {P.DIFFUSE_INDIRECT: through})
                glass_light = gbuf.splat(surf.albedo * through, True)
                images[P.COMBINED][pixels, :3] += glass_light
                glazed[pixels] = _divide(glass_light, images[P.DIFFUSE_COLOR][pixels])
            if lobe is not None:
                color = glossy_color[pixels] = gbuf.splat(lobe.color, True)
                for name, image in ((P.GLOSSY_COLOR, color),
                                    (P.GLOSSY_DIRECT, _divide(gbuf.splat(glossy, True), color))):
                    if name in want:
                        images[name][pixels] = image
            emitted = gbuf.splat(surf.emission, True) + lamps if {P.EMIT, P.DENOISING_ALBEDO} & want else None
            if P.EMIT in want:
                images[P.EMIT][pixels] = emitted
            if P.DENOISING_ALBEDO in want:  # Cycles': the colour reflected, plus what is emitted and the world seen
                albedo = images[P.DIFFUSE_COLOR][pixels] + glossy_color[pixels] + emitted
                images[P.DENOISING_ALBEDO][pixels] = albedo + (background if need_background and
                                                               not settings.film_transparent else 0.0)
            if data_wanted:
                for name, image in data_passes(gbuf, scene, data_wanted, tracer, rng, settings.mist,
                                               settings.ao_distance).items():
                    images[name][pixels] = image
            return {"gbuffer": marks["gbuffer"] - marks["start"], "direct": marks["direct"] - marks["gbuffer"],
                    "gather": marks["gather"] - marks["direct"]}

        (x, y, _, _), (bx, by, bw, bh) = cam.pixel_region, scene.camera.pixel_region
        border = (slice(by - y, by - y + bh), slice(bx - x, bx - x + bw))  # the filter's margin off
        ready = 0  # output rows shown so far

        def show(done_pixels: int):
            """Hand ``shown`` the output rows that the blocks done so far complete."""
            nonlocal ready
            rows = min(done_pixels // w - border[0].start, bh)
            if rows > ready:
                band = images[P.COMBINED].reshape(h, w, 4)[border][ready:rows]
                shown(ready, band.astype(np.float32))
                ready = rows

        # one block more than cores: numpy's GIL-held moments of one block overlap another's embree and ufunc work
        # (living room, 2 cores: 1.8 cores busy instead of 1.7)
        with ThreadPoolExecutor(tracer.threads + 1) as pool:
            for done, spent in enumerate(pool.map(shade_block, range(len(starts))), start=1):
                for stage, seconds in spent.items():
                    timing[stage] += seconds
                if shown is not None and not cancelled.is_set():  # blocks end in order: all before this are done
                    show(min(done * settings.block_pixels, w * h))
                if progress is not None and progress(done / len(starts), "rendering") is False:
                    cancelled.set()
        if cancelled.is_set():
            raise Cancelled()
    finally:
        if sequence is None:  # a sequence keeps its BVH for the next frame
            tracer.close()

    lit = None
    if need_indirect:
        t0 = time.perf_counter()
        reflected = _divide(shine, shine_color)  # Glossy Indirect
        if filtering:
            def smooth(image, kind):
                """Each lobe's light filtered among the pixels that have that lobe, guided by its own samples."""
                count = guide_count[kind]
                position = guide_position[kind] / np.maximum(count, 1)[:, None]
                normal = guide_normal[kind] / np.maximum(np.linalg.norm(guide_normal[kind], axis=1, keepdims=True),
                                                         1e-30)  # float32's
                return deinterleave(image.reshape(h, w, 3), position.reshape(h, w, 3), normal.reshape(h, w, 3),
                                    (count > 0).reshape(h, w), pixel_footprint(cam, position).reshape(h, w),
                                    settings.gather.interleave, settings.threads).reshape(-1, 3)
            indirect = smooth(indirect, 0)
            guard("filter", {P.DIFFUSE_INDIRECT: indirect})
            if need_glossy:
                reflected = smooth(reflected, 1)
                guard("filter", {P.GLOSSY_INDIRECT: reflected})
        lit = images[P.DIFFUSE_COLOR] * indirect + glossy_color * reflected  # the indirect light in Combined
        images[P.COMBINED][:, :3] += lit
        # the denoiser's, apart from the rest (``denoise_combined``)
        lit = np.asarray(lit, np.float32) if settings.denoise and settings.denoise_indirect_apart else None
        if P.GLOSSY_INDIRECT in want:
            images[P.GLOSSY_INDIRECT] = reflected
        del reflected
        timing["filter"] = time.perf_counter() - t0
        result.info["vpls"] = len(vpls)
    if P.DIFFUSE_INDIRECT in want:
        images[P.DIFFUSE_INDIRECT] = indirect if glazed is None else indirect + glazed
    result.seconds.update(timing)
    if P.NOISY_IMAGE in want:
        images[P.NOISY_IMAGE] = images[P.COMBINED].copy()
    if settings.denoise:
        # the gathering's frame arrays go before the denoiser's scratch memory comes (1920 x 1080: 0.2 GB)
        del indirect, shine, shine_color, glossy_color, guide_position, guide_normal, guide_count
        trim_heap()
        t0 = time.perf_counter()
        denoise_combined(images[P.COMBINED].reshape(h, w, -1), images[P.DENOISING_ALBEDO].reshape(h, w, 3),
                         images[P.DENOISING_NORMAL].reshape(h, w, 3), settings.threads, progress, result.warnings,
                         "the image", settings.denoise_prefilter, settings.denoise_quality, settings.samples,
                         None if lit is None else lit.reshape(h, w, 3))
        result.seconds["denoise"] = time.perf_counter() - t0
    result.rays, result.threads = tracer.rays_traced, tracer.threads
    result.passes = {name: images[name].reshape(h, w, -1)[border].astype(np.float32) for name in want
                     if name in settings.passes or name == P.COMBINED}
    guard("output", result.passes)
    return result
