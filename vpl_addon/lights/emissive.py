"""Emissive meshes as one light: radiance = Emission Color x Strength, emitted from both sides of every
triangle whose material emits. Where an image drives Emission Color, a triangle emits the image's mean over it
(``MAP_POINTS`` stratified points), so a mesh with a mostly black emission texture lights the scene only where the
texture glows."""
from __future__ import annotations

import numpy as np

from ..core.color import LUMINANCE, largest
from ..core.sampling import cosine_hemisphere, dot, sample_cdf, triangle_barycentrics
from ..materials.textures import at_points
from .light import Light

MAP_POINTS = 4  # per side of the grid of points over a triangle that average an emission texture (16 points)


class EmissiveTriangles(Light):
    """All triangles whose material emits, as one light: triangle chosen by power, point uniform on it."""

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
        idx = sample_cdf(self.cdf, u1)
        # reuse u1 within the chosen CDF bin for the point: keeps one random pair per sample
        lo = np.where(idx > 0, self.cdf[np.maximum(idx - 1, 0)], 0.0)
        w = np.maximum(self.cdf[idx] - lo, 1e-300)
        u1r = np.clip((u1 - lo) / w, 0.0, 1.0 - 1e-12)
        b1, b2 = triangle_barycentrics(u1r, u2)
        tri = self.triangles[idx]
        q = tri[:, 0] + b1[:, None] * (tri[:, 1] - tri[:, 0]) + b2[:, None] * (tri[:, 2] - tri[:, 0])
        to_l = q - p
        d2 = dot(to_l, to_l)
        dist = np.sqrt(d2)
        wi = to_l / np.maximum(dist, 1e-300)[:, None]
        cos_l = np.abs(dot(wi, self.normals[idx]))
        pdf_area = self.prob[idx] / np.maximum(self.areas[idx], 1e-300)
        factor = cos_l / np.maximum(d2 * pdf_area, 1e-300)
        return wi, dist, factor[:, None] * self.radiance[idx], self.normals[idx]

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
