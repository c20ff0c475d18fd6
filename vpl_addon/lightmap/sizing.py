"""Each object's map size from a texel density: the number of texels a metre of its surface spans, as game
engines set lightmap resolution (Unity's texels per unit, Godot's texel size), so that large and small objects are
lit at the same detail in one bake.

An object whose surface area is A m^2 and whose UV islands cover the share c of its map spans sqrt(A / c) metres
per map side; at d texels a metre its side is d sqrt(A / c) texels, rounded to the nearest power of two (the sizes
textures are made in) and kept between ``MIN_SIZE`` and the largest size a bake takes.
"""
from __future__ import annotations

import numpy as np

MIN_SIZE = 4


def density_size(scene, triangles: np.ndarray, uv: np.ndarray, density: float, largest: int) -> int:
    """The side of the map of the scene's ``triangles`` (row indices) with UVs ``uv`` (T,3,2) at ``density``
    texels a metre: ``MIN_SIZE`` for an object without UV area (whose map holds nothing)."""
    area = float(scene.triangle_areas[triangles].sum())
    edges = uv[:, 1:] - uv[:, :1]
    uv_area = float(np.abs(edges[:, 0, 0] * edges[:, 1, 1] - edges[:, 0, 1] * edges[:, 1, 0]).sum()) / 2.0
    if not (np.isfinite(area) and np.isfinite(uv_area)) or area <= 0.0 or uv_area <= 0.0:
        return MIN_SIZE
    side = density * np.sqrt(area / min(uv_area, 1.0))
    return int(np.clip(2 ** np.round(np.log2(max(side, 1.0))), MIN_SIZE, largest))
