"""The G-buffer: what the camera sees at several filter-distributed samples per pixel.

For a block of pixels it traces ``spp`` primary rays per pixel (stratified sub-pixel positions warped by the pixel
filter, see ``camera.py``) and keeps, for the samples that hit, the surface position, the geometric and shading
normals turned toward the viewer (surfaces are two-sided, as in Cycles), UV, material terms and emission. Passes
are formed by ``splat``: the mean over a pixel's samples, misses counting as zero, exactly like Cycles' film with
a transparent background.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .sampling import dot, normalize, stratified_2d
from .textures import sample_bilinear


@dataclass
class GBuffer:
    pixels: np.ndarray  # (P,) flat pixel indices (row-major, row 0 at the top) covered by this block
    spp: int
    sample: np.ndarray  # (K,) index of each hit among the P*spp samples (sample // spp = position in pixels)
    position: np.ndarray  # (K,3)
    geometric_normal: np.ndarray  # (K,3) facing the viewer
    shading_normal: np.ndarray  # (K,3) facing the viewer's side
    wo: np.ndarray  # (K,3) unit direction toward the viewer
    prim: np.ndarray  # (K,) triangle index
    material: np.ndarray  # (K,) material index
    albedo: np.ndarray  # (K,3) diffuse albedo (Cycles' Diffuse Color)
    roughness: np.ndarray  # (K,)
    metallic: np.ndarray  # (K,)
    emission: np.ndarray  # (K,3)

    @staticmethod
    def build(scene, tracer, pixels: np.ndarray, spp: int, rng: np.random.Generator) -> "GBuffer":
        cam = scene.camera
        pixels = np.asarray(pixels, np.int64)
        u, v = stratified_2d(len(pixels), spp, rng)
        pix = np.repeat(pixels, spp)
        px = (pix % cam.width) + 0.5 + cam.filter_offsets(u.ravel())
        py = (pix // cam.width) + 0.5 + cam.filter_offsets(v.ravel())
        origins, dirs, near = cam.rays(px, py)
        origins = origins + dirs * near[:, None]
        hits = tracer.intersect(origins, dirs, tmax=np.maximum(cam.clip_end - near, 0.0))
        sample = np.nonzero(hits.hit)[0]
        prim = hits.prim[sample]
        b1, b2 = hits.u[sample][:, None], hits.v[sample][:, None]
        b0 = 1.0 - b1 - b2
        tri = scene.triangles[prim].astype(np.float64)
        position = b0 * tri[:, 0] + b1 * tri[:, 1] + b2 * tri[:, 2]
        wo = -dirs[sample]
        ng = scene.geometric_normals[prim] if len(prim) else np.zeros((0, 3))
        flip = dot(ng, wo) < 0.0
        ng = np.where(flip[:, None], -ng, ng)
        cn = scene.normals[prim].astype(np.float64)
        ns = normalize(b0 * cn[:, 0] + b1 * cn[:, 1] + b2 * cn[:, 2])
        ns = np.where(flip[:, None], -ns, ns)
        ns = np.where((dot(ns, ns) > 0.5)[:, None], ns, ng)
        mat = scene.material[prim]
        m = scene.materials
        base = m.base_color[mat].astype(np.float64)
        tex_ids = m.texture[mat]
        if (tex_ids >= 0).any():
            uv_c = scene.uvs[prim].astype(np.float64)
            uv = b0 * uv_c[:, 0] + b1 * uv_c[:, 1] + b2 * uv_c[:, 2]
            for t in np.unique(tex_ids[tex_ids >= 0]):
                sel = tex_ids == t
                base[sel] = sample_bilinear(scene.textures[t], uv[sel])[:, :3]
        metallic = m.metallic[mat].astype(np.float64)
        return GBuffer(pixels=pixels, spp=spp, sample=sample, position=position, geometric_normal=ng,
                       shading_normal=ns, wo=wo, prim=prim, material=mat,
                       albedo=np.clip(base, 0.0, 1.0) * (1.0 - metallic)[:, None],
                       roughness=m.roughness[mat].astype(np.float64), metallic=metallic,
                       emission=m.emission[mat].astype(np.float64))

    def __len__(self):
        return len(self.sample)

    def splat(self, values: np.ndarray) -> np.ndarray:
        """Per-pixel means (P,C) of per-hit values (K,C): misses contribute zero, as with a transparent film."""
        values = np.asarray(values, np.float64)
        index = self.sample // self.spp
        sums = [np.bincount(index, weights=values[:, c], minlength=len(self.pixels)) for c in range(values.shape[1])]
        return np.stack(sums, axis=1) / self.spp

    @property
    def coverage(self) -> np.ndarray:
        """Fraction of each pixel's samples that hit geometry: the alpha of a transparent film."""
        return np.bincount(self.sample // self.spp, minlength=len(self.pixels)) / self.spp
