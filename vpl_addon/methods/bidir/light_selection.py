"""Camera-driven light selection (Segovia et al. 2006, sec. 4.1, after Dietrich et al. 2003).

Each light's direct contribution is measured at points the camera sees; light paths then start from lights in
proportion to it, plus a small uniform floor so no light that could matter gets probability zero (unbiased). Lights
that barely reach the visible surfaces are rarely chosen."""
from __future__ import annotations

import numpy as np

from ...core.color import LUMINANCE
from ...lights.direct import diffuse_direct


def camera_light_distribution(lights, camera_points, tracer, rng, samples: int = 1, floor: float = 0.01):
    """Selection probabilities (L,) of the lights of a ``LightSet``."""
    if len(lights) <= 1 or len(camera_points) == 0:
        return lights.prob.copy()
    seen = np.array([float((diffuse_direct(camera_points.surface, lights.only(i), tracer, samples, rng)
                            @ LUMINANCE).mean()) for i in range(len(lights))])
    if seen.sum() <= 0.0:
        return lights.prob.copy()
    weight = seen + floor * seen.mean()
    return weight / weight.sum()
