"""Midpoint subdivision of a whole scene, for scaling runs: every triangle becomes four (corners, normals, UVs,
tangents and colours interpolated at the edge midpoints), so the surface and the image stay the same while the
triangle count grows."""
from __future__ import annotations

import dataclasses

import numpy as np

from ..core.scene import Scene


def _split(corners: np.ndarray) -> np.ndarray:
    """(T,3,C) per-corner values -> (4T,3,C): the corner triangles and the middle one of each."""
    a, b, c = corners[:, 0], corners[:, 1], corners[:, 2]
    ab, bc, ca = (a + b) / 2, (b + c) / 2, (c + a) / 2
    return np.stack([np.stack(t, 1) for t in ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))], 1) \
        .reshape(-1, 3, corners.shape[2])


def subdivide(scene: Scene, levels: int = 1) -> Scene:
    """The scene with each triangle split into 4**levels (shading normals renormalised)."""
    s = scene
    for _ in range(levels):
        normals = _split(s.normals.astype(np.float64))
        normals /= np.maximum(np.linalg.norm(normals, axis=2, keepdims=True), 1e-12)
        corners = {name: None if getattr(s, name) is None else
                   _split(getattr(s, name).astype(np.float64)).astype(np.float32)
                   for name in ("triangles", "uvs", "tangents", "colors")}
        s = dataclasses.replace(s, normals=normals.astype(np.float32), material=np.repeat(s.material, 4),
                                object_id=np.repeat(s.object_id, 4), **corners)
    return s


def levels_for(triangles: int, smallest: int = 8000, largest: int = 1_200_000) -> list[int]:
    """Subdivision levels whose triangle counts (triangles * 4**level) lie in [smallest, largest]."""
    return [k for k in range(16) if smallest <= triangles * 4 ** k <= largest]
