"""The baked texels as the view that methods placing by the camera place by: bidir's camera points x_1 (Segovia et
al. 2006, sec. 3.1 and 4) and smc's directly visible points X (Hedman et al. 2016, Algorithm 1, line 3) drawn over
the sample points of every baked object's texels in place of the pixels (``MethodContext.view_points``), so that
their VPLs serve the surfaces that are baked, not what the scene's camera happens to see.

Every texel sample lies on a surface, so none misses (``CameraPoints.hit_fraction`` 1): a camera point's share of
the image becomes a sample's share of all the baked texel samples, the lightmap being the image.
"""
from __future__ import annotations

import numpy as np

from ..materials.surface import Surface
from ..paths.camera_points import CameraPoints
from .texels import Texels
from .unocclude import unocclude


class TexelView:
    """Points drawn uniformly over the sample points of ``parts`` (each baked object's ``Texels``), moved out of
    other geometry as the bake moves them (``unocclude``), in the order of the parts and their texels."""

    def __init__(self, scene, parts: list[Texels], tracer, face_normals: np.ndarray):
        self.scene, self.parts, self.tracer, self.face_normals = scene, parts, tracer, face_normals
        self.starts = np.cumsum([0] + [len(texels) for texels in parts])

    def __call__(self, count: int, rng: np.random.Generator) -> CameraPoints:
        rows = np.sort(rng.integers(0, self.starts[-1], count)) if self.starts[-1] else np.zeros(0, np.int64)
        surfaces = []
        for texels, start, end in zip(self.parts, self.starts[:-1], self.starts[1:]):
            chosen = texels.take(rows[(rows >= start) & (rows < end)] - start)
            surfaces.append(unocclude(chosen.surface(self.scene), chosen.footprint(self.scene), self.tracer,
                                      self.face_normals)[0])
        return CameraPoints(Surface.concat(surfaces), len(rows))
