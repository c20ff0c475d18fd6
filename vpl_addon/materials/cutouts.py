"""What rays pass through: alpha cut-outs and thin glass.

Alpha: the Principled BSDF's Alpha as Cycles renders it, a stochastic hole. A ray that reaches a surface of opacity
a stops there with probability a and goes on through it otherwise (Cycles mixes in a Transparent BSDF of weight
1 - a, so the expected light is the same); alpha clip (a glTF MASK material, ``TextureMap.cutoff``) makes a 0 or 1,
alpha blend leaves it in between.

Glass (``Materials.glass``: Transmission Weight >= 0.5, or a Glass BSDF): a smooth dielectric surface. A ray goes
on through it with probability T = (1 - F(cos theta, IOR)) x the luminance of its Base Color (Walter et al. 2007,
eq. 22 for F); where it stops, ``surface.shade`` makes the point a white mirror of the glass's roughness, so the light
it reflects is 1 - T in expectation (a ray that carries colour, below, carries F / (1 - T) there: F). Camera rays
refract as they go on (``Tracer.intersect_bent``: Snell's law about the interpolated normal, F of the interface from
the side the ray comes from), so a glass ball shows the room upside down as in Cycles, and rough glass blurs what
lies behind it; every other ray (shadow rays, light paths, the
gather's) takes glass as a thin sheet and goes on straight, with F at the IOR on both faces, which is exact for a
pane and keeps shadow rays straight segments.

Coloured glass (channels of its tint unequal; the tint is the colour light keeps crossing one face, ``Materials``:
the Glass BSDF's Color, the Principled BSDF's square root of Base Color, as Cycles tints each crossing): a ray asked
for its colour (``tinted``) goes on with probability (1 - F) x the tint's largest channel and carries the tint
divided by that channel as a weight (at most 1, so no ray gains light). The camera's rays, the shadow rays of
direct light, light paths, the summing gather's shadow rays and the photon lights' gather (its samples and the
camera path's extension, ``surface.bounce_tinted``) carry it; the rays that ask only whether or where they hit
(camera paths over metal for the summing methods, vbnl's placement, smc's and bidir's own rays, AO) take the
tint's luminance as the grey above.

``Tracer`` asks a ``Cutouts`` at every hit on such a triangle, so camera rays, shadow rays, light paths and the
gather's visibility all see the same holes and panes; it also reports which rays went through glass, whose light
Cycles counts as indirect (a transmission bounce)."""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..core.color import luminance
from .microfacet import alpha as microfacet_alpha
from .microfacet import dielectric_fresnel, sample
from .textures import at_points


class _Faces(NamedTuple):
    """What the rays that reach glass in ``Cutouts.passes`` see of its faces."""
    fresnel: np.ndarray  # (G,) F
    ior: np.ndarray  # (G,) the IOR, relative to the side the ray comes from where the glass is a solid's surface
    normal: np.ndarray | None  # (G,3) the normal F is of; None for a thin sheet (the geometric normal, either side)
    inside: np.ndarray | None  # (G,) bool whether the ray leaves the solid; None for a thin sheet


class Cutouts:
    """The triangles with holes or glass (``prims``) and what passes through them."""

    def __init__(self, scene):
        m = scene.materials
        self._scene = scene
        self._alpha_map = m.mapped("alpha")
        self._glass = m.glass
        tint = np.clip(m.base_color.astype(np.float64), 0.0, 1.0)  # what crossing a face of the glass leaves
        most = tint.max(axis=1)
        coloured = self._glass & (most > tint.min(axis=1))
        # whether a ray asked for its colour can carry a weight but 1: some glass is not clear white (it is
        # coloured, or what it absorbs must not show as reflection)
        self.weighs = bool((self._glass & (tint.min(axis=1) < 1.0)).any())
        self._grey = luminance(tint)  # the chance to pass (times 1 - F) of a ray that does not carry colour
        self._clear = np.where(coloured, most, self._grey)  # and of one that does, carrying ``_tint``
        self._tint = np.where(coloured[:, None], tint / np.maximum(most, 1e-300)[:, None], 1.0)
        self._roughness = np.clip(np.nan_to_num(m.roughness.astype(np.float64)), 0.0, 1.0)
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
               rng: np.random.Generator, bend: bool = False, tinted: bool = False, solid_glass: bool = False
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
        """(goes on (N,) bool, through glass (N,) bool, (N,3) the unit directions they go on with, (N,3) the colour
        weight of each or None) for rays of unit directions ``d`` hitting (prim, u, v) of geometric normals ``ng``:
        each goes on with probability 1 - alpha + alpha T (T of glass, 0 otherwise), through a hole straight. The
        weight (``tinted`` rays, where some glass is not clear white) is 1 but for the rays through coloured glass and
        those that stop at glass that absorbs: a ray stops at a face with probability 1 - T and is shaded as its
        mirror, which must reflect F, so it carries F / (1 - T) (and, inside a solid, where what stops is what the
        glass absorbs, 0). With ``solid_glass`` glass stops every ray (its holes do not): the first surface, as
        Cycles' data passes see it.

        Without ``bend`` a pane is a thin sheet: the ray goes on straight and T takes F at the IOR from either side.
        With ``bend`` the glass is a solid's surface, as Cycles' Glass BSDF renders it: the IOR is relative to the
        side the ray comes from, which the triangle's winding tells (Cycles' backfacing flag), and the ray refracts
        (Snell's law, Walter et al. 2007 eq. 40) about the interpolated normal or, on rough glass, about a
        microfacet normal drawn from GGX's visible normals (alpha = Roughness^2, eq. 33's distribution; Heitz
        2018), with F of that normal. Inside the solid, a ray the face reflects (F, all of it past the critical
        angle) goes on reflected toward the solid's other faces, as Cycles' path does; outside, it stops there and
        sees the glass as a mirror (``surface.shade``), as does a ray a microfacet would send back to its own side.
        A Roughness map is read as its material's value."""
        alpha = self.opacity(prim, u, v)
        mat = self._scene.material[prim]
        glass = np.nonzero(self._glass[mat])[0] if not solid_glass else np.zeros(0, np.int64)
        clear, face = np.zeros(len(prim)), None
        x = rng.random(len(prim))
        if len(glass):
            face = self._faces(prim[glass], u[glass], v[glass], d[glass], ng[glass], mat[glass], rng, bend)
            clear[glass] = (1.0 - face.fresnel) * (self._clear if tinted else self._grey)[mat[glass]]
        hole = x >= alpha
        through = ~hole & (x < alpha * clear)
        weight = self._weights(mat, glass, hole, through, clear, face) if tinted and self.weighs else None
        if not bend or not len(glass):
            return hole | through, through, np.array(d, np.float64), weight
        return _through_solid(d, ng, glass, face, x, alpha, clear, hole, through, weight)

    def _faces(self, prim, u, v, d, ng, mat, rng, bend: bool) -> _Faces:
        """What rays ``d`` that reach glass at (prim, u, v) of materials ``mat`` see of its faces: without ``bend``
        F at the IOR about the geometric normal ``ng`` (a thin sheet, either side); with it F of the IOR relative to
        the side the ray comes from, about the interpolated normal or a rough glass's microfacet normal
        (``_microfacets``)."""
        ior = self._scene.materials.ior[mat].astype(np.float64)
        cos = np.einsum("ij,ij->i", ng, d)
        normal = inside = None
        if bend:
            inside = cos >= 0.0  # leaving the solid through its face
            normal = self._normals(prim, u, v, ng)
            ior = np.where(inside, 1.0 / ior, ior)
            rough = np.nonzero(self._roughness[mat] > 0.0)[0]
            if len(rough):
                normal[rough] = self._microfacets(normal[rough], d[rough], mat[rough], rng)
            cos = np.einsum("ij,ij->i", normal, d)
        return _Faces(dielectric_fresnel(cos, ior), ior, normal, inside)

    def _weights(self, mat, glass, hole, through, clear, face) -> np.ndarray:
        """(N,3) the colour weight of ``tinted`` rays: the tint of the coloured glass a ray goes through (over its
        largest channel), F / (1 - T) where a ray stops at glass (``face.fresnel``: the mirror ``surface.shade`` makes
        of it reflects F, not the 1 - T that stops), 1 elsewhere."""
        weight = np.ones((len(mat), 3))
        weight[through] = self._tint[mat[through]]
        if len(glass):
            stop = ~hole[glass] & ~through[glass]
            weight[glass[stop]] = (face.fresnel[stop] / np.maximum(1.0 - clear[glass[stop]], 1e-300))[:, None]
        return weight

    def _microfacets(self, normal, d, mat, rng) -> np.ndarray:
        """(N,3) microfacet normals of rough glass for rays ``d`` at points of smooth ``normal`` (either side):
        GGX's visible normals (``microfacet.sample``) seen from the ray's side."""
        u = rng.random((2, len(d)))
        return sample(_facing(normal, d), -d, microfacet_alpha(self._roughness[mat]), u[0], u[1])[2]

    def _normals(self, prim, u, v, ng) -> np.ndarray:
        """(N,3) the unit interpolated normals at (prim, u, v), on the side of the geometric normals ``ng``."""
        corners = self._scene.normals[prim].astype(np.float64)
        n = corners[:, 0] * (1.0 - u - v)[:, None] + corners[:, 1] * u[:, None] + corners[:, 2] * v[:, None]
        n *= np.where(np.einsum("ij,ij->i", n, ng) < 0.0, -1.0, 1.0)[:, None]
        length = np.linalg.norm(n, axis=1, keepdims=True)
        return np.where(length > 1e-12, n / np.maximum(length, 1e-300), ng)


def _through_solid(d, ng, glass, face, x, alpha, clear, hole, through, weight):
    """``Cutouts.passes`` with ``bend``, from what a thin sheet lets through (``hole``, ``through``, ``weight``):
    the rays through glass refract (``_refracted``; one a bent normal sends back to its own side stops at the face,
    a mirror), and inside the solid (``face.inside``) the rays the face reflects go on reflected
    toward its other faces while those that neither cross nor reflect are absorbed (weight 0)."""
    fresnel, ior, normal, inside = face
    onward = np.array(d, np.float64)
    rows = np.nonzero(through[glass])[0]
    bent, ok = _refracted(d[glass[rows]], normal[rows], ior[rows], ng[glass[rows]])
    onward[glass[rows]] = bent
    through[glass[rows[~ok]]] = False
    reach = alpha[glass] * (clear[glass] + fresnel)  # x below it: the ray crosses the face or the face reflects it
    # inside, the rays the face reflects stay in the solid (toward its other faces) rather than end there
    back = np.nonzero(inside & ~through[glass] & ~hole[glass] & (x[glass] < reach))[0]
    turned = d[glass[back]] - 2.0 * np.einsum("ij,ij->i", d[glass[back]], normal[back])[:, None] * normal[back]
    kept = np.sign(np.einsum("ij,ij->i", turned, ng[glass[back]])) < 0.0  # still inside
    onward[glass[back[kept]]] = turned[kept]
    on = hole | through
    on[glass[back[kept]]] = True
    if weight is not None:
        weight[glass[rows[~ok]]] = 1.0  # a ray a bent normal sent back did not cross: a mirror
        weight[glass[back]] = 1.0  # reflected inside (or back out) with probability F
        absorbed = inside & ~hole[glass] & (x[glass] >= reach)
        weight[glass[absorbed]] = 0.0  # inside, a ray that neither crosses nor reflects is absorbed
    return on, through, onward, weight


def _facing(n: np.ndarray, d: np.ndarray) -> np.ndarray:
    """The normals ``n`` turned toward the side the rays ``d`` come from."""
    return n * np.where(np.einsum("ij,ij->i", d, n) > 0.0, -1.0, 1.0)[:, None]


def _refracted(d: np.ndarray, n: np.ndarray, eta: np.ndarray, ng: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(unit directions, (N,) bool whether each goes on across the surface) of rays ``d`` refracted at normals ``n``
    (either side) into a medium of relative IOR ``eta`` (n_t / n_i), which must not reflect totally:
    (d + (c - sqrt(eta^2 - 1 + c^2)) n_i) / eta with n_i the normal facing the ray and c = -d . n_i (Walter et al.
    2007 eq. 40 written for the transmitted direction). A direction that a bent normal (interpolated, or a rough
    microfacet's) would send back to the ray's side of the triangle (``ng``) does not go on."""
    facing = _facing(n, d)
    c = -np.einsum("ij,ij->i", d, facing)
    g = np.sqrt(np.maximum(eta * eta - 1.0 + c * c, 0.0))
    t = d + (c - g)[:, None] * facing
    t /= np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-300)
    ok = np.sign(np.einsum("ij,ij->i", t, ng)) == np.sign(np.einsum("ij,ij->i", d, ng))
    return t, ok


def cutouts(scene) -> Cutouts | None:
    """The scene's ``Cutouts``, None when every material is opaque (rays then cost nothing extra)."""
    m = scene.materials
    if not len(scene.material) or not ((m.alpha < 1.0) | (m.mapped("alpha") >= 0) | m.glass).any():
        return None
    return Cutouts(scene)
