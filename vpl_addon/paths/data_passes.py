"""Cycles' data passes of a block of pixels, from its G-buffer: what the camera sees rather than light.

As Cycles 5 writes them (measured on its passes):
- ``Depth``, ``Position``, ``Object Index``, ``Material Index`` come from one ray through the pixel's centre: the
  distance of its hit along the camera's view axis (1e10 where it misses), the hit point (0), the object's and the
  material's Pass Index (0). Cycles writes them at its sample 0, which falls on the pixel's centre: they are the same
  whatever the seed, Depth is exactly the view-axis distance of Position, and at a pixel whose samples partly miss
  Depth is 1e10 and Position 0 while Normal is the covered share of a unit normal. The ray goes through holes and
  stops at glass (Cycles writes data passes at the first surface that is not transparent).
- ``Normal``: the mean over the pixel's samples of the shading normal (facing the ray's side, as Cycles flips back
  faces), misses counting zero; ``Denoising Normal`` the same in camera space (x right, y up, z forward: Cycles').
- ``Mist``: one minus the mean over the samples of ``1 - m``, with ``m = clamp((d - start) / depth) ^ falloff`` for
  the hit's distance ``d`` from the camera (along its axis for an orthographic one) and the world's mist settings;
  a miss counts ``m = 1``.
- ``Ambient Occlusion``: the share of the samples whose one cosine-distributed ray from the hit meets nothing within
  the world's AO distance (a miss counts zero).
- Cryptomatte (``core.cryptomatte``): the objects, materials and assets (an object's outermost parent) the samples
  see, each with its share of the samples.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core import cryptomatte
from ..core import passes as P
from ..core.color import largest
from ..core.sampling import cosine_hemisphere, dot, interpolated
from .gbuffer import camera_hits

NO_DEPTH = 1e10  # Cycles' Depth where the first sample misses


@dataclass(frozen=True)
class Mist:
    """The world's mist pass settings (Blender's World > Mist Pass): start and depth in metres, and the falloff's
    exponent (Quadratic 2, Linear 1, Inverse Quadratic 0.5)."""
    start: float = 5.0
    depth: float = 25.0
    falloff: float = 2.0

    def factor(self, distance: np.ndarray) -> np.ndarray:
        ramp = np.clip((distance - self.start) / max(self.depth, 1e-12), 0.0, 1.0)
        return ramp ** self.falloff


def cryptomatte_levels(wanted) -> dict[str, int]:
    """Kind -> ranks asked for, from the Cryptomatte pass names among ``wanted``."""
    levels = {}
    for kind in P.CRYPTOMATTE:
        count = sum(1 for name in wanted if name.startswith(kind))
        if count:
            levels[kind] = 2 * count
    return levels


def first_surfaces_needed(wanted) -> bool:
    """Whether the data passes among ``wanted`` take the G-buffer's samples at their first surface
    (``GBuffer.build`` with ``first``)."""
    return bool({P.NORMAL, P.MIST, P.AO} & set(wanted)) or bool(cryptomatte_levels(wanted))


def data_passes(gbuf, scene, wanted, tracer, rng: np.random.Generator, mist: Mist = Mist(),
                ao_distance: float = 10.0) -> dict[str, np.ndarray]:
    """The data passes among ``wanted`` for the pixels of ``gbuf``: name -> (pixels, channels)."""
    surf, cam, count = gbuf.surface, scene.camera, len(gbuf.pixels)
    out = {}
    camera_axis = -cam.to_world[:3, 2]
    centred = {P.DEPTH, P.POSITION, P.OBJECT_INDEX, P.MATERIAL_INDEX} & set(wanted)
    if centred:
        hits = camera_hits(cam, tracer, gbuf.pixels % cam.width + 0.5, gbuf.pixels // cam.width + 0.5, first=True).hits
        at, prim = np.nonzero(hits.hit)[0], hits.prim[hits.hit]
        u, v = hits.u[at], hits.v[at]
        point = interpolated(scene.triangles[prim], np.stack([1.0 - u - v, u, v], axis=1))
        for name, value, empty in ((P.DEPTH, lambda: dot(point - cam.position, camera_axis), NO_DEPTH),
                                   (P.POSITION, lambda: point, 0.0),
                                   (P.OBJECT_INDEX, lambda: scene.object_pass_index[scene.object_id[prim]], 0.0),
                                   (P.MATERIAL_INDEX, lambda: scene.materials.pass_index[scene.material[prim]], 0.0)):
            if name in centred:
                out[name] = np.full((count, P.CHANNELS[name]), empty)
                out[name][at] = value().reshape(len(at), P.CHANNELS[name])
    if P.DENOISING_NORMAL in wanted:  # through smooth glass, as Cycles' denoising data (its albedo too), and
        # none from a surface without a BSDF (an Emission shader alone), as Cycles writes none there (measured)
        bsdf = ((largest(surf.albedo) > 0.0) | surf.glossy)[:, None]
        out[P.DENOISING_NORMAL] = gbuf.splat(surf.shading_normal * bsdf) @ cam.to_world[:3, :3] * (1.0, 1.0, -1.0)
    gbuf = gbuf.first_surfaces()
    surf = gbuf.surface
    object_id = scene.object_id[surf.prim]
    if P.NORMAL in wanted:
        out[P.NORMAL] = gbuf.splat(surf.shading_normal)
    if P.MIST in wanted:
        offset = surf.position - cam.position
        distance = np.abs(dot(offset, camera_axis)) if cam.orthographic else np.linalg.norm(offset, axis=1)
        out[P.MIST] = 1.0 - gbuf.splat((1.0 - mist.factor(distance))[:, None])
    if P.AO in wanted:
        out[P.AO] = np.repeat(gbuf.splat(_unoccluded(surf, tracer, rng, ao_distance)[:, None]), 3, axis=1)
    items = {"CryptoObject": (object_id, scene.object_names),
             "CryptoMaterial": (surf.material, scene.materials.names),
             "CryptoAsset": (scene.object_asset[object_id], scene.asset_names)}
    for kind, levels in cryptomatte_levels(wanted).items():
        item, names = items[kind]
        pairs = cryptomatte.ranked(gbuf.sample // gbuf.spp, item, 1.0 / gbuf.spp, count, levels,
                                   cryptomatte.ids(names))
        for number, name in enumerate(P.cryptomatte_passes(kind, levels)):
            out[name] = pairs[:, 4 * number:4 * number + 4]
    return out


def _unoccluded(surf, tracer, rng: np.random.Generator, distance: float) -> np.ndarray:
    """(K,) 1 where a cosine-distributed ray about the shading normal leaves the surface (on its geometric side)
    and meets nothing within ``distance``, else 0."""
    if len(surf) == 0 or distance <= 0.0:
        return np.zeros(len(surf))
    dirs, _ = cosine_hemisphere(rng.random(len(surf)), rng.random(len(surf)), surf.shading_normal)
    leaves = dot(dirs, surf.geometric_normal) > 0.0
    open_ = tracer.visible(surf.position, surf.geometric_normal, dirs, np.full(len(surf), distance))
    return (leaves & open_).astype(np.float64)
