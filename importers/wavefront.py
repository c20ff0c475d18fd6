"""Wavefront OBJ -> numpy polygons (positions, per-corner uvs and normals), no bpy.

Mitsuba reads only positions, texture coordinates, normals and faces of an OBJ (materials come from the scene XML),
so that is all this reads; ``shared_scenes`` turns it into a Blender mesh. Faces keep their corner count (Blender
meshes hold n-gons); negative (relative) indices are resolved.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class ObjMesh:
    positions: np.ndarray  # (V,3) float64
    face_sizes: np.ndarray  # (F,) int32, corners per face
    corner_vertex: np.ndarray  # (C,) int32 into positions
    corner_uv: np.ndarray | None  # (C,2) or None when the file has no texture coordinates
    corner_normal: np.ndarray | None  # (C,3) or None when the file has no normals

    @property
    def triangle_count(self) -> int:
        return int(np.sum(self.face_sizes - 2))


def read_obj(path: str) -> ObjMesh:
    v, vt, vn = [], [], []
    sizes, cv, ct, cn = [], [], [], []
    with open(path, encoding="utf-8", errors="replace") as f:
        for line in f:
            if line.startswith("v "):
                v.append(line.split()[1:4])
            elif line.startswith("vt"):
                vt.append(line.split()[1:3])
            elif line.startswith("vn"):
                vn.append(line.split()[1:4])
            elif line.startswith("f "):
                corners = line.split()[1:]
                if len(corners) < 3:
                    continue
                sizes.append(len(corners))
                for c in corners:
                    parts = c.split("/")
                    cv.append(_index(parts[0], len(v)))
                    ct.append(_index(parts[1], len(vt)) if len(parts) > 1 and parts[1] else -1)
                    cn.append(_index(parts[2], len(vn)) if len(parts) > 2 and parts[2] else -1)
    positions = np.array(v, np.float64).reshape(-1, 3)
    ct_a, cn_a = np.array(ct, np.int64), np.array(cn, np.int64)
    uv = None
    if vt and len(ct_a) and (ct_a >= 0).all():
        uv = np.array(vt, np.float64).reshape(-1, 2)[ct_a]
    normal = None
    if vn and len(cn_a) and (cn_a >= 0).all():
        normal = np.array(vn, np.float64).reshape(-1, 3)[cn_a]
    return ObjMesh(positions, np.array(sizes, np.int32), np.array(cv, np.int32), uv, normal)


def _index(token: str, count: int) -> int:
    i = int(token)
    return i - 1 if i > 0 else count + i
