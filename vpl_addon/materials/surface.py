"""What a ray finds where it hits: position, normals turned toward the ray's origin side, material terms.

The one place that turns embree hits into shading data; the G-buffer, light paths and camera paths all use it.
Surfaces are two-sided (as in Cycles): both normals are flipped to face the incoming ray.
"""
from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from ..core.sampling import cosine_hemisphere, dot, normalize
from .microfacet import f82_b
from .textures import sample_bilinear


@dataclass
class Surface:
    position: np.ndarray  # (K,3)
    geometric_normal: np.ndarray  # (K,3) facing the incoming ray
    shading_normal: np.ndarray  # (K,3) facing the incoming ray's side
    prim: np.ndarray  # (K,) triangle index
    material: np.ndarray  # (K,)
    albedo: np.ndarray  # (K,3) diffuse albedo (base colour or texture x (1 - metallic))
    roughness: np.ndarray  # (K,)
    metallic: np.ndarray  # (K,) weight of the metallic GGX lobe (``microfacet``)
    emission: np.ndarray  # (K,3)
    specular: np.ndarray  # (K,3) F0 of the metallic lobe: the base colour (or texture)
    edge: np.ndarray  # (K,3) b of the F82-tint Fresnel (``microfacet.f82_b``)
    incident: np.ndarray  # (K,3) unit direction of the ray that found the point (the viewer is at -incident)

    def __len__(self):
        return len(self.prim)

    def take(self, rows) -> "Surface":
        return Surface(*(getattr(self, f.name)[rows] for f in fields(Surface)))

    @staticmethod
    def concat(parts: list["Surface"]) -> "Surface":
        return Surface(*(np.concatenate([getattr(p, f.name) for p in parts]) for f in fields(Surface)))


def shade(scene, dirs: np.ndarray, hits, rows: np.ndarray) -> Surface:
    """Surface data at ``hits`` for the rays ``rows`` (which must have hit), given their unit directions."""
    prim = hits.prim[rows]
    b1, b2 = hits.u[rows][:, None], hits.v[rows][:, None]
    b0 = 1.0 - b1 - b2
    tri = scene.triangles[prim].astype(np.float64)
    position = b0 * tri[:, 0] + b1 * tri[:, 1] + b2 * tri[:, 2]
    ng = normalize(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]))  # of these triangles only: O(hits)
    flip = dot(ng, dirs[rows]) > 0.0
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
    base = np.clip(base, 0.0, 1.0)
    return Surface(position=position, geometric_normal=ng, shading_normal=ns, prim=prim, material=mat,
                   albedo=base * (1.0 - metallic)[:, None],
                   roughness=m.roughness[mat].astype(np.float64), metallic=metallic,
                   emission=m.emission[mat].astype(np.float64), specular=base,
                   edge=f82_b(base, m.specular_tint[mat].astype(np.float64)), incident=dirs[rows])


def bounce(scene, tracer, surface: Surface, dirs: np.ndarray):
    """Rays from the points of ``surface`` along ``dirs``, offset off it; rays that would leave below the true
    surface are dropped. Returns (what the rays hit, the index of the point each hit came from)."""
    leave = np.nonzero(dot(dirs, surface.geometric_normal) > 0.0)[0]
    hits = tracer.intersect(tracer.offset_origin(surface.position[leave], surface.geometric_normal[leave]),
                            dirs[leave])
    rows = np.nonzero(hits.hit)[0]
    return shade(scene, dirs[leave], hits, rows), leave[rows]


def diffuse_bounce(scene, tracer, surface: Surface, rng: np.random.Generator):
    """One cosine-weighted ray (the diffuse BSDF's sample) from every point of ``surface`` (``bounce``). Returns
    (what the rays hit, the index of the point each hit came from, the directions of all points, their cos
    theta)."""
    dirs, cos = cosine_hemisphere(rng.random(len(surface)), rng.random(len(surface)), surface.shading_normal)
    return (*bounce(scene, tracer, surface, dirs), dirs, cos)
