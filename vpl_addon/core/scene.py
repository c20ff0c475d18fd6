"""The engine's scene: world-space geometry, materials, lights, world and camera as numpy arrays.

Everything downstream of extraction reads only this. It is built either from Blender (``operators/extract.py``)
or directly in code (tests, stress scenes). ``Scene.build`` sanitises the input on purpose: triangles with
non-finite corners or zero area are dropped (and counted per object so the caller can name them), shading normals
that are missing, non-finite or zero fall back to the geometric normal, non-finite UVs become 0, non-finite or
negative texels become 0 and a material whose texture does not exist uses its Base Color.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from .camera import Camera

if TYPE_CHECKING:  # an annotation only: the core layer imports nothing above it (``lights`` builds on ``core``)
    from ..lights import Light


@dataclass
class Materials:
    """Material table indexed by the per-triangle material id (row 0 is the fallback grey diffuse)."""

    names: list[str]
    base_color: np.ndarray  # (M,3) linear RGB albedo of the diffuse lobe
    roughness: np.ndarray  # (M,)
    metallic: np.ndarray  # (M,)
    emission: np.ndarray  # (M,3) emitted radiance, W/(m^2 sr): Emission Color x Strength
    texture: np.ndarray  # (M,) int index into Scene.textures of the base colour, -1 for none
    specular_tint: np.ndarray  # (M,3) F82 tint of the metallic lobe (white: plain Schlick Fresnel)

    @staticmethod
    def make(rows: list[dict]) -> "Materials":
        """Rows of {name, base_color, roughness, metallic, emission, texture, specular_tint}; missing keys take
        defaults."""
        rows = [{"name": "VPL fallback grey"}] + list(rows)

        def col(key, default, dtype=np.float32):
            return np.array([r.get(key, default) for r in rows], dtype=dtype)

        m = Materials(
            names=[r["name"] for r in rows],
            base_color=col("base_color", (0.8, 0.8, 0.8)).reshape(-1, 3),
            roughness=col("roughness", 0.5),
            metallic=col("metallic", 0.0),
            emission=col("emission", (0.0, 0.0, 0.0)).reshape(-1, 3),
            texture=col("texture", -1, np.int32),
            specular_tint=col("specular_tint", (1.0, 1.0, 1.0)).reshape(-1, 3),
        )
        for a in (m.base_color, m.roughness, m.metallic, m.emission, m.specular_tint):
            np.nan_to_num(a, copy=False, nan=0.0, posinf=0.0, neginf=0.0)
        np.clip(m.base_color, 0.0, 1.0, out=m.base_color)
        np.clip(m.roughness, 0.0, 1.0, out=m.roughness)
        np.clip(m.metallic, 0.0, 1.0, out=m.metallic)
        np.clip(m.specular_tint, 0.0, 1.0, out=m.specular_tint)
        np.maximum(m.emission, 0.0, out=m.emission)
        return m

    @property
    def diffuse_albedo(self) -> np.ndarray:
        """Albedo of the diffuse lobe: what Cycles' ``Diffuse Color`` pass holds (metals have none)."""
        return self.base_color * (1.0 - self.metallic)[:, None]

    @property
    def glossy(self) -> bool:
        """Whether any material has a metallic (GGX) lobe: without one, nothing glossy is computed."""
        return bool((self.metallic > 0.0).any())


@dataclass
class Environment:
    """The world as an equirectangular map (Blender's Environment Texture): radiance times the Background's strength
    and the rotation taking a world direction to the map's lookup direction (the Mapping node's)."""
    image: np.ndarray  # (H,W,3) float32 linear radiance, row 0 = bottom (v = 0)
    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))  # (3,3)

    @staticmethod
    def checked(image, rotation=None) -> "Environment | None":
        """The map made safe (NaN, infinite and negative texels 0; a rotation that is not one: none), or None for a
        map without texels or light."""
        image = np.asarray(image, np.float32)
        if image.ndim != 3 or image.shape[0] == 0 or image.shape[1] == 0 or image.shape[2] < 3:
            return None
        image = np.maximum(np.nan_to_num(image[..., :3], nan=0.0, posinf=0.0, neginf=0.0), 0.0)
        if not image.max() > 0.0:
            return None
        r = np.eye(3) if rotation is None else np.asarray(rotation, np.float64).reshape(3, 3)
        if not (np.isfinite(r).all() and np.allclose(r @ r.T, np.eye(3), atol=1e-6)):
            r = np.eye(3)
        return Environment(image, r)


@dataclass
class Scene:
    triangles: np.ndarray  # (T,3,3) float32 world-space corners
    normals: np.ndarray  # (T,3,3) float32 per-corner shading normals (unit)
    uvs: np.ndarray  # (T,3,2) float32
    material: np.ndarray  # (T,) int32 index into materials
    object_id: np.ndarray  # (T,) int32 index into object_names
    object_names: list[str]
    materials: Materials
    lights: list[Light]
    camera: Camera
    world: np.ndarray = field(default_factory=lambda: np.zeros(3, np.float32))  # background radiance RGB
    environment: Environment | None = None  # the world as a map (then ``world`` is not used)
    textures: list[np.ndarray] = field(default_factory=list)  # (h,w,3) float32 linear, row 0 = bottom (v = 0)
    dropped: dict[str, int] = field(default_factory=dict)  # object name -> triangles dropped by build()
    max_bounces: int = 8  # diffuse bounce limit of light paths (Cycles' min(max_bounces, diffuse_bounces))

    @staticmethod
    def build(triangles, materials: Materials, lights, camera, *, normals=None, uvs=None, material=None,
              object_id=None, object_names=None, world=(0.0, 0.0, 0.0), environment=None, textures=(),
              max_bounces=8) -> "Scene":
        """Assemble a scene from raw arrays, dropping triangles that cannot be traced or shaded."""
        tri = np.asarray(triangles, np.float64).reshape(-1, 3, 3)
        n = len(tri)
        material = np.zeros(n, np.int32) if material is None else np.asarray(material, np.int32).reshape(n)
        object_id = np.zeros(n, np.int32) if object_id is None else np.asarray(object_id, np.int32).reshape(n)
        object_names = list(object_names or ["object"])
        normals = None if normals is None else np.asarray(normals, np.float64).reshape(n, 3, 3)
        uvs = np.zeros((n, 3, 2)) if uvs is None else np.asarray(uvs, np.float64).reshape(n, 3, 2)

        ng = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        area2 = np.linalg.norm(ng, axis=1)
        scale = np.abs(tri).max(axis=(1, 2)) if n else np.zeros(0)
        with np.errstate(invalid="ignore"):
            keep = np.isfinite(tri).all(axis=(1, 2)) & np.isfinite(area2) & (area2 > (scale * 1e-6) ** 2)
        dropped = {}
        for oid, count in zip(*np.unique(object_id[~keep], return_counts=True)):
            dropped[object_names[oid] if 0 <= oid < len(object_names) else str(oid)] = int(count)
        tri, ng, area2, uvs, material, object_id = (a[keep] for a in (tri, ng, area2, uvs, material, object_id))
        ng = ng / area2[:, None]
        if normals is None:
            sn = np.repeat(ng[:, None, :], 3, axis=1)
        else:
            sn = normals[keep]
            length = np.linalg.norm(sn, axis=2, keepdims=True)
            with np.errstate(invalid="ignore", divide="ignore"):
                sn = sn / length
            bad = ~(np.isfinite(sn).all(axis=2) & (length[..., 0] > 1e-12))
            sn = np.where(bad[..., None], ng[:, None, :], sn)
        uvs = np.nan_to_num(uvs, nan=0.0, posinf=0.0, neginf=0.0)
        material = np.where((material >= 0) & (material < len(materials.names)), material, 0).astype(np.int32)
        textures = [np.maximum(np.nan_to_num(np.asarray(t, np.float32), nan=0.0, posinf=0.0), 0.0)
                    for t in textures]
        tex = materials.texture
        usable = np.array([i < 0 or (i < len(textures) and textures[i].ndim == 3 and textures[i].size > 0)
                           for i in tex], bool)
        if not usable.all():  # a copy: the caller's table stays as it was
            materials = replace(materials, texture=np.where(usable, tex, -1).astype(np.int32))

        return Scene(triangles=tri.astype(np.float32), normals=sn.astype(np.float32), uvs=uvs.astype(np.float32),
                     material=material, object_id=object_id.astype(np.int32), object_names=object_names,
                     materials=materials, lights=[l for l in lights if l.is_active], camera=camera,
                     world=np.maximum(np.nan_to_num(np.asarray(world, np.float32), nan=0.0, posinf=0.0), 0.0),
                     environment=None if environment is None else Environment.checked(environment.image,
                                                                                       environment.rotation),
                     textures=textures, dropped=dropped,
                     max_bounces=max(0, int(max_bounces)))

    @property
    def geometric_normals(self) -> np.ndarray:
        """(T,3) unit face normals from the corner winding (counter-clockwise = front, as in Blender)."""
        tri = self.triangles.astype(np.float64)
        ng = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        return ng / np.linalg.norm(ng, axis=1, keepdims=True)

    @property
    def triangle_areas(self) -> np.ndarray:
        tri = self.triangles.astype(np.float64)
        return 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)

    @property
    def surface_area(self) -> float:
        return float(self.triangle_areas.sum())

    @property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Axis-aligned box of the geometry (a unit box at the origin for an empty scene)."""
        if len(self.triangles) == 0:
            return -np.ones(3), np.ones(3)
        pts = self.triangles.reshape(-1, 3).astype(np.float64)
        return pts.min(axis=0), pts.max(axis=0)
