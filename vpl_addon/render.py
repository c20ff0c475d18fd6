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
from dataclasses import dataclass, field
from functools import partial
from typing import Callable

import numpy as np

from .core import passes as P
from .core.color import largest, limit_scale
from .core.denoise import DenoiseCancelled, DenoiserMissing, check as check_denoising, denoise, prefilter_for, \
    available as denoiser_available
from .core.memory import render_heap, trim_heap
from .core.sampling import group_sum, pixel_nets
from .core.tracer import Tracer
from .gather.bilateral import bright_apart, deinterleave
from .gather.summing import GatherSettings, clamp_distance, gather
from .lights import LightSet
from .lights.direct import direct_light
from .materials.cutouts import cutouts
from .materials.microfacet import GlossyLobe
from .methods import METHODS, NONE, MethodContext, MethodSettings, place
from .methods.base import Method
from .paths.data_passes import Mist, data_passes, first_surfaces_needed
from .paths.gbuffer import GBuffer
from .paths.over_metal import over_metal


class Cancelled(Exception):
    """The user cancelled the render."""


@dataclass
class RenderSettings:
    # camera samples per pixel (G-buffer) and next-event samples per camera sample for direct light: 16 x 2, chosen
    # by ``bench/sample_counts.py``: with the render denoised, the VPLs' indirect light is the picture's error, and
    # 64 x 8 takes 1.4-4.1x as long for the same rMAE. vbnl gathers one sample pair per camera sample unless told
    # otherwise, so ``samples`` is the render's one quality knob (``bench/sample_counts.py --pairs``)
    samples: int = 16
    light_samples: int = 2
    seed: int = 0
    # a sequence's seed of this frame for placing lights (None: ``seed``); the pixels keep ``seed`` in every frame,
    # as Cycles without an animated seed, so their noise does not flicker
    placement_seed: int | None = None
    passes: tuple[str, ...] = (P.COMBINED, P.DIFFUSE_DIRECT, P.DIFFUSE_COLOR, P.EMIT)
    method: str = "vbnl"  # how virtual lights are placed: a name of ``methods.METHODS``, or "none" (no indirect light)
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
        if self.method != NONE and self.method not in METHODS:
            raise ValueError(f"unknown method {self.method!r}; choose one of {NONE}, {', '.join(METHODS)}")
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
    # stage -> the part of those seconds its threads waited on embree (place: summed over the threads that traced)
    embree_seconds: dict[str, float] = field(default_factory=dict)
    rays: int = 0
    threads: int = 1  # CPU threads it ran on
    warnings: list[str] = field(default_factory=list)
    info: dict = field(default_factory=dict)  # what the method reports (paths traced, reverse share, ...)


GLOSSY_SAMPLING = 2.0  # a rough coat's gathering samples against its share of the reflectance (``glossy_samples``)



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


@dataclass
class _Plan:
    """What a frame needs, decided from the settings, the scene and its lights before a ray is traced: the passes
    to make, the work they ask for (each ``need_*`` that is false skips its work), the camera of the pixels
    rendered, and how the method's light is gathered."""
    want: set[str]  # the passes asked for, Combined, and the denoiser's guides when it denoises
    need_direct: bool
    need_indirect: bool  # narrowed by ``_place`` to whether anything is left to gather
    need_glossy: bool
    need_background: bool
    filtering: bool  # the gather's filter runs on the light the points' own gathering finds (``_filter``)
    bounces: int
    cam: object  # the camera of the pixels rendered: a border's, plus the filter's reach around it
    w: int
    h: int
    border: tuple[slice, slice]  # the output's rows and columns among ``cam``'s pixels (the filter's margin off)
    placement: MethodSettings  # the method's settings, vbnl's light paths following the camera samples
    method: Method | None  # the method (``methods.base.Method``); None for "none"
    sampled: Callable | None  # the method's own gather, if it samples its lights; None: its VPLs are summed
    gather_spp: int  # gathering samples per pixel, of its camera samples
    repeats: int  # the sampled gather's sample pairs per gathering sample
    data_wanted: set[str]  # the data passes (``paths.data_passes``) among ``want``
    first_surfaces: bool  # whether they see each sample's first surface (``first_surfaces_needed``)


@dataclass
class _Placed:
    """The method's lights placed for the frame, and what gathering them reads: the method's ``context`` (its own
    gather's) or, for summed VPLs, the gather's clamping distance and order of the lights (``gather.summing``)."""
    vpls: object = None  # VirtualLights
    context: MethodContext | None = None
    d_min: float = 0.0
    permutation: np.ndarray | None = None


@dataclass
class _Frame:
    """The frame's arrays, one row per pixel of the plan's camera, into which each block writes its pixels' rows.
    They are float32, as the passes are written (a block's sums are made in float64): a 1920 x 1080 frame's pixels
    take 8 bytes a channel less."""
    images: dict[str, np.ndarray]  # pass -> (W*H, channels)
    indirect: np.ndarray  # Diffuse Indirect: the pixel's albedo-weighted mean of the gathered light
    # its part that the points' own gathering finds (the filter's input, ``_filter``); None without the filter
    near: np.ndarray | None
    # the light of shadow rays through glass: Cycles' Diffuse Indirect (a transmission bounce), by pixel; None
    # without glass, direct light or bounces
    glazed: np.ndarray | None
    # glossy indirect light and its colour summed over the gathering samples; Glossy Color (all samples)
    shine: np.ndarray
    shine_color: np.ndarray
    glossy_color: np.ndarray
    # the filter's guides: the summed position and normal of the pixel's diffuse gathering samples, and their
    # number (float32: a guide needs no more, and 1920 x 1080 holds 0.12 GB less); None without the filter
    guide_position: np.ndarray | None
    guide_normal: np.ndarray | None
    guide_count: np.ndarray | None

    def drop_gathering(self) -> None:
        """The gathering's arrays let go (a pass keeps the one it holds), so that the denoiser's scratch memory
        finds their room."""
        self.indirect = self.near = self.shine = self.shine_color = self.glossy_color = None
        self.guide_position = self.guide_normal = self.guide_count = None


@dataclass
class _Job:
    """One frame under way: what its stages after the placement read (the scene, its settings, tracer and lights,
    the plan and the placed lights) and the frame's arrays they write."""
    scene: object
    settings: RenderSettings
    tracer: Tracer
    lights: LightSet
    plan: _Plan
    placed: _Placed
    frame: _Frame


@render_heap()
def render(scene, settings: RenderSettings, progress: Callable[[float, str], bool] | None = None,
           sequence=None, shown: Callable[[int, np.ndarray], None] | None = None) -> RenderResult:
    """One frame; ``sequence`` (a ``sequence.state.SequenceState``) carries the method's state from the previous
    frame. Its stages are named calls, as in pbrt-v4's and Mitsuba 3's integrators: build the tracer and lights,
    plan what the frame needs, place the method's lights, make the frame's buffers, shade its blocks (G-buffer,
    direct light, the gather, the passes), add the filtered indirect light, denoise, collect the passes. The C
    library keeps the heap the render frees until it ends (``core.memory.render_heap``)."""
    result = RenderResult(passes={})
    tracer, lights = _build(scene, settings, sequence, result)
    try:
        plan = _plan(scene, settings, lights)
        placed = _place(scene, settings, plan, tracer, lights, sequence, result)
        job = _Job(scene, settings, tracer, lights, plan, placed, _frame(scene, plan))
        timing = _shade(job, progress, shown, result)
    finally:
        if sequence is None:  # a sequence keeps its BVH for the next frame
            tracer.close()
    images, lit = job.frame.images, None
    if plan.need_indirect:
        lit = _filter(job, timing)
        result.info["vpls"] = len(placed.vpls)
    if P.DIFFUSE_INDIRECT in plan.want:
        glazed = job.frame.glazed
        images[P.DIFFUSE_INDIRECT] = job.frame.indirect if glazed is None else job.frame.indirect + glazed
    result.seconds.update(timing)
    if P.NOISY_IMAGE in plan.want:
        images[P.NOISY_IMAGE] = images[P.COMBINED].copy()
    if settings.denoise:
        _denoise(job, lit, progress, result)
    return _collect(job, result)


def _guard(settings: RenderSettings, stage: str, arrays: dict[str, np.ndarray]) -> None:
    """A bad value fails the render naming the method and the stage that made it (``core.passes.check``)."""
    P.check(arrays, f"method {settings.method!r}, stage {stage!r}")


def _build(scene, settings: RenderSettings, sequence, result: RenderResult) -> tuple[Tracer, LightSet]:
    """The frame's tracer (a sequence's own, which keeps its BVH between frames) and lights, in ``result`` the
    seconds as "build" and warnings of skipped triangles and of a scene without lights."""
    for name, count in scene.dropped.items():
        result.warnings.append(f"object {name!r}: {count} degenerate or non-finite triangles skipped")
    t0 = time.perf_counter()
    tracer = Tracer(scene.triangles, threads=settings.threads, cutouts=cutouts(scene), seed=settings.seed) \
        if sequence is None else sequence.begin(scene, threads=settings.threads)
    lights = LightSet(scene)
    if len(lights) == 0:
        result.warnings.append("the scene has no lights: direct and indirect light are black")
    result.seconds["build"] = time.perf_counter() - t0
    return tracer, lights


def _plan(scene, settings: RenderSettings, lights: LightSet) -> _Plan:
    """What the frame needs (``_Plan``) to make ``settings``' passes of ``scene`` lit by ``lights``."""
    want = set(settings.passes) | {P.COMBINED}
    if settings.denoise:
        want |= {P.DENOISING_ALBEDO, P.DENOISING_NORMAL}
    need_glossy = scene.materials.glossy and bool((set(P.GLOSSY) | {P.COMBINED}) & want)
    need_direct = bool({P.DIFFUSE_DIRECT, P.GLOSSY_DIRECT, P.COMBINED} & want) and len(lights) > 0
    bounces = scene.max_bounces if settings.max_bounces is None else settings.max_bounces
    need_background = lights.world is not None and (P.ENVIRONMENT in want or not settings.film_transparent)
    need_indirect = bool({P.DIFFUSE_INDIRECT, P.COMBINED} & want) and len(lights) > 0 and \
        settings.method != NONE and bounces > 0 and len(scene.triangles) > 0
    # the gather's filter evens out the interleaving (and a sampled gather's noise) for a picture left as rendered;
    # before OIDN it costs more than it removes (it blends the light of nearby surfaces, which OIDN's guides keep
    # apart): without it the denoised Combined is 13 to 37 % closer to the references with vbnl, 2 to 9 % with the
    # others
    filtering = need_indirect and settings.gather.filter and settings.gather.interleave > 1 and \
        not (settings.denoise and denoiser_available())
    # a render border: its pixels only, and the filter's reach around it, so that it filters them as in the frame
    cam = scene.camera.around(settings.gather.interleave if filtering else 0)
    (x, y, w, h), (bx, by, bw, bh) = cam.pixel_region, scene.camera.pixel_region
    method = None if settings.method == NONE else METHODS[settings.method]
    placement = settings.placement if method is None or method.frame_settings is None else \
        method.frame_settings(settings.placement, w * h * settings.samples)
    sampled = None if method is None else method.gather  # the method's own gather, if it samples
    if sampled is None:
        gather_spp, repeats = min(settings.indirect_samples, settings.samples), 1
    else:  # the method's sample pairs per pixel, spread over the camera samples
        pairs = method.gather_samples(placement, settings.samples)
        gather_spp = min(pairs, settings.samples)
        repeats = -(-pairs // gather_spp)
    data_wanted = want - set(P.ALL)
    return _Plan(want, need_direct, need_indirect, need_glossy, need_background, filtering, bounces, cam, w, h,
                 (slice(by - y, by - y + bh), slice(bx - x, bx - x + bw)), placement, method, sampled, gather_spp,
                 repeats, data_wanted, first_surfaces_needed(data_wanted))


def _place(scene, settings: RenderSettings, plan: _Plan, tracer, lights: LightSet, sequence,
           result: RenderResult) -> _Placed:
    """The method's lights for the frame (none unless it needs indirect light), checked at "place"; a sequence's
    method carries its state from frame to frame (``SequenceState.place``). In ``result`` the method's info and
    the seconds as "place". Narrows ``plan.need_indirect`` to whether anything is left to gather: light over metal
    needs no VPL (the lights' own light the metal reflects)."""
    if not plan.need_indirect:
        return _Placed()
    t0, waited = time.perf_counter(), tracer.embree_seconds
    placement_seed = settings.seed if settings.placement_seed is None else settings.placement_seed
    context = MethodContext(scene, tracer, lights, np.random.default_rng([placement_seed, 1 << 20]), plan.bounces,
                            np.random.default_rng([settings.seed, 1 << 21]),
                            None if sequence is None else partial(sequence.still, scene))
    if sequence is None:
        vpls, result.info = place(settings.method, context, plan.placement)
    else:
        vpls, result.info = sequence.place(plan.method, context, plan.placement)
    _guard(settings, "place", {"VPL intensity": vpls.intensity})
    placed = _Placed(vpls, context)
    if plan.sampled is None:
        placed.d_min = clamp_distance(scene.surface_area, plan.placement.vpls, settings.gather.clamp)
        placed.permutation = context.rng.permutation(len(vpls))
    result.seconds["place"] = time.perf_counter() - t0
    result.embree_seconds["place"] = tracer.embree_seconds - waited
    plan.need_indirect = len(vpls) > 0 or (plan.sampled is None and scene.materials.glossy)
    return placed


def _frame(scene, plan: _Plan) -> _Frame:
    """The frame's arrays (``_Frame``) at zero: a pass each of ``plan.want`` and Diffuse Color, and the
    gathering's light, colour and guides (the light through glass only for glass lit directly, the filter's input
    and guides only for the filter)."""
    pixels = plan.w * plan.h
    images = {name: np.zeros((pixels, P.CHANNELS[name]), np.float32) for name in plan.want | {P.DIFFUSE_COLOR}}
    indirect = np.zeros((pixels, 3), np.float32)
    glazed = np.zeros((pixels, 3), np.float32) \
        if plan.need_direct and plan.bounces > 0 and scene.materials.glass.any() else None
    shine, shine_color, glossy_color = (np.zeros((pixels, 3), np.float32) for _ in range(3))
    near, guide_position, guide_normal = (np.zeros((pixels, 3), np.float32) if plan.filtering else None
                                          for _ in range(3))
    guide_count = np.zeros(pixels, np.float32) if plan.filtering else None
    return _Frame(images, indirect, near, glazed, shine, shine_color, glossy_color, guide_position,
                  guide_normal, guide_count)


def _shade(job: _Job, progress, shown, result: RenderResult) -> dict[str, float]:
    """The frame's blocks of pixels shaded concurrently (``_shade_block``); after each, ``shown`` handed the output
    rows it completes and ``progress`` told, which cancels the render by returning False (``Cancelled``). Returns
    each block stage's seconds summed over the blocks; the part of them spent waiting on embree goes to
    ``result.embree_seconds``."""
    plan, block_pixels = job.plan, job.settings.block_pixels
    blocks = len(range(0, plan.w * plan.h, block_pixels))
    timing = {"gbuffer": 0.0, "direct": 0.0, "gather": 0.0}
    waited = result.embree_seconds
    waited.update(dict.fromkeys(timing, 0.0))
    cancelled = threading.Event()
    ready = 0  # output rows shown so far
    # one block more than cores: numpy's GIL-held moments of one block overlap another's embree and ufunc work
    # (living room, 2 cores: 1.8 cores busy instead of 1.7)
    with ThreadPoolExecutor(job.tracer.threads + 1) as pool:
        for done, spent in enumerate(pool.map(partial(_shade_block, job, cancelled), range(blocks)), start=1):
            for stage, (seconds, embree) in spent.items():
                timing[stage] += seconds
                waited[stage] += embree
            if shown is not None and not cancelled.is_set():  # blocks end in order: all before this are done
                ready = _show(job, shown, ready, min(done * block_pixels, plan.w * plan.h))
            if progress is not None and progress(done / blocks, "rendering") is False:
                cancelled.set()
    if cancelled.is_set():
        raise Cancelled()
    return timing


def _show(job: _Job, shown, ready: int, done_pixels: int) -> int:
    """Hand ``shown`` the output rows after the first ``ready`` that the blocks done so far complete (their first
    ``done_pixels`` pixels); returns the rows shown in all."""
    plan, (rows_out, _) = job.plan, job.plan.border
    rows = min(done_pixels // plan.w - rows_out.start, rows_out.stop - rows_out.start)
    if rows <= ready:
        return ready
    band = job.frame.images[P.COMBINED].reshape(plan.h, plan.w, 4)[plan.border][ready:rows]
    shown(ready, band.astype(np.float32))
    return rows


def _shade_block(job: _Job, cancelled: threading.Event, number: int) -> dict[str, tuple[float, float]]:
    """Everything for block ``number`` of the frame's pixels, its random numbers drawn from ``(seed, number)``: the
    G-buffer, direct light, the gather and the passes. Blocks run concurrently (numpy and embree release the GIL).
    Returns the seconds of each stage and the part of them it waited on embree; nothing once the render is
    ``cancelled``."""
    if cancelled.is_set():
        return {}
    settings, plan = job.settings, job.plan
    start = number * settings.block_pixels
    pixels = np.arange(start, min(start + settings.block_pixels, plan.w * plan.h))
    rng = np.random.default_rng([settings.seed, number])
    tracer = job.tracer
    marks = {"start": (time.perf_counter(), tracer.waited())}
    gbuf = GBuffer.build(job.scene, job.tracer, plan.cam.frame_pixels(pixels), settings.samples, rng,
                         plan.first_surfaces)
    _guard(settings, "G-buffer", {P.DIFFUSE_COLOR: gbuf.surface.albedo, P.EMIT: gbuf.surface.emission})
    lobe = GlossyLobe.of(gbuf.surface) if plan.need_glossy else None
    marks["gbuffer"] = (time.perf_counter(), tracer.waited())
    direct, glossy, through = _direct(job, gbuf, lobe, rng)
    marks["direct"] = (time.perf_counter(), tracer.waited())
    if plan.need_indirect:
        _indirect(job, gbuf, lobe, rng, pixels)
    marks["gather"] = (time.perf_counter(), tracer.waited())
    _accumulate(job, gbuf, lobe, rng, pixels, direct, glossy, through)
    stages = list(marks)
    return {b: (marks[b][0] - marks[a][0], marks[b][1] - marks[a][1]) for a, b in zip(stages, stages[1:])}


def _direct(job: _Job, gbuf: GBuffer, lobe: GlossyLobe | None, rng: np.random.Generator):
    """The direct light (K,3) at the block's hits, reflected diffusely and by ``lobe`` (checked at "direct light"),
    and the light (K,3) of their shadow rays through glass (None unless the frame keeps it); zeros without direct
    light. A pixel's light samples are scrambled nets, dealt to its camera samples in random order."""
    surf, settings, lights = gbuf.surface, job.settings, job.lights
    if not job.plan.need_direct:
        return np.zeros_like(surf.albedo), np.zeros_like(surf.albedo), None
    numbers = []
    for needed in (bool(lights.local), lights.world is not None):  # a net for each kind of light
        numbers += pixel_nets(gbuf.sample // gbuf.spp, settings.light_samples, rng) if needed else [None, None]
    through = None if job.frame.glazed is None else np.zeros_like(surf.albedo)
    direct, glossy = direct_light(surf, lights, job.tracer, settings.light_samples, rng, numbers=tuple(numbers),
                                  glossy=lobe, through=through)
    _guard(settings, "direct light", {P.DIFFUSE_DIRECT: direct, P.GLOSSY_DIRECT: glossy})
    return direct, glossy, through


def _indirect(job: _Job, gbuf: GBuffer, lobe: GlossyLobe | None, rng: np.random.Generator,
              pixels: np.ndarray) -> None:
    """The block's indirect light into the frame: the gathering samples of each lobe (a pixel's first diffuse
    ones; ``glossy_samples`` of its glossy ones) gathered (``_gather_light``) and checked at "gather"; Diffuse
    Indirect as Cycles' pass, the pixel's albedo-weighted mean light, the part the filter takes apart when it
    filters; the glossy light and its colour summed by pixel; the filter's guides."""
    frame, plan, surf, count = job.frame, job.plan, gbuf.surface, len(pixels)
    # the gathering samples of each lobe; the diffuse passes see only diffuse surfaces
    rows = gbuf.first(largest(surf.albedo) > 0.0, plan.gather_spp)
    near, further = _gather_light(job, gbuf, rng, rows)
    _guard(job.settings, "gather", {P.DIFFUSE_INDIRECT: near, P.DIFFUSE_INDIRECT + " (continued paths)": further})
    if lobe is not None:
        shiny = gbuf.first(surf.glossy, glossy_samples(gbuf, surf, lobe, plan.gather_spp))
        reflected = sum(_gather_light(job, gbuf, rng, shiny, lobe))
        _guard(job.settings, "gather", {P.GLOSSY_INDIRECT: reflected})
        at = gbuf.sample[shiny] // gbuf.spp
        frame.shine[pixels] = group_sum(at, gbuf.tinted(reflected, shiny), count)
        frame.shine_color[pixels] = group_sum(at, gbuf.tinted(lobe.color[shiny], shiny), count)
    at = gbuf.sample[rows] // gbuf.spp  # Cycles' pass: the pixel's albedo-weighted mean light
    albedo = gbuf.tinted(surf.albedo[rows], rows)
    weight = group_sum(at, albedo, count)
    if plan.filtering:
        frame.near[pixels] = P.divide(group_sum(at, albedo * near, count), weight)
        _guide(frame, gbuf, pixels, rows)
    else:
        further = further + near
    frame.indirect[pixels] = P.divide(group_sum(at, albedo * further, count), weight)


def _gather_light(job: _Job, gbuf: GBuffer, rng: np.random.Generator, rows: np.ndarray,
                  lobe: GlossyLobe | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(R,3) the indirect light at the G-buffer's hits ``rows``, reflected by a white Lambertian surface or, given
    the block's ``lobe``, by its metallic lobe there, in two parts (the method contract's): what the hits' own
    gathering finds and what the paths continued past them bring. The VPLs summed (``_summed``) or, for a method
    that samples its own lights, the mean of its gather's ``repeats`` sample pairs at each hit."""
    surf, plan, placed = gbuf.surface, job.plan, job.placed
    if plan.sampled is None:
        glossy = None if lobe is None else lobe.take(rows)
        return _clamped(job, *_summed(job, surf.take(rows), glossy, gbuf.pixel_of_hit[rows], rng))
    many = np.repeat(rows, plan.repeats)
    parts = _clamped(job, *plan.sampled(surf.take(many), placed.vpls, placed.context, plan.placement, rng,
                                        glossy=None if lobe is None else lobe.take(many),
                                        pixel=gbuf.sample[many] // gbuf.spp))
    near, further = (part.reshape(len(rows), plan.repeats, 3).mean(axis=1) for part in parts)
    return near, further


def _clamped(job: _Job, near: np.ndarray, further: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A gathering sample's two parts of light scaled alike so that their sum is at most Clamp Indirect
    (``GatherSettings.clamp_indirect``) in its brightest channel; as they are when it is off."""
    limit = job.settings.gather.clamp_indirect
    if limit <= 0.0:
        return near, further
    scale = limit_scale(near + further, limit)[:, None]
    return near * scale, further * scale


def _summed(job: _Job, points, glossy: GlossyLobe | None, pixel: np.ndarray,
            rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """The VPLs' light at camera points (white Lambertian, or the metallic lobe ``glossy``): the interleaved gather,
    each point with its pixel's VPL subset, and the light that comes over metal (``paths.over_metal``); a metallic
    lobe sees VPLs only over its paths. The ends of paths over metal draw a random subset each: their light is the
    path's noise, with no tile pattern to filter."""
    placed, width, settings = job.placed, job.plan.cam.width, job.settings.gather

    def vpl_light(ends, xy=None):
        xy = rng.integers(0, max(1, settings.interleave), (len(ends), 2)) if xy is None else xy
        return gather(ends, xy, placed.vpls, job.tracer, settings, placed.d_min, placed.permutation)
    further = over_metal(points, glossy, job.scene, job.tracer, job.lights, rng, vpl_light, job.plan.bounces)
    if glossy is not None:
        return np.zeros_like(further), further
    return vpl_light(points, np.stack([pixel % width, pixel // width], 1)), further  # the frame's tiles


def _guide(frame: _Frame, gbuf: GBuffer, pixels: np.ndarray, rows: np.ndarray) -> None:
    """The filter's guides of the block's pixels from their diffuse gathering samples ``rows``: their summed
    position and normal, and their number."""
    surf, local = gbuf.surface, gbuf.sample[rows] // gbuf.spp
    frame.guide_position[pixels] = group_sum(local, surf.position[rows], len(pixels))
    frame.guide_normal[pixels] = group_sum(local, surf.shading_normal[rows], len(pixels))
    frame.guide_count[pixels] = np.bincount(local, minlength=len(pixels))


def _accumulate(job: _Job, gbuf: GBuffer, lobe: GlossyLobe | None, rng: np.random.Generator, pixels: np.ndarray,
                direct: np.ndarray, glossy: np.ndarray, through: np.ndarray | None) -> None:
    """The block's camera samples into the frame's passes: Combined (direct light, emission and the lights seen,
    and the world on an opaque film; the indirect light comes at the end, ``_filter``), Environment, the colour
    passes, the direct light over its colour, the light through glass, Emit, Denoising Albedo, the data passes."""
    settings, plan, frame, surf = job.settings, job.plan, job.frame, gbuf.surface
    want, images = plan.want, frame.images
    lamps = gbuf.lamps()  # the lights the camera sees
    images[P.COMBINED][pixels, :3] = gbuf.splat(surf.albedo * direct + glossy + surf.emission, True) + lamps
    images[P.COMBINED][pixels, 3] = gbuf.coverage if settings.film_transparent else 1.0
    if plan.need_background:
        background = gbuf.background(job.lights.world)
        _guard(settings, "G-buffer", {P.ENVIRONMENT: background})
        if not settings.film_transparent:
            images[P.COMBINED][pixels, :3] += background
        if P.ENVIRONMENT in want:
            images[P.ENVIRONMENT][pixels] = background
    images[P.DIFFUSE_COLOR][pixels] = gbuf.splat(surf.albedo, True)
    if P.DIFFUSE_DIRECT in want:
        images[P.DIFFUSE_DIRECT][pixels] = P.divide(gbuf.splat(surf.albedo * direct, True),
                                                   images[P.DIFFUSE_COLOR][pixels])
    if through is not None:
        _guard(settings, "direct light", {P.DIFFUSE_INDIRECT: through})
        glass_light = gbuf.splat(surf.albedo * through, True)
        images[P.COMBINED][pixels, :3] += glass_light
        frame.glazed[pixels] = P.divide(glass_light, images[P.DIFFUSE_COLOR][pixels])
    if lobe is not None:
        color = frame.glossy_color[pixels] = gbuf.splat(lobe.color, True)
        for name, image in ((P.GLOSSY_COLOR, color), (P.GLOSSY_DIRECT, P.divide(gbuf.splat(glossy, True), color))):
            if name in want:
                images[name][pixels] = image
    emitted = gbuf.splat(surf.emission, True) + lamps if {P.EMIT, P.DENOISING_ALBEDO} & want else None
    if P.EMIT in want:
        images[P.EMIT][pixels] = emitted
    if P.DENOISING_ALBEDO in want:  # Cycles': the colour reflected, plus what is emitted and the world seen
        albedo = images[P.DIFFUSE_COLOR][pixels] + frame.glossy_color[pixels] + emitted
        images[P.DENOISING_ALBEDO][pixels] = albedo + (background if plan.need_background and
                                                       not settings.film_transparent else 0.0)
    if plan.data_wanted:
        for name, image in data_passes(gbuf, job.scene, plan.data_wanted, job.tracer, rng, settings.mist,
                                       settings.ao_distance).items():
            images[name][pixels] = image


def _filter(job: _Job, timing: dict[str, float]) -> np.ndarray | None:
    """The gathered light added to Combined: Glossy Indirect the shine over its colour, the near part of Diffuse
    Indirect filtered into it when the plan filters (``_smooth``, checked at "filter"), the seconds in
    ``timing`` as "filter". Returns the indirect light in Combined (W*H,3) when the denoiser takes it apart
    (``denoise_combined``), else None."""
    settings, plan, frame = job.settings, job.plan, job.frame
    t0 = time.perf_counter()
    reflected = P.divide(frame.shine, frame.shine_color)  # Glossy Indirect
    if plan.filtering:  # the rare bright samples of either part stay as sampled (``bright_apart``)
        tile, shape = settings.gather.interleave, (plan.h, plan.w, 3)
        spread, kept = bright_apart(frame.indirect.reshape(shape), tile)
        near, alone = bright_apart(frame.near.reshape(shape), tile, interleaved=True)
        frame.indirect = (kept + alone).reshape(-1, 3) + _smooth(job, (near + spread).reshape(-1, 3))
        _guard(settings, "filter", {P.DIFFUSE_INDIRECT: frame.indirect})
    lit = frame.images[P.DIFFUSE_COLOR] * frame.indirect + frame.glossy_color * reflected  # the light in Combined
    frame.images[P.COMBINED][:, :3] += lit
    lit = np.asarray(lit, np.float32) if settings.denoise and settings.denoise_indirect_apart else None
    if P.GLOSSY_INDIRECT in plan.want:
        frame.images[P.GLOSSY_INDIRECT] = reflected
    timing["filter"] = time.perf_counter() - t0
    return lit


def _smooth(job: _Job, image: np.ndarray) -> np.ndarray:
    """The near light (W*H,3) filtered among the pixels that gathered it, guided by their diffuse samples
    (``gather.bilateral.deinterleave``)."""
    frame, plan, h, w = job.frame, job.plan, job.plan.h, job.plan.w
    count = frame.guide_count
    position = frame.guide_position / np.maximum(count, 1)[:, None]
    normal = frame.guide_normal / np.maximum(np.linalg.norm(frame.guide_normal, axis=1, keepdims=True),
                                             1e-30)  # float32's
    return deinterleave(image.reshape(h, w, 3), position.reshape(h, w, 3), normal.reshape(h, w, 3),
                        (count > 0).reshape(h, w), pixel_footprint(plan.cam, position).reshape(h, w),
                        job.settings.gather.interleave, job.settings.threads).reshape(-1, 3)


def _denoise(job: _Job, lit: np.ndarray | None, progress, result: RenderResult) -> None:
    """Combined denoised in place (``denoise_combined``) with the indirect light ``lit`` apart, if given; the
    gathering's frame arrays go first, before the denoiser's scratch memory comes (1920 x 1080: 0.2 GB). The
    seconds in ``result`` as "denoise", a missing denoiser among its warnings."""
    settings, plan, images = job.settings, job.plan, job.frame.images
    job.frame.drop_gathering()
    trim_heap()
    t0 = time.perf_counter()
    h, w = plan.h, plan.w
    denoise_combined(images[P.COMBINED].reshape(h, w, -1), images[P.DENOISING_ALBEDO].reshape(h, w, 3),
                     images[P.DENOISING_NORMAL].reshape(h, w, 3), settings.threads, progress, result.warnings,
                     "the image", settings.denoise_prefilter, settings.denoise_quality, settings.samples,
                     None if lit is None else lit.reshape(h, w, 3))
    result.seconds["denoise"] = time.perf_counter() - t0


def _collect(job: _Job, result: RenderResult) -> RenderResult:
    """``result`` with the passes asked for and Combined, float32 and cut to the border (checked at "output"), and
    the rays traced and threads used."""
    plan = job.plan
    result.rays, result.threads = job.tracer.rays_traced, job.tracer.threads
    result.passes = {name: job.frame.images[name].reshape(plan.h, plan.w, -1)[plan.border].astype(np.float32)
                     for name in plan.want if name in job.settings.passes or name == P.COMBINED}
    _guard(job.settings, "output", result.passes)
    return result
