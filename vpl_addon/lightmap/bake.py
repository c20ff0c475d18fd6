"""Lightmaps of several objects from one set of virtual lights: each object's texel G-buffer (``texels``), its
samples pushed out of other geometry (``unocclude``), the direct light and the VPLs' light gathered at them, the
passes of Cycles' bake types, OIDN's lightmap filter, the islands dilated, the seams stitched.

The VPLs are placed once for all the objects baked (``methods.place``), so every texel of every object is lit by
the same set: the cost of placing them is paid once however many objects there are, where Cycles' bake traces its
paths object by object. A method that places by the view (bidir's camera points, smc's) places by the baked texels
in place of the pixels (``view``); vbnl samples its lights per camera sample (its own gather) and is not offered.

The passes are those of Cycles' bake types (``BAKE_PASSES``), as Cycles divides its light by its colour when the
Color toggle is off: ``Diffuse Indirect`` (type DIFFUSE, pass filter INDIRECT), ``Diffuse Direct`` (DIRECT),
``Diffuse`` (both), ``Diffuse Color`` (COLOR alone) and ``Combined`` (the diffuse light times its colour, plus
emission; glossy light is not baked). A texel's light is the albedo-weighted mean over its samples, as a render's
pixel's (``render``); alpha is the texel's coverage.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..core import passes as P
from ..core.denoise import DenoiserMissing
from ..core.memory import render_heap
from ..core.sampling import group_sum
from ..core.tracer import Tracer
from ..gather.summing import GatherSettings, clamp_distance, gather
from ..lights import LightSet
from ..lights.direct import direct_light
from ..materials.cutouts import cutouts
from ..methods import METHODS, MethodContext, MethodSettings, place
from .denoising import denoise_maps
from .dilation import dilate
from .seams import seam_pairs, stitch
from .sizing import density_size
from .texels import Texels, bake_uvs, rasterise
from .unocclude import unocclude
from .view import TexelView

DIFFUSE = "Diffuse"
BAKE_PASSES = (P.DIFFUSE_INDIRECT, P.DIFFUSE_DIRECT, DIFFUSE, P.DIFFUSE_COLOR, P.COMBINED)
MAX_SIZE = 16384
MIN_MARGIN = 2  # the ring every island grows at least, whatever margin is asked for


class Cancelled(Exception):
    """``progress`` returned False: the bake stopped."""


@dataclass
class LightmapSettings:
    size: int = 128  # texels per side of each object's map
    # texels a metre of surface (``sizing``): each object's size from its area, in place of ``size``; None: ``size``
    texel_density: float | None = None
    samples: int = 4  # sample points per texel (direct light, coverage); a square number
    light_samples: int = 2  # shadow rays per sample for the direct light
    indirect_samples: int = 1  # samples per texel that gather the VPLs' light
    bake_pass: str = P.DIFFUSE_INDIRECT  # one of ``BAKE_PASSES``
    method: str = "ir"
    placement: MethodSettings = field(default_factory=lambda: MethodSettings(vpls=16384))
    # VPLs each texel gathers, a random subset of them all (``_indirect``); and the clamp of their geometry term in
    # mean VPL spacings (``gather.summing``)
    texel_vpls: int = 256
    clamp: float = GatherSettings.clamp
    margin: int = 16  # texels the islands grow by (Cycles' bake margin's default)
    denoise: bool = True  # OIDN's lightmap filter (``core.denoise.denoise_lightmap``)
    stitch: bool = True  # one value on both sides of each UV seam (``seams``)
    seed: int = 0
    threads: int | None = None
    max_bounces: int | None = None  # None: the scene's

    def __post_init__(self):
        if not 0 < self.size <= MAX_SIZE:
            raise ValueError(f"size must be between 1 and {MAX_SIZE} texels (got {self.size})")
        if self.texel_density is not None and not 0.0 < self.texel_density < float("inf"):
            raise ValueError(f"texel density must be a positive number of texels a metre (got {self.texel_density})")
        if self.samples < 1 or self.indirect_samples < 1 or self.texel_vpls < 1 or self.light_samples < 0:
            raise ValueError("samples, indirect samples and texel VPLs must be at least 1, light samples at least 0")
        if self.bake_pass not in BAKE_PASSES:
            raise ValueError(f"unknown pass {self.bake_pass!r}; choose one of {', '.join(BAKE_PASSES)}")
        if self.method not in METHODS or not METHODS[self.method].sums_lights:
            summed = [name for name, m in METHODS.items() if m.sums_lights]
            raise ValueError(f"method {self.method!r} cannot bake lightmaps; choose one of {', '.join(summed)}")
        if self.margin < 0:
            raise ValueError(f"margin must not be negative (got {self.margin})")


@dataclass
class LightmapResult:
    # object name -> (size,size,4) float32, its own size: the pass, alpha = coverage; row 0 at v = 1
    images: dict[str, np.ndarray]
    # object name -> seconds of its own work; "place" the VPLs' and "denoise" the denoiser's (shared)
    seconds: dict[str, float]
    warnings: list[str] = field(default_factory=list)
    info: dict = field(default_factory=dict)


@dataclass
class _Lit:
    """What lights the texels: the tracer, the lights, the placed VPLs and the gather's clamp and VPL order; and
    the scene's face normals, which ``unocclude`` reads for every object (made once: O(scene) each time). ``texels``
    holds the objects' texels that placing by the view rasterised already (object index -> ``_texels``), so that
    their bake takes them instead of rasterising again."""
    tracer: Tracer
    lights: LightSet
    face_normals: np.ndarray
    vpls: object = None
    d_min: float = 0.0
    permutation: np.ndarray | None = None
    texels: dict = field(default_factory=dict)


@render_heap()
def bake(scene, objects: list[str], settings: LightmapSettings,
         progress: Callable[[float, str], bool] | None = None) -> LightmapResult:
    """The lightmaps of the ``objects`` (names of the scene's) in ``settings.bake_pass``; every object of the
    scene occludes and reflects light, baked or not. ``progress(fraction, text)`` hears of each object done and
    cancels the bake by returning False (``Cancelled``). The C library keeps the heap the bake frees until it ends
    (``core.memory.render_heap``)."""
    result = LightmapResult({}, {})
    missing = [name for name in objects if name not in scene.object_names]
    if missing:
        raise ValueError(f"object {missing[0]!r} is not in the scene")
    tracer = Tracer(scene.triangles, threads=settings.threads, cutouts=cutouts(scene), seed=settings.seed)
    try:
        lit = _Lit(tracer, LightSet(scene), scene.geometric_normals)
        if len(lit.lights) == 0 and settings.bake_pass != P.DIFFUSE_COLOR:
            result.warnings.append("the scene has no lights: the lightmaps are black")
        t0 = time.perf_counter()
        if _needs_indirect(settings) and len(lit.lights) and len(scene.triangles):
            _place(scene, objects, settings, lit, result)
        result.seconds["place"] = time.perf_counter() - t0
        maps = {}
        for number, name in enumerate(objects):
            t0 = time.perf_counter()
            maps[name] = _bake_object(scene, scene.object_names.index(name), settings, lit, result)
            result.seconds[name] = time.perf_counter() - t0
            if progress is not None and progress((number + 1) / len(objects), name) is False:
                raise Cancelled()
    finally:
        tracer.close()
    _finish(maps, settings, result)
    return result


@dataclass
class _Map:
    """One object's map before it is denoised: its light (size,size,3, dilated; row 0 at v = 0), the texels its
    UV map covers and how much, and its seams (``seams.seam_pairs``)."""
    light: np.ndarray
    coverage: np.ndarray
    pairs: np.ndarray

    @property
    def filled(self) -> np.ndarray:
        return self.coverage > 0.0


def _finish(maps: dict[str, _Map], settings: LightmapSettings, result: LightmapResult) -> None:
    """The maps into ``result.images``: denoised all at once (``denoising``; the seconds as "denoise"), their
    seams stitched, the rings grown again, alpha the coverage, row 0 at v = 1."""
    t0 = time.perf_counter()
    lights = [m.light for m in maps.values()]
    if settings.denoise and settings.bake_pass != P.DIFFUSE_COLOR and any(light.any() for light in lights):
        try:
            lights = denoise_maps(lights, settings.threads)
        except DenoiserMissing as err:
            result.warnings.append(f"{err}: the lightmaps are not denoised")
    margin = max(settings.margin, MIN_MARGIN)
    for (name, m), light in zip(maps.items(), lights):
        size = len(m.coverage)
        image = stitch(light.reshape(-1, 3), m.pairs, m.filled.ravel()).reshape(size, size, 3)
        image = dilate(np.where(m.filled[..., None], image, 0.0), m.filled, margin)
        out = np.concatenate([image, m.coverage[..., None]], axis=2)[::-1]
        result.images[name] = np.ascontiguousarray(np.maximum(out, 0.0), np.float32)
    result.seconds["denoise"] = time.perf_counter() - t0


def _needs_indirect(settings: LightmapSettings) -> bool:
    return settings.bake_pass in (P.DIFFUSE_INDIRECT, DIFFUSE, P.COMBINED)


def _bounces(scene, settings: LightmapSettings) -> int:
    return scene.max_bounces if settings.max_bounces is None else settings.max_bounces


def _place(scene, objects: list[str], settings: LightmapSettings, lit: _Lit, result: LightmapResult) -> None:
    """The VPLs of all the ``objects``, once, into ``lit`` (checked finite and non-negative), their number in
    ``result.info``; a method that places by the view places by the objects' texels (``view.TexelView``)."""
    if _bounces(scene, settings) <= 0:
        return
    view = None
    if not METHODS[settings.method].view_independent:
        lit.texels = {index: _texels(scene, index, settings) for index in map(scene.object_names.index, objects)}
        view = TexelView(scene, [texels for texels, _, _ in lit.texels.values()], lit.tracer, lit.face_normals)
    context = MethodContext(scene, lit.tracer, lit.lights, np.random.default_rng([settings.seed, 1 << 20]),
                            _bounces(scene, settings), np.random.default_rng([settings.seed, 1 << 21]),
                            view_points=view)
    lit.vpls, info = place(settings.method, context, settings.placement)
    P.check({"VPL intensity": lit.vpls.intensity}, f"lightmap, method {settings.method!r}, stage 'place'")
    lit.d_min = clamp_distance(scene.surface_area, settings.placement.vpls, settings.clamp)
    lit.permutation = context.rng.permutation(len(lit.vpls))
    result.info.update(info, vpls=len(lit.vpls))


def _bake_object(scene, index: int, settings: LightmapSettings, lit: _Lit, result: LightmapResult) -> _Map:
    """One object's map before denoising: its texels, their light in the pass, the islands dilated."""
    name = scene.object_names[index]
    texels, triangles, uv = lit.texels.pop(index, None) or _texels(scene, index, settings)
    size = texels.size
    if len(uv) and (uv.min() < 0.0 or uv.max() > 1.0):
        result.warnings.append(f"object {name!r}: its UV map reaches outside [0, 1]; the texels there are not baked")
    if texels.overlap > 0.01:
        result.warnings.append(f"object {name!r}: {texels.overlap:.0%} of its UV map overlaps itself; the "
                               f"overlapping texels hold the mean of the surfaces there")
    surface, _ = unocclude(texels.surface(scene), texels.footprint(scene), lit.tracer, lit.face_normals)
    light = _light(texels, surface, settings, lit)
    P.check({settings.bake_pass: light}, f"lightmap of {name!r}")
    coverage = texels.coverage.reshape(size, size)
    pairs = seam_pairs(scene.triangles[triangles], uv, size) if settings.stitch else np.zeros((0, 2), np.int64)
    return _Map(dilate(light.reshape(size, size, 3), coverage > 0.0, max(settings.margin, MIN_MARGIN)), coverage,
                pairs)


def _texels(scene, index: int, settings: LightmapSettings) -> tuple[Texels, np.ndarray, np.ndarray]:
    """(object ``index``'s ``Texels`` in a map of ``settings.size`` or of its texel density's size, its triangles'
    rows, their bake UVs)."""
    triangles = np.nonzero(scene.object_id == index)[0]
    uv = bake_uvs(scene)[triangles]
    size = settings.size if settings.texel_density is None else \
        density_size(scene, triangles, uv, settings.texel_density, MAX_SIZE)
    return rasterise(scene, triangles, size, settings.samples, np.random.default_rng([settings.seed, index])), \
        triangles, uv


def _light(texels: Texels, surface, settings: LightmapSettings, lit: _Lit) -> np.ndarray:
    """(size*size,3) the pass at each texel: the albedo-weighted means of its samples' direct and gathered light
    (Cycles' division by the colour), the colour, or Combined."""
    count = texels.size ** 2
    albedo = surface.albedo
    color = P.divide(group_sum(texels.texel, albedo, count), np.bincount(texels.texel, minlength=count)[:, None])
    if settings.bake_pass == P.DIFFUSE_COLOR:
        return color
    total = np.zeros((count, 3))
    if settings.bake_pass != P.DIFFUSE_INDIRECT and len(lit.lights) and settings.light_samples:
        rng = np.random.default_rng([settings.seed, 1 << 22, len(texels)])
        direct = direct_light(surface, lit.lights, lit.tracer, settings.light_samples, rng)[0]
        total += P.divide(group_sum(texels.texel, albedo * direct, count), group_sum(texels.texel, albedo, count))
    if _needs_indirect(settings) and lit.vpls is not None:
        total += _indirect(texels, surface, settings, lit)
    if settings.bake_pass != P.COMBINED:
        return total
    return color * total + P.divide(group_sum(texels.texel, surface.emission, count),
                                   np.bincount(texels.texel, minlength=count)[:, None])


def _indirect(texels: Texels, surface, settings: LightmapSettings, lit: _Lit) -> np.ndarray:
    """(size*size,3) Diffuse Indirect: the VPLs summed at each texel's first ``indirect_samples`` samples, the
    albedo-weighted mean. Each texel sums one of t x t disjoint subsets of the VPLs, about ``texel_vpls`` of them,
    scaled to the whole set (interleaving, ``gather.summing``), the subset drawn at random per texel rather than by
    its place in a tile: the subsets' differences are then white noise, which OIDN's lightmap filter takes out,
    where a tile's pattern left streaks; and no geometry-aware filter is needed, which blends texels on both sides
    of a wall standing on the floor (``gather.bilateral`` put 0.16 of the light outside a closed room on the floor
    inside it). The whole set's size matters more than each texel's share: on the Cornell box at 128 x 128
    (``bench/lightmap.py``), the lit texels' rMAE is 0.069 with 4096 VPLs in 16 subsets, 0.055 with 16384 in 64 at
    the same time, 0.050 with 16384 in 16 at 3.5 times it."""
    count = texels.size ** 2
    rows = texels.first(settings.indirect_samples)
    points, at = surface.take(rows), texels.texel[rows]
    tile = max(1, int(round(np.sqrt(len(lit.vpls) / settings.texel_vpls))))
    xy = np.random.default_rng([settings.seed, 1 << 23]).integers(0, tile, (len(at), 2))
    light = gather(points, xy, lit.vpls, lit.tracer, GatherSettings(interleave=tile, clamp=settings.clamp,
                                                                    filter=False), lit.d_min, lit.permutation)
    albedo = points.albedo
    return P.divide(group_sum(at, albedo * light, count), group_sum(at, albedo, count))
