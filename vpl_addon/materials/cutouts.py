"""Alpha cut-outs: the Principled BSDF's Alpha as Cycles renders it, a stochastic hole. A ray that reaches a
surface of opacity a stops there with probability a and goes on through it otherwise (Cycles mixes in a
Transparent BSDF of weight 1 - a, so the expected light is the same); alpha clip (a glTF MASK material,
``TextureMap.cutoff``) makes a 0 or 1, alpha blend leaves it in between. ``Tracer`` asks a ``Cutouts`` at every
hit on a triangle whose material has an Alpha below 1 or an alpha map, so camera rays, shadow rays, light paths and
the gather's visibility all see the same holes."""
from __future__ import annotations

import numpy as np

from .surface import interpolated
from .textures import lookup


class Cutouts:
    """The triangles with holes (``prims``) and the opacity at points of them."""

    def __init__(self, scene):
        m = scene.materials
        self._scene = scene
        self._alpha_map = m.mapped("alpha")
        holed = (m.alpha < 1.0) | (self._alpha_map >= 0)
        self.prims = holed[scene.material]  # (T,) bool

    def opacity(self, prim: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        """(N,) opacity in [0, 1] at barycentric (u, v) of triangles ``prim``: the Alpha input's value, or its map's
        at the point's UV."""
        scene, m = self._scene, self._scene.materials
        mat = scene.material[prim]
        out = m.alpha[mat].astype(np.float64)
        ids = self._alpha_map[mat]
        linked = np.nonzero(ids >= 0)[0]
        if len(linked):
            bary = np.stack([1.0 - u[linked] - v[linked], u[linked], v[linked]], axis=1)
            uv = interpolated(scene.uvs[prim[linked]], bary)
            for t in np.unique(ids[linked]):
                sel = np.nonzero(ids[linked] == t)[0]
                out[linked[sel]] = lookup(m.maps[t], scene.textures, uv[sel], scalar=True)
        return np.clip(np.nan_to_num(out, nan=1.0), 0.0, 1.0)

    def passes(self, prim: np.ndarray, u: np.ndarray, v: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """(N,) bool: which rays go on through the hits (prim, u, v), each with probability 1 - opacity."""
        return rng.random(len(prim)) >= self.opacity(prim, u, v)


def cutouts(scene) -> Cutouts | None:
    """The scene's ``Cutouts``, None when every material is opaque (rays then cost nothing extra)."""
    m = scene.materials
    if not len(scene.material) or not ((m.alpha < 1.0) | (m.mapped("alpha") >= 0)).any():
        return None
    return Cutouts(scene)
