"""Points the camera sees, drawn uniformly over the image: the x_1 of Segovia et al.'s length-2 camera paths.

Misses count as attempts (they see nothing), so ``hit_fraction`` turns means over the hits into means over
camera samples. The points are kept in image order, so ``choose_stratified`` can give each estimate one point
from each of M bands of the image instead of M points that may clump."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..materials.surface import Surface
from .gbuffer import GBuffer


@dataclass
class CameraPoints:
    surface: Surface  # the hits
    attempts: int  # camera samples drawn, hits and misses

    @property
    def hit_fraction(self) -> float:
        return len(self.surface) / self.attempts if self.attempts else 0.0

    def __len__(self):
        return len(self.surface)

    @staticmethod
    def sample(scene, tracer, count: int, rng: np.random.Generator) -> "CameraPoints":
        cam = scene.camera
        pixels = np.sort(rng.integers(0, cam.width * cam.height, count))
        gbuf = GBuffer.build(scene, tracer, pixels, 1, rng)
        return CameraPoints(gbuf.surface, count)

    def choose_stratified(self, rows: int, m: int, rng: np.random.Generator) -> np.ndarray:
        """(rows * m,) indices: for each of ``rows`` estimates, one uniform point in each of m equal bands of the
        hits (in image order). Each index is still uniform over the hits, so means stay unbiased."""
        k = len(self.surface)
        u = (np.arange(m)[None, :] + rng.random((rows, m))) / m
        return np.minimum((u * k).astype(np.int64), k - 1).ravel()
