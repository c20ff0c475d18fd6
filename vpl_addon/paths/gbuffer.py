"""The G-buffer: what the camera sees at several filter-distributed samples per pixel.

For a block of pixels it traces ``spp`` primary rays per pixel (stratified sub-pixel positions warped by the pixel
filter and, with depth of field, stratified points of the lens, see ``core.camera``) and keeps the ``Surface`` of
the samples that hit, and the directions of those that miss.
Passes are formed by ``splat``: the mean over a pixel's samples, misses counting as zero, exactly like Cycles' film
with a transparent background; ``background`` is the other share of the pixel, what its missing samples see of the
world (Cycles' Environment pass). A light the camera sees (``Light.visible``: an area light, a point or spot
light's sphere or disc, the sun's disc in the sky) adds its radiance to what its samples see behind it, as in
Cycles (``lamps``). What the samples see through coloured glass carries its colour (``tint``: Combined and the
colour passes take it, the data passes do not), as Cycles' throughput does.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import NamedTuple

import numpy as np

from ..core.sampling import group_sum, stratified_2d, stratified_4d
from ..core.tracer import Hits
from ..materials.surface import Surface, shade


class CameraHits(NamedTuple):
    heading: np.ndarray  # (N,3) the unit direction each ray has at its hit (or leaves the scene with)
    hits: Hits
    crossed: np.ndarray  # (N,) bool: which rays crossed glass on the way
    lamp: np.ndarray | None  # (N,3) the radiance of the visible lights each meets before its surface


def camera_hits(cam, tracer, px: np.ndarray, py: np.ndarray, lights=None, lens=None,
                first: bool = False) -> CameraHits:
    """What the camera's rays through image positions (px, py) (and the lens's numbers ``lens``, ``Camera.rays``)
    hit between the clip distances, refracted by the glass they pass (``Tracer.intersect_bent``; with ``first``
    the first surface, glass included: ``Tracer.intersect_first``); given ``lights`` (a list), also the radiance of
    the visible lights each ray meets before its surface (``Light.seen``, along the ray as it leaves the camera). As
    in Cycles, a light the camera sees adds its light to what is behind it and hides nothing."""
    origins, dirs, near = cam.rays(px, py, lens)
    origins = origins + dirs * near[:, None]
    tmax = np.maximum(cam.clip_end - near, 0.0)
    if first:
        hits, heading, crossed = tracer.intersect_first(origins, dirs, tmax=tmax), dirs, np.zeros(len(dirs), bool)
    else:
        hits, heading, crossed = tracer.intersect_bent(origins, dirs, tmax=tmax)
    if lights is None:
        return CameraHits(heading, hits, crossed, None)
    lamp, far = np.zeros((len(dirs), 3)), np.where(hits.hit, hits.t, tmax)
    for light in lights:
        found = light.seen(origins, dirs)
        if found is None:
            continue
        t, radiance = found
        seen = (t > 0.0) & ((t < far) | (np.isinf(t) & ~hits.hit))  # a sun where the ray reaches the sky
        lamp[seen] += radiance[seen]
    return CameraHits(heading, hits, crossed, lamp)


@dataclass
class GBuffer:
    pixels: np.ndarray  # (P,) flat pixel indices (row-major, row 0 at the top) covered by this block
    spp: int
    sample: np.ndarray  # (K,) index of each hit among the P*spp samples (sample // spp = position in pixels)
    surface: Surface  # (K,) what each hit sees
    missed: np.ndarray  # (M,) index of each miss among the P*spp samples
    miss_direction: np.ndarray  # (M,3) the direction of each miss's camera ray
    on_lamp: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))  # (L,) samples that see a light
    lamp_radiance: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))  # (L,3) what they see of it
    tint: np.ndarray | None = None  # (K,3) what coloured glass leaves of each hit's light; None: no such glass
    miss_tint: np.ndarray | None = None  # (M,3) the same for the misses
    # the samples whose first surface is not where their light comes from (glass they crossed), as ``sample`` and
    # ``surface`` with those samples' first surfaces instead: what the data passes see (``first_surfaces``)
    first_sample: np.ndarray | None = None
    first_surface: Surface | None = None

    @staticmethod
    def build(scene, tracer, pixels: np.ndarray, spp: int, rng: np.random.Generator,
              first: bool = False) -> "GBuffer":
        """The G-buffer of ``pixels``; with ``first``, also the first surfaces of the samples that crossed glass
        (``first_surfaces``)."""
        cam = scene.camera
        pixels = np.asarray(pixels, np.int64)
        lens = None
        if cam.aperture > 0.0:  # depth of field: the lens's points stratified with the filter's positions
            u, v, *lens = (a.ravel() for a in stratified_4d(len(pixels), spp, rng))
        else:
            u, v = stratified_2d(len(pixels), spp, rng)
        pix = np.repeat(pixels, spp)
        px = (pix % cam.width) + 0.5 + cam.filter_offsets(u.ravel())
        py = (pix // cam.width) + 0.5 + cam.filter_offsets(v.ravel())
        dirs, hits, crossed, lamp = camera_hits(cam, tracer, px, py, [light for light in scene.lights if light.visible],
                                                lens)
        sample = np.nonzero(hits.hit)[0]
        on_lamp = np.nonzero((lamp > 0.0).any(axis=1))[0]
        missed = np.nonzero(~hits.hit)[0]
        tint = (None, None) if hits.tint is None else (hits.tint[sample], hits.tint[missed])
        gbuf = GBuffer(pixels=pixels, spp=spp, sample=sample, surface=shade(scene, dirs, hits, sample),
                       missed=missed, miss_direction=dirs[missed], on_lamp=on_lamp, lamp_radiance=lamp[on_lamp],
                       tint=tint[0], miss_tint=tint[1])
        rows = np.nonzero(crossed)[0]
        if first and len(rows):  # the same rays again, stopping at the glass
            ahead = camera_hits(cam, tracer, px[rows], py[rows], lens=None if lens is None else
                                [numbers[rows] for numbers in lens], first=True)
            kept = sample[~np.isin(sample, rows)]  # the hits of the rays that crossed no glass
            found = np.nonzero(ahead.hits.hit)[0]
            index = np.concatenate([kept, rows[found]])
            order = np.argsort(index, kind="stable")
            gbuf.first_sample = index[order]
            gbuf.first_surface = Surface.concat([gbuf.surface.take(np.searchsorted(sample, kept)),
                                                 shade(scene, ahead.heading, ahead.hits, found)]).take(order)
        return gbuf

    def first_surfaces(self) -> "GBuffer":
        """This G-buffer as the data passes see it: each sample at the first surface it meets, glass included (as
        Cycles writes them), with no tint."""
        if self.first_sample is None:
            return self if self.tint is None else replace(self, tint=None)
        return replace(self, sample=self.first_sample, surface=self.first_surface, tint=None, first_sample=None,
                       first_surface=None)

    def __len__(self):
        return len(self.sample)

    @property
    def pixel_of_hit(self) -> np.ndarray:
        """(K,) flat image index of each hit's pixel."""
        return self.pixels[self.sample // self.spp]

    def splat(self, values: np.ndarray, tinted: bool = False) -> np.ndarray:
        """Per-pixel means (P,C) of per-hit values (K,C): misses contribute zero, as with a transparent film.
        ``tinted``: the values are light or colour, which coloured glass in front of a hit tints (``tinted``)."""
        values = self.tinted(values) if tinted else values
        return group_sum(self.sample // self.spp, np.asarray(values, np.float64), len(self.pixels)) / self.spp

    def tinted(self, values: np.ndarray, rows=slice(None)) -> np.ndarray:
        """(R,3) the light or colour ``values`` of the hits ``rows`` as the camera sees them, times what coloured
        glass in front of each leaves of it (``values`` itself where no glass is coloured)."""
        return values if self.tint is None else values * self.tint[rows]

    def background(self, world) -> np.ndarray:
        """(P,3) per-pixel mean of the radiance ``world`` (a light with ``radiance(w)``, or None for a black world)
        sends along the camera rays that miss, hits counting as zero: a pixel on an edge gets the background with
        the weight of its samples that miss, as the pixel filter spreads them."""
        if world is None or len(self.missed) == 0:
            return np.zeros((len(self.pixels), 3))
        seen = np.asarray(world.radiance(self.miss_direction), np.float64)
        if self.miss_tint is not None:
            seen = seen * self.miss_tint
        return group_sum(self.missed // self.spp, seen, len(self.pixels)) / self.spp

    def lamps(self) -> np.ndarray:
        """(P,3) per-pixel mean of the radiance the camera sees of visible lights (on top of what their samples
        see behind them)."""
        return group_sum(self.on_lamp // self.spp, self.lamp_radiance, len(self.pixels)) / self.spp

    @property
    def coverage(self) -> np.ndarray:
        """Fraction of each pixel's samples that hit geometry: the alpha of a transparent film."""
        return np.bincount(self.sample // self.spp, minlength=len(self.pixels)) / self.spp

    def first(self, where: np.ndarray, count) -> np.ndarray:
        """Rows of the first ``count`` hits of each pixel among those ``where`` holds: a pixel whose first samples
        miss a lobe (a wall's edge on a metal floor) still has that lobe's light from its other samples. ``count``
        is one number, or one per pixel (P,)."""
        rows = np.nonzero(where)[0]
        pixel = self.sample[rows] // self.spp  # non-decreasing: hits are in sample order
        rank = np.arange(len(rows)) - np.searchsorted(pixel, pixel)
        return rows[rank < (count if np.isscalar(count) else np.asarray(count)[pixel])]
