"""Caustic photons aimed at the sharp glossy surfaces: Jensen's projection map (*Global Illumination using Photon
Maps*, 1996, sec. 3.1) for the distant lights.

A distant light (the sun, the sky, an HDR) emits its light paths through a disc as wide as the whole scene, so few
of them meet a small metal object: the helmet under its HDR takes a small share of them, and its glints on the
ground are a few caustic photons each. The same light emitted through the disc of a sphere around just the
surfaces that may be sharper than ``SHARP`` carries, per path, the power of that smaller disc, and nearly every
path meets them. So the caustics of the distant lights come from paths of their own (``trace_caustic_photons``),
a share of the light paths' number, where they bring several times the light paths' caustic photons, and the
light paths leave them the distant lights' caustics (``distant_caustics``). Each path is the line a scene-wide
disc would have emitted, started outside the scene, so what stands between the light and the sharp surface still
shades it.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...gather.virtual_lights import VirtualLights
from ...lights.light_set import LightSet
from ...materials.textures import lowest
from ...paths.light_paths import SHARP, trace_paths

CAUSTIC_BOUNCES = 2  # light -> the sharp lobe -> the receiver: the caustic photon's bounce
# aimed paths are traced only where they bring at least this many times the caustic photons of the light paths:
# the helmet's sharp surfaces are 1/80 of its scene's disc, the living room's (a glossy floor and table) 1/2.2
DENSER = 4.0


@dataclass
class AimedLights:
    """The distant lights of a scene emitting through the disc of the sphere (``center``, ``radius``) around its
    sharp surfaces, their paths started ``back`` further upstream, outside the scene; ``LightSet.emit``'s
    interface, which ``trace_paths`` calls."""

    lights: LightSet
    back: float

    def __len__(self):
        return len(self.lights)

    def emit(self, count, rng, prob=None, with_light=False):
        origins, dirs, power, *light = self.lights.emit(count, rng, prob, with_light=True)
        origins = origins - self.back * dirs
        return (origins, dirs, power, light[0]) if with_light else (origins, dirs, power)


def aimed_lights(scene, lights: LightSet, share: float = 1.0) -> AimedLights | None:
    """The distant lights of ``lights`` aimed at ``scene``'s surfaces that may be sharper than ``SHARP``
    (``sharp_bounds``), for ``share`` aimed paths per light path; None without either, or where those paths would
    not bring ``DENSER`` times the light paths' caustic photons (the scene's disc over the sharp surfaces', times
    ``share``)."""
    distant = [light for light, far in zip(lights.lights, distant_lights(lights)) if far]
    bounds = sharp_bounds(scene)
    if not distant or bounds is None or share * (lights.radius / bounds[1]) ** 2 < DENSER:
        return None
    center, radius = bounds
    back = float(np.linalg.norm(center - lights.center)) + lights.radius + radius
    return AimedLights(LightSet(lights=distant, center=center, radius=radius), back)


def distant_lights(lights: LightSet) -> np.ndarray:
    """(L,) bool: which of ``lights`` emit through a disc (the sun, the world), whose caustic photons are aimed."""
    return np.array([light is lights.world or light.distant for light in lights.lights], bool)


def distant_caustics(lights: LightSet, aimed: AimedLights | None) -> np.ndarray | None:
    """(L,) bool: which of ``lights``' light paths leave caustic photons: all but the distant ones when their
    caustic photons are aimed; None: all."""
    return None if aimed is None else ~distant_lights(lights)


def trace_caustic_photons(scene, tracer, aimed: AimedLights, count: int, rng: np.random.Generator,
                          first_path: int = 0) -> VirtualLights:
    """The caustic photons of ``count`` aimed light paths (not yet divided by the number of paths): the VPLs they
    leave over one sharp lobe, holding only their white-receiver intensity (``VirtualLights.caustic``)."""
    found = trace_paths(scene, tracer, aimed, count, rng, CAUSTIC_BOUNCES, first_path=first_path)
    caustic = found.take(np.nonzero(found.caustic.any(axis=1))[0])
    caustic.intensity = np.zeros_like(caustic.intensity)
    return caustic


def sharp_bounds(scene) -> tuple[np.ndarray, float] | None:
    """(center, radius) of a sphere around every triangle whose material has a glossy lobe (metallic or the
    specular layer; not glass) that may be sharper than ``SHARP`` somewhere: its Roughness, or the least its map
    gives (``textures.lowest``), below it, on its own or on the material it mixes with; None if there is none."""
    m = scene.materials
    lobe = (m.metallic > 0.0) | (m.mapped("metallic") >= 0) | ((m.specular > 0.0) & (m.ior != 1.0))
    if m.fresnel_mix is not None:
        lobe |= m.fresnel_mix > 0.0
    least = np.array([r if i < 0 else lowest(m.maps[i], scene.textures)
                      for i, r in zip(m.mapped("roughness"), m.roughness)])
    sharp = lobe & ~m.glass & (least < SHARP)
    if m.mix_other is not None:
        sharp |= (m.mix_other >= 0) & sharp[np.maximum(m.mix_other, 0)]
    corners = scene.triangles[sharp[scene.material]].reshape(-1, 3).astype(np.float64)
    if not len(corners):
        return None
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    center = 0.5 * (lo + hi)
    return center, max(float(np.linalg.norm(corners - center, axis=1).max()), 1e-12)
