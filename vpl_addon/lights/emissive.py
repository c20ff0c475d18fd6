"""Emissive meshes as one light: radiance = Emission Color x Strength, emitted from both sides of every
triangle whose material emits. Where an image drives Emission Color, a triangle emits the image's mean over it
(``MAP_POINTS`` stratified points), so a mesh with a mostly black emission texture lights the scene only where the
texture glows.

For the glossy lobe's multiple importance sampling (``lights.direct``) the light says what a direction finds of it
(``mis``): the nearest of its triangles along the ray, in a BVH of its own, and the pdf with which its sampling
draws that direction, p(triangle) / Omega."""
from __future__ import annotations

import threading

import numpy as np

from ..core.color import LUMINANCE, largest
from ..core.compiled import inline, kernel
from ..core.sampling import cosine_hemisphere, sample_cdf, triangle_barycentrics
from ..core.tracer import Tracer
from ..materials.textures import at_points
from .light import Light

MAP_POINTS = 4  # per side of the grid of points over a triangle that average an emission texture (16 points)


class EmissiveTriangles(Light):
    """All triangles whose material emits, as one light: a triangle chosen by power, a direction uniform in its
    solid angle (next-event estimation) or a point uniform on it (light paths)."""

    name = "emissive triangles"

    def __init__(self, triangles, normals, radiance):
        self.triangles = np.asarray(triangles, np.float64)
        self.normals = np.asarray(normals, np.float64)
        self.radiance = np.asarray(radiance, np.float64)
        e1 = self.triangles[:, 1] - self.triangles[:, 0]
        e2 = self.triangles[:, 2] - self.triangles[:, 0]
        self.areas = 0.5 * np.linalg.norm(np.cross(e1, e2), axis=1)
        weight = self.areas * (self.radiance @ LUMINANCE)
        self.total = float(weight.sum())
        self.cdf = np.cumsum(weight) / self.total if self.total > 0 else np.ones(len(weight))
        self.prob = weight / self.total if self.total > 0 else np.zeros(len(weight))
        self._tracer, self._building = None, threading.Lock()

    @staticmethod
    def from_scene(scene) -> "EmissiveTriangles | None":
        emission = _emission(scene)
        sel = largest(emission) > 0.0
        if not sel.any():
            return None
        return EmissiveTriangles(scene.triangles[sel], scene.geometric_normals[sel], emission[sel])

    def flux_estimate(self, scene_radius):
        return 2.0 * np.pi * self.total  # both sides

    def intensity_estimate(self):
        """The intensity of every triangle facing the same way."""
        return self.total

    def bounds(self):
        pts = self.triangles.reshape(-1, 3)
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        return 0.5 * (lo + hi), 0.5 * float(np.linalg.norm(hi - lo))

    def _sample_incident(self, p, n, u1, u2):
        """A triangle chosen by power (``u1`` within the chosen CDF bin reused for the point), then a direction
        uniform in the solid angle it subtends at p: L x solid angle / p(triangle), no 1/d^2 spikes beside a
        panel (``_triangle_samples``). Sampled by area instead, a point on a wall 1 cm behind an emissive panel gets
        the right mean from a heavy tail (a render's samples have a median of 0.56x the mean), which the denoiser
        takes for noise: a dark rim around the panel."""
        idx = sample_cdf(self.cdf, u1)
        lo = np.where(idx > 0, self.cdf[np.maximum(idx - 1, 0)], 0.0)
        w = np.maximum(self.cdf[idx] - lo, 1e-300)
        u1r = np.clip((u1 - lo) / w, 0.0, 1.0 - 1e-12)
        wi, dist, weight = np.zeros((len(p), 3)), np.zeros(len(p)), np.zeros((len(p), 3))
        _triangle_samples(np.asarray(p, np.float64), idx, self.triangles, self.normals, self.radiance, self.prob,
                          u1r, np.asarray(u2, np.float64), wi, dist, weight)
        return wi, dist, weight, self.normals[idx]

    def mis(self, p, n, w):
        """(distance, radiance, pdf, normal) of the nearest of the triangles along each ray from p along w
        (``Light.mis``): its radiance (the mean ``_sample_incident`` weighs), p(triangle) / Omega, the pdf of
        drawing w toward it, and its normal; 0 where the ray meets none. The rays leave p pushed off its surface
        along n, to the side w leaves by (``Tracer.offset_origin``), so a point of a glowing surface does not find
        itself."""
        with self._building:
            if self._tracer is None:
                self._tracer = Tracer(self.triangles, threads=1)
        side = np.where((np.einsum("ij,ij->i", n, w) >= 0.0)[:, None], n, -n)
        origin = self._tracer.offset_origin(p, side)
        hits = self._tracer.intersect(origin, w)
        rows = np.nonzero(hits.hit)[0]
        dist, radiance, pdf = np.full(len(p), np.inf), np.zeros((len(p), 3)), np.zeros(len(p))
        normal = np.zeros((len(p), 3))
        idx = hits.prim[rows]
        at = np.asarray(p, np.float64)[rows]
        dist[rows] = _to_plane(at, w[rows], origin[rows], hits.t[rows], self.triangles[idx, 0], self.normals[idx])
        radiance[rows], normal[rows] = self.radiance[idx], self.normals[idx]
        _triangle_pdfs(at, idx, self.triangles, self.prob, pdf, rows)
        return dist, radiance, pdf, normal

    def emit(self, count, rng, center, radius):
        idx = sample_cdf(self.cdf, rng.random(count))
        b1, b2 = triangle_barycentrics(rng.random(count), rng.random(count))
        tri = self.triangles[idx]
        origins = tri[:, 0] + b1[:, None] * (tri[:, 1] - tri[:, 0]) + b2[:, None] * (tri[:, 2] - tri[:, 0])
        side = np.where(rng.random(count) < 0.5, 1.0, -1.0)[:, None] * self.normals[idx]
        dirs, _ = cosine_hemisphere(rng.random(count), rng.random(count), side)
        # radiance x pi (cosine lobe) x area / p(triangle), times 2 for the side chosen with probability 1/2
        power = self.radiance[idx] * (2.0 * np.pi * self.areas[idx] / np.maximum(self.prob[idx], 1e-300))[:, None]
        origins = origins + side * (1e-7 * max(radius, 1e-30))
        return origins, dirs, power


def _to_plane(p, w, origin, t, corner, normal):
    """(N,) the distance from p along w to the plane of the triangle (a corner and its unit normal) the ray from the
    pushed ``origin`` met at ``t``, in double precision: p + w dist lies on the light's surface, where a shadow ray
    stops off it (``Tracer.visible_through``'s target normal). Taken as t from the pushed origin, it would lie off
    the surface by the push (extent / 65536), farther than the shadow ray's margin: a glowing sphere would hide
    itself from the rays that graze it. A ray along the plane keeps the pushed origin's distance."""
    across = np.einsum("ij,ij->i", w, normal)
    height = np.einsum("ij,ij->i", corner - p, normal)
    flat = np.abs(across) < 1e-9
    return np.where(flat, t + np.einsum("ij,ij->i", origin - p, w), height / np.where(flat, 1.0, across))


def _emission(scene) -> np.ndarray:
    """(T,3) radiance of every triangle: its material's Emission, or the mean of its emission map over it."""
    m = scene.materials
    out = m.emission[scene.material].astype(np.float64)
    ids = m.mapped("emission")[scene.material]
    if not (ids >= 0).any():
        return out
    u, v = (np.mgrid[0:MAP_POINTS, 0:MAP_POINTS].reshape(2, -1) + 0.5) / MAP_POINTS
    b1, b2 = triangle_barycentrics(u, v)
    bary = np.stack([1.0 - b1 - b2, b1, b2], axis=1)  # (P,3) spread over the triangle
    for t in np.unique(ids[ids >= 0]):
        tris = np.nonzero(ids == t)[0]
        value = at_points(m.maps[t], scene, np.repeat(tris, len(bary)), np.tile(bary, (len(tris), 1)),
                          scalar=False).reshape(len(tris), len(bary), 3)
        out[tris] = np.maximum(np.nan_to_num(value.mean(axis=1), nan=0.0, posinf=0.0), 0.0)
    return out


@kernel
def _triangle_samples(p, idx, triangles, normals, radiance, prob, u1, u2, wi, dist, weight):
    """For each sample i at point p[i] on triangle idx[i] (chosen with probability prob): the direction ``wi``
    uniform in the solid angle Omega the triangle subtends (``_spherical_triangle``), the distance ``dist`` to it
    along wi, and the weight L_e / pdf = L Omega / prob; all three zero where Omega is 0."""
    for i in range(len(idx)):
        t = idx[i]
        if prob[t] <= 0.0:
            continue
        q0 = (triangles[t, 0, 0] - p[i, 0], triangles[t, 0, 1] - p[i, 1], triangles[t, 0, 2] - p[i, 2])
        q1 = (triangles[t, 1, 0] - p[i, 0], triangles[t, 1, 1] - p[i, 1], triangles[t, 1, 2] - p[i, 2])
        q2 = (triangles[t, 2, 0] - p[i, 0], triangles[t, 2, 1] - p[i, 1], triangles[t, 2, 2] - p[i, 2])
        solid, w = _spherical_triangle(q0, q1, q2, u1[i], u2[i])
        if not solid > 0.0:  # a point in the triangle's plane outside it, on its edge or corner: no light
            continue
        n = (normals[t, 0], normals[t, 1], normals[t, 2])
        # the plane's distance along w, kept within the triangle's farthest corner (rounding at grazing angles)
        far = max(np.sqrt(_dot(q0, q0)), np.sqrt(_dot(q1, q1)), np.sqrt(_dot(q2, q2)))
        facing = _dot(n, w)
        d = min(max(_dot(n, q0) / facing if facing != 0.0 else far, 0.0), far)
        wi[i, 0], wi[i, 1], wi[i, 2] = w
        dist[i] = d
        for c in range(3):
            weight[i, c] = solid / prob[t] * radiance[t, c]


@kernel
def _triangle_pdfs(p, idx, triangles, prob, pdf, rows):
    """pdf[rows[i]] = prob / Omega of triangle idx[i] seen from p[i]: the solid-angle pdf with which
    ``_triangle_samples`` draws a direction toward it (0 where Omega is 0)."""
    for i in range(len(idx)):
        t = idx[i]
        q0 = (triangles[t, 0, 0] - p[i, 0], triangles[t, 0, 1] - p[i, 1], triangles[t, 0, 2] - p[i, 2])
        q1 = (triangles[t, 1, 0] - p[i, 0], triangles[t, 1, 1] - p[i, 1], triangles[t, 1, 2] - p[i, 2])
        q2 = (triangles[t, 2, 0] - p[i, 0], triangles[t, 2, 1] - p[i, 1], triangles[t, 2, 2] - p[i, 2])
        solid = _subtended(q0, q1, q2)
        pdf[rows[i]] = prob[t] / solid if solid > 0.0 else 0.0


@inline
def _dot(a, b):
    """a . b of two 3-tuples."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@inline
def _cross(a, b):
    """a x b of two 3-tuples."""
    return a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]


@inline
def _unit(a):
    """a / |a|, and |a| (a zero vector stays zero)."""
    length = np.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])
    s = 1.0 / length if length > 0.0 else 0.0
    return (a[0] * s, a[1] * s, a[2] * s), length


@inline
def _across(a, b):
    """The unit tangent at unit vector a of the great arc from a toward b: b's part orthogonal to a."""
    k = _dot(a, b)
    return _unit((b[0] - k * a[0], b[1] - k * a[1], b[2] - k * a[2]))[0]


@inline
def _solid_angle(a, b, c):
    """The solid angle of the spherical triangle with unit corners a, b, c (Van Oosterom and Strackee 1983:
    tan(Omega / 2) = |a . (b x c)| / (1 + a.b + b.c + c.a))."""
    return 2.0 * np.arctan2(abs(_dot(a, _cross(b, c))), 1.0 + _dot(a, b) + _dot(b, c) + _dot(c, a))


@inline
def _spherical_triangle(q0, q1, q2, u1, u2):
    """The solid angle Omega of the triangle with corners q0, q1, q2 seen from the origin (``_solid_angle``), and
    the unit direction that (u1, u2) maps to, uniformly in it (``_arvo``). Above pi sr the origin's foot on the
    triangle's plane lies inside the triangle, and the triangle is cut there into three, each drawn with the
    share of Omega it has: their corners at the foot are straight below the origin and the others away from it,
    where the whole triangle seen from nearly in its plane has three angles near pi, at which Arvo's construction
    runs out of double precision (4 % bright at 1e-8 of the triangle's size from it, dark at 1e-10)."""
    a, _ = _unit(q0)
    b, _ = _unit(q1)
    c, _ = _unit(q2)
    solid = _solid_angle(a, b, c)
    if not solid > np.pi:
        return solid, _arvo(a, b, c, solid, u1, u2)
    f, s0, s1, s2 = _split_at_foot(q0, q1, q2, a, b, c)
    total = s0 + s1 + s2
    x = u1 * total
    if x < s0:
        return total, _arvo(a, f, b, s0, x / s0, u2)
    if x < s0 + s1:
        return total, _arvo(b, f, c, s1, (x - s0) / s1, u2)
    return total, _arvo(c, f, a, s2, min((x - s0 - s1) / max(s2, 1e-300), 1.0), u2)


@inline
def _split_at_foot(q0, q1, q2, a, b, c):
    """The unit direction f toward the foot of the origin on the plane of the triangle q0, q1, q2 (unit corners a,
    b, c), and the solid angles of the three triangles (f, a, b), (f, b, c), (f, c, a) it cuts the triangle into."""
    e1, e2 = (q1[0] - q0[0], q1[1] - q0[1], q1[2] - q0[2]), (q2[0] - q0[0], q2[1] - q0[1], q2[2] - q0[2])
    n, _ = _unit(_cross(e1, e2))
    height = _dot(q0, n)
    f, _ = _unit((height * n[0], height * n[1], height * n[2]))
    return f, _solid_angle(f, a, b), _solid_angle(f, b, c), _solid_angle(f, c, a)


@inline
def _subtended(q0, q1, q2):
    """The solid angle of the triangle q0, q1, q2 seen from the origin, as ``_spherical_triangle`` computes it."""
    a, _ = _unit(q0)
    b, _ = _unit(q1)
    c, _ = _unit(q2)
    solid = _solid_angle(a, b, c)
    if not solid > np.pi:
        return solid
    _, s0, s1, s2 = _split_at_foot(q0, q1, q2, a, b, c)
    return s0 + s1 + s2


@inline
def _arvo(a, b, c, solid, u1, u2):
    """The unit direction (u1, u2) maps to uniformly in the spherical triangle of unit corners a, b, c and area
    ``solid`` (Arvo, "Stratified Sampling of Spherical Triangles", SIGGRAPH 1995): u1 picks the sub-triangle of
    area u1 Omega that has the corners a, b and a point c' on arc ac, u2 a point on the arc from b to c' by its
    cosine. Well conditioned unless the angle at a is near pi."""
    cos_c = _dot(a, b)
    ab_t, ac_t = _across(a, b), _across(a, c)  # the arcs' tangents at a: the angle between them is alpha
    cos_alpha = _dot(ab_t, ac_t)
    sin_alpha = _unit(_cross(ab_t, ac_t))[1]
    sub = u1 * solid - np.arctan2(sin_alpha, cos_alpha)
    s, t = np.sin(sub), np.cos(sub)
    u = t - cos_alpha
    v = s + sin_alpha * cos_c
    den = (v * s + u * t) * sin_alpha
    cos_b = ((v * t - u * s) * cos_alpha - v) / den if den != 0.0 else 1.0
    cos_b = min(max(cos_b, -1.0), 1.0)
    sin_b = np.sqrt(max(1.0 - cos_b * cos_b, 0.0))
    c2 = (cos_b * a[0] + sin_b * ac_t[0], cos_b * a[1] + sin_b * ac_t[1], cos_b * a[2] + sin_b * ac_t[2])
    # 1 - b.c' as |b - c'|^2 / 2, exact where c' is close to b
    gap = ((b[0] - c2[0]) ** 2 + (b[1] - c2[1]) ** 2 + (b[2] - c2[2]) ** 2) / 2.0
    z = 1.0 - u2 * gap
    r = np.sqrt(max(u2 * gap * (2.0 - u2 * gap), 0.0))  # sqrt(1 - z^2) without the cancellation
    e = _across(b, c2)
    return _unit((z * b[0] + r * e[0], z * b[1] + r * e[1], z * b[2] + r * e[2]))[0]  # unit to the last digit
