"""The texel G-buffer of one object: where each texel of its UV map lies on the surface.

Each texel of a ``size`` x ``size`` map holds ``samples`` sub-texel sample points, one in each cell of a square grid
over the texel, jittered by the same offsets in every texel (stratified, so a texel's samples cover it evenly, and
deterministic per seed). A sample inside one of the object's UV triangles is that triangle's point of the same
barycentric coordinates: the rasterisation of the UV map into world positions that lightmappers begin with
(Godot's ``LightmapperRD``, Unity's texel positions). A texel's *coverage* is the share of its samples that some
triangle covers (alpha of the baked image, as Cycles' bake margin reads it); more than one triangle covering a sample
means overlapping UV islands.

Texel (x, y) is at u = (x + 0.5) / size, v = (y + 0.5) / size: y counts from v = 0 up, as Blender holds images.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..core.compiled import kernel
from ..core.tracer import Hits
from ..materials.surface import Surface, shade


@dataclass
class Texels:
    """The samples of one object's texels, in texel order: flat texel index ``y * size + x`` per sample, its
    triangle (a row of the scene's) and barycentric coordinates (of corners 1 and 2), and each texel's coverage."""
    size: int
    samples: int  # sample points per texel
    texel: np.ndarray  # (K,) int64
    prim: np.ndarray  # (K,) int64
    bary: np.ndarray  # (K,2)
    coverage: np.ndarray  # (size*size,) share of a texel's samples inside the UV map, at most 1
    overlap: float  # share of the covered sample points that more than one triangle covers

    def __len__(self):
        return len(self.texel)

    def surface(self, scene) -> Surface:
        """The samples' ``Surface`` seen from the front of their triangles (their winding's side, which a UV map's
        texel stands for), as a ray along the negated face normal finds them."""
        hits = Hits(prim=self.prim.astype(np.int32), t=np.zeros(len(self)), u=self.bary[:, 0], v=self.bary[:, 1])
        tri = scene.triangles[self.prim].astype(np.float64)
        face = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        face /= np.maximum(np.linalg.norm(face, axis=1, keepdims=True), 1e-300)
        return shade(scene, -face, hits, np.arange(len(self)))

    def footprint(self, scene) -> np.ndarray:
        """(K,) the world-space width of one texel at each sample: sqrt(triangle area / its area in texels)."""
        tri = scene.triangles[self.prim].astype(np.float64)
        area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
        uv = bake_uvs(scene)[self.prim].astype(np.float64) * self.size
        e1, e2 = uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]
        texels = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
        return np.sqrt(area / np.maximum(texels, 1e-30))

    def take(self, rows: np.ndarray) -> "Texels":
        """The samples ``rows`` alone (each texel's coverage as before)."""
        return dataclasses.replace(self, texel=self.texel[rows], prim=self.prim[rows], bary=self.bary[rows])

    def first(self, count: int) -> np.ndarray:
        """Rows of the first ``count`` samples of each texel."""
        rank = np.arange(len(self)) - np.searchsorted(self.texel, self.texel)
        return np.nonzero(rank < count)[0]


def bake_uvs(scene) -> np.ndarray:
    """(T,3,2) the UVs lightmaps are baked in: the scene's bake UV map, or the textures' UVs without one."""
    return scene.uvs if scene.bake_uvs is None else scene.bake_uvs


def rasterise(scene, triangles: np.ndarray, size: int, samples: int, rng: np.random.Generator) -> Texels:
    """The ``Texels`` of the scene's ``triangles`` (row indices) in a ``size`` x ``size`` map with ``samples``
    sample points per texel (rounded up to a square number), in the scene's bake UV map (``Scene.bake_uvs``, else
    its ``uvs``); triangles whose UVs span no area cover nothing."""
    grid = max(1, int(np.ceil(np.sqrt(samples))))
    cells = np.stack(np.meshgrid(np.arange(grid), np.arange(grid), indexing="xy"), -1).reshape(-1, 2)
    offsets = (cells + rng.random(cells.shape)) / grid
    uv = np.ascontiguousarray(bake_uvs(scene)[triangles], np.float64) * size
    none = np.zeros(0, np.int64)
    count = _cover(uv, offsets, size, none, none, np.zeros((0, 2)), False, none)
    texel, sub, bary = np.empty(count, np.int64), np.empty(count, np.int64), np.empty((count, 2))
    owner = np.empty(count, np.int64)
    _cover(uv, offsets, size, texel, sub, bary, True, owner)
    order = np.lexsort((sub, texel))  # by texel, then sample: a texel's samples are consecutive
    texel, sub, bary, owner = texel[order], sub[order], bary[order], owner[order]
    point = texel * len(offsets) + sub
    distinct, first = np.unique(point, return_index=True)
    overlap = 1.0 - len(distinct) / max(count, 1)
    coverage = np.bincount(texel[first], minlength=size * size) / len(offsets)
    return Texels(size, len(offsets), texel, np.asarray(triangles, np.int64)[owner], bary, coverage, overlap)


@kernel
def _cover(uv, offsets, size, texel, sub, bary, fill, owner):
    """The sample points inside each UV triangle ``uv`` (T,3,2, in texels): counted, and with ``fill`` written
    (flat texel, sample number, barycentrics, triangle); returns their number."""
    k = 0
    for t in range(len(uv)):
        e1x, e1y = uv[t, 1, 0] - uv[t, 0, 0], uv[t, 1, 1] - uv[t, 0, 1]
        e2x, e2y = uv[t, 2, 0] - uv[t, 0, 0], uv[t, 2, 1] - uv[t, 0, 1]
        det = e1x * e2y - e1y * e2x
        if abs(det) < 1e-12:
            continue
        lo_x = max(int(np.floor(min(uv[t, 0, 0], uv[t, 1, 0], uv[t, 2, 0]))), 0)
        hi_x = min(int(np.floor(max(uv[t, 0, 0], uv[t, 1, 0], uv[t, 2, 0]))), size - 1)
        lo_y = max(int(np.floor(min(uv[t, 0, 1], uv[t, 1, 1], uv[t, 2, 1]))), 0)
        hi_y = min(int(np.floor(max(uv[t, 0, 1], uv[t, 1, 1], uv[t, 2, 1]))), size - 1)
        for y in range(lo_y, hi_y + 1):
            for x in range(lo_x, hi_x + 1):
                for s in range(len(offsets)):
                    dx, dy = x + offsets[s, 0] - uv[t, 0, 0], y + offsets[s, 1] - uv[t, 0, 1]
                    b1 = (dx * e2y - dy * e2x) / det
                    b2 = (e1x * dy - e1y * dx) / det
                    if b1 < 0.0 or b2 < 0.0 or b1 + b2 > 1.0:
                        continue
                    if fill:
                        texel[k], sub[k], owner[k] = y * size + x, s, t
                        bary[k, 0], bary[k, 1] = b1, b2
                    k += 1
    return k
