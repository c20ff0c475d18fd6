"""What rays pass through: alpha cut-outs and thin glass.

Alpha: the Principled BSDF's Alpha as Cycles renders it, a stochastic hole. A ray that reaches a surface of opacity
a stops there with probability a and goes on through it otherwise (Cycles mixes in a Transparent BSDF of weight
1 - a, so the expected light is the same); alpha clip (a glTF MASK material, ``TextureMap.cutoff``) makes a 0 or 1,
alpha blend leaves it in between.

Glass (``Materials.glass``: Transmission Weight >= 0.5, or a Glass BSDF): a smooth dielectric surface. A ray goes
on through it with probability T = (1 - F(cos theta, IOR)) x the luminance of its Base Color (Walter et al. 2007,
eq. 22 for F); where it stops, ``surface.shade`` makes the point a white mirror of the glass's roughness, so the light
it reflects is 1 - T in expectation. Camera rays refract as they go on (``Tracer.intersect_bent``: Snell's law about
the interpolated normal, F of the interface from the side the ray comes from), so a glass ball shows the room upside
down as in Cycles; every other ray (shadow rays, light paths, the gather's) takes glass as a thin sheet and goes on
straight, with F at the IOR on both faces, which is exact for a pane and keeps shadow rays straight segments. The
tint is grey; rough glass refracts as smooth glass.

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

    def passes(self, prim: np.ndarray, u: np.ndarray, v: np.ndarray, d: np.ndarray, ng: np.ndarray,
               rng: np.random.Generator, bend: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(goes on (N,) bool, through glass (N,) bool, (N,3) the unit directions they go on with) for rays of unit
        directions ``d`` hitting (prim, u, v) of geometric normals ``ng``: each goes on with probability
        1 - alpha + alpha T (T of glass, 0 otherwise), through a hole straight.

        Without ``bend`` a pane is a thin sheet: the ray goes on straight and T takes F at the IOR from either side.
        With ``bend`` the glass is a solid's surface, as Cycles' Glass BSDF renders it: F is the interface's (the
        IOR relative to the side the ray comes from, which the triangle's winding tells, as Cycles' backfacing flag
        does; past the critical angle inside F = 1 and the ray stops there as a mirror) and the ray refracts about
        the interpolated normal (Snell's law, Walter et al. 2007 eq. 40); smooth whatever its Roughness."""
        alpha = self.opacity(prim, u, v)
        mat = self._scene.material[prim]
        glass = np.nonzero(self._glass[mat])[0]
        clear = np.zeros(len(prim))
        onward = np.array(d, np.float64)
        if len(glass):
            ior = self._scene.materials.ior[mat[glass]].astype(np.float64)
            cos = np.einsum("ij,ij->i", ng[glass], d[glass])
            if bend:
                normal = self._normals(prim[glass], u[glass], v[glass], ng[glass])
                ior = np.where(cos < 0.0, ior, 1.0 / ior)
                cos = np.einsum("ij,ij->i", normal, d[glass])
            clear[glass] = (1.0 - dielectric_fresnel(cos, ior)) * self._clear[mat[glass]]
        x = rng.random(len(prim))
        hole = x >= alpha
        through = ~hole & (x < alpha * clear)
        if bend and through.any():
            rows = np.nonzero(through[glass])[0]
            onward[glass[rows]] = _refracted(d[glass[rows]], normal[rows], ior[rows], ng[glass[rows]])
        return hole | through, through, onward

    def _normals(self, prim, u, v, ng) -> np.ndarray:
        """(N,3) the unit interpolated normals at (prim, u, v), on the side of the geometric normals ``ng``."""
        corners = self._scene.normals[prim].astype(np.float64)
        n = corners[:, 0] * (1.0 - u - v)[:, None] + corners[:, 1] * u[:, None] + corners[:, 2] * v[:, None]
        n *= np.where(np.einsum("ij,ij->i", n, ng) < 0.0, -1.0, 1.0)[:, None]
        length = np.linalg.norm(n, axis=1, keepdims=True)
        return np.where(length > 1e-12, n / np.maximum(length, 1e-300), ng)


def _refracted(d: np.ndarray, n: np.ndarray, eta: np.ndarray, ng: np.ndarray) -> np.ndarray:
    """Unit directions of rays ``d`` refracted at normals ``n`` (either side) into a medium of relative IOR ``eta``
    (n_t / n_i), which must not reflect totally: (d + (c - sqrt(eta^2 - 1 + c^2)) n_i) / eta with n_i the normal
    facing the ray and c = -d . n_i (Walter et al. 2007 eq. 40 written for the transmitted direction). A direction
    that the interpolated normal would send back across the triangle (``ng``) stays straight."""
    facing = n * np.where(np.einsum("ij,ij->i", d, n) > 0.0, -1.0, 1.0)[:, None]
    c = -np.einsum("ij,ij->i", d, facing)
    g = np.sqrt(np.maximum(eta * eta - 1.0 + c * c, 0.0))
    t = d + (c - g)[:, None] * facing
    t /= np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-300)
    same_side = np.sign(np.einsum("ij,ij->i", t, ng)) == np.sign(np.einsum("ij,ij->i", d, ng))
    return np.where(same_side[:, None], t, d)


def cutouts(scene) -> Cutouts | None:
    """The scene's ``Cutouts``, None when every material is opaque (rays then cost nothing extra)."""
    m = scene.materials
    if not len(scene.material) or not ((m.alpha < 1.0) | (m.mapped("alpha") >= 0) | m.glass).any():
        return None
    return Cutouts(scene)
