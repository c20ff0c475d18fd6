"""A set of virtual point lights (VPLs): what every method places and the one gather consumes.

A VPL is a point on a diffuse surface that re-emits light with a cosine lobe about its normal. Its ``intensity`` I
is the radiant intensity along the normal with every sampling weight already applied (light path power x albedo
/ pi / number of paths for Keller's VPLs, radiance / (density x count) for Segovia's reverse VPLs, times the
resampling weight), so the light a VPL sends to a white Lambertian receiver x is
``I cos(theta_vpl) cos(theta_x) / (pi d^2) V`` and the sum over the set estimates the indirect light at x.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.rows import concat_fields, take_fields

STANDARD, REVERSE = 0, 1


@dataclass
class VirtualLights:
    position: np.ndarray  # (N,3)
    normal: np.ndarray  # (N,3) unit, on the side the VPL lights
    intensity: np.ndarray  # (N,3) weighted radiant intensity along the normal
    bounce: np.ndarray  # (N,) diffuse bounces the light made up to and including this VPL (1 = first surface)
    kind: np.ndarray  # (N,) STANDARD (from a light) or REVERSE (from the camera)
    path: np.ndarray  # (N,) index of the light path (standard) or camera path (reverse) it ends
    # (N,3) the radiant intensity a white Lambertian surface would send where the light came over one sharp glossy
    # lobe from its light (light -> glossy -> here: a caustic, ``paths.light_paths``), 0 elsewhere
    caustic: np.ndarray | None = None

    def __post_init__(self):
        if self.caustic is None:
            self.caustic = np.zeros((len(self.position), 3))

    @staticmethod
    def empty() -> "VirtualLights":
        return VirtualLights(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0, np.int32),
                             np.zeros(0, np.int8), np.zeros(0, np.int64))

    @staticmethod
    def concat(parts: list["VirtualLights"]) -> "VirtualLights":
        parts = [p for p in parts if len(p)] or [VirtualLights.empty()]
        return concat_fields(VirtualLights, parts)

    def take(self, index) -> "VirtualLights":
        return take_fields(self, index)

    def scaled(self, factor) -> "VirtualLights":
        """The same lights with intensities multiplied by a scalar or a per-light factor."""
        factor = np.asarray(factor, np.float64)
        factor = factor[:, None] if factor.ndim else factor
        return VirtualLights(self.position, self.normal, self.intensity * factor, self.bounce, self.kind, self.path,
                             self.caustic * factor)

    def __len__(self):
        return len(self.position)

    @property
    def reverse_share(self) -> float:
        """Fraction of the lights that came from the camera (Segovia et al., Table 1)."""
        return float((self.kind == REVERSE).mean()) if len(self) else 0.0
