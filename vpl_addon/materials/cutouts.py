"""What rays pass through: alpha cut-outs and thin glass.

Alpha: the Principled BSDF's Alpha as Cycles renders it, a stochastic hole. A ray that reaches a surface of opacity
a stops there with probability a and goes on through it otherwise (Cycles mixes in a Transparent BSDF of weight
1 - a, so the expected light is the same); alpha clip (a glTF MASK material, ``TextureMap.cutoff``) makes a 0 or 1,
alpha blend leaves it in between.

Glass (``Materials.glass``: Transmission Weight >= 0.5, or a Glass BSDF): a thin dielectric sheet. A ray goes on
straight through with probability T = (1 - F(cos theta, IOR)) x the luminance of its Base Color (Walter et al. 2007,
eq. 22 for F), which is what a pane of parallel faces passes per face; where it stops, ``surface.shade`` makes the
point a white mirror of the glass's roughness, so the light it reflects is 1 - T in expectation. Straight through
is exact in direction for a pane and a thin sheet, an approximation for a lens (no refraction); the tint is grey.

``Tracer`` asks a ``Cutouts`` at every hit on such a triangle, so camera rays, shadow rays, light paths and the
gather's visibility all see the same holes and panes; it also reports which rays went through glass, whose light
Cycles counts as indirect (a transmission bounce)."""
from __future__ import annotations

import numpy as np

from ..core.color import luminance
from .microfacet import dielectric_fresnel
from .textures import at_points


class Cutouts:
    """The triangles with holes or glass (``prims``) and what passes through them."""

    def __init__(self, scene):
        m = scene.materials
        self._scene = scene
        self._alpha_map = m.mapped("alpha")
        self._glass = m.glass
        self._clear = luminance(np.clip(m.base_color.astype(np.float64), 0.0, 1.0))  # the glass's tint, grey
        holed = (m.alpha < 1.0) | (self._alpha_map >= 0) | self._glass
        self.prims = holed[scene.material]  # (T,) bool

    def opacity(self, prim: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        """(N,) alpha in [0, 1] at barycentric (u, v) of triangles ``prim``: the Alpha input's value, or its map's
        at the point's UV."""
        scene, m = self._scene, self._scene.materials
        mat = scene.material[prim]
        out = m.alpha[mat].astype(np.float64)
        ids = self._alpha_map[mat]
        linked = np.nonzero(ids >= 0)[0]
        if len(linked):
            bary = np.stack([1.0 - u[linked] - v[linked], u[linked], v[linked]], axis=1)
            for t in np.unique(ids[linked]):
                sel = np.nonzero(ids[linked] == t)[0]
                out[linked[sel]] = at_points(m.maps[t], scene, prim[linked[sel]], bary[sel], scalar=True)
        return np.clip(np.nan_to_num(out, nan=1.0), 0.0, 1.0)

    def passes(self, prim: np.ndarray, u: np.ndarray, v: np.ndarray, cos: np.ndarray,
               rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """(goes on (N,) bool, through glass (N,) bool) for rays hitting (prim, u, v) at cosines ``cos`` with the
        geometric normal: each goes on with probability 1 - alpha + alpha T (T of glass, 0 otherwise)."""
        alpha = self.opacity(prim, u, v)
        mat = self._scene.material[prim]
        glass = self._glass[mat]
        clear = np.zeros(len(prim))
        if glass.any():
            ior = self._scene.materials.ior[mat[glass]].astype(np.float64)
            clear[glass] = (1.0 - dielectric_fresnel(cos[glass], ior)) * self._clear[mat[glass]]
        x = rng.random(len(prim))
        hole = x >= alpha
        return hole | (x < alpha * clear), ~hole & (x < alpha * clear)


def cutouts(scene) -> Cutouts | None:
    """The scene's ``Cutouts``, None when every material is opaque (rays then cost nothing extra)."""
    m = scene.materials
    if not len(scene.material) or not ((m.alpha < 1.0) | (m.mapped("alpha") >= 0) | m.glass).any():
        return None
    return Cutouts(scene)
