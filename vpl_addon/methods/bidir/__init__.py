"""Bidirectional Instant Radiosity (Segovia, Iehl, Mitanchey, Peroche, EGSR 2006).

1. Light selection from the camera (sec. 4.1): ``light_selection``.
2. N/2 standard VPLs from light paths and N/2 reverse VPLs from length-2 camera paths (sec. 3.1), the latter with
   the eq. 7 density from M = 5 camera points; each half estimates the indirect light, so both are weighted 1/2.
3. The power each VPL brings to the camera from M = 10 camera paths; N' = N / r VPLs resampled by that power with a
   small uniform floor in the CDF (sec. 3.2, 4).
4. Kept reverse VPLs get their density re-estimated with M = 50 camera points (sec. 4, "a very simple trick").

Light over metal reaches the reverse VPLs and the camera points through camera paths continued to the gather
(``paths.over_metal``), as for every summed-VPL method.

The budget (``MethodSettings.vpls``) is N', the number of VPLs the gather sees.

In a sequence the light paths of the standard VPLs are kept from frame to frame and verified against moving objects and
lights (``sequence.path_verification``, Moreau et al.); the reverse VPLs, the power estimates and the resampling are
done again in every frame in which something moved (the camera included)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...gather.summing import clamp_distance
from ...gather.virtual_lights import REVERSE, VirtualLights
from ...paths.light_paths import trace_until
from ...sequence.path_verification import PlacedFromPaths, follow
from ..base import Method
from . import reverse_vpls
from .light_selection import camera_light_distribution
from .resampling import camera_power, resample


@dataclass
class BidirSettings:
    ratio: float = 10.0  # r = N / N'
    power_paths: int = 10  # M for the power each VPL brings to the camera
    density_paths_coarse: int = 5  # M of eq. 7 while estimating power
    density_paths_fine: int = 50  # M of eq. 7 for the kept reverse VPLs
    # uniform quantity added to the resampling CDF, as a fraction of the mean power. The paper gives no value;
    # with M = 10 power estimates the error in the Cornell box is lowest when it equals the mean
    cdf_floor: float = 1.0
    light_floor: float = 0.01  # the same for the light-selection CDF
    camera_points: int = 4096  # pool of camera points x_j used by the estimates above
    # not from the paper (it does not say): light samples for a reverse VPL's direct light and standard VPLs it
    # gathers for its indirect light; 16 / 256 cut the Cornell box's error by a tenth against 4 / 64
    direct_samples: int = 16
    standard_samples: int = 256
    clamp: float = 0.5  # geometry clamping inside the estimates (as GatherSettings.clamp)


def start(context, settings) -> PlacedFromPaths:
    return PlacedFromPaths()


def advance(state: PlacedFromPaths, context, settings, motion):
    return state.advance(place, context, settings, motion)


def place(context, settings, state: PlacedFromPaths | None = None, motion=None):
    b: BidirSettings = settings.bidir
    scene, tracer, rng = context.scene, context.tracer, context.rng
    kept_count = max(1, int(settings.vpls))
    total = max(2, int(round(kept_count * b.ratio)))
    pool = context.seen(b.camera_points, rng)
    d_min = clamp_distance(scene.surface_area, kept_count, b.clamp)

    light_prob = camera_light_distribution(context.lights, pool, tracer, rng, floor=b.light_floor)
    if state is None:
        standard, paths = trace_until(scene, tracer, context.lights, total // 2, rng, context.max_bounces,
                                      light_prob)
    else:
        paths = follow(state.paths, context, motion, total // 2, settings.path_reuse, settings.path_threshold,
                       light_prob)
        standard = state.paths.lights()
    reverse = reverse_vpls.place(scene, tracer, context.lights, pool, context.seen, total - total // 2, standard,
                                 rng, context.max_bounces, b.density_paths_coarse, b.direct_samples,
                                 b.standard_samples, d_min)
    both = VirtualLights.concat([standard.scaled(0.5), reverse.vpls.scaled(0.5)])
    power = camera_power(both, pool, b.power_paths, tracer, d_min, rng)
    index, weight = resample(power, kept_count, b.cdf_floor, rng)
    kept = both.take(index).scaled(weight)

    # refine the density of the kept reverse VPLs with more camera points
    rev = np.nonzero(kept.kind == REVERSE)[0]
    if len(rev):
        factor = reverse.refine(index[rev] - len(standard), pool, b.density_paths_fine, tracer, rng)
        kept.intensity[rev] *= factor[:, None]
    info = {"light_paths": paths, "reverse_attempts": reverse.attempts, "standard": len(standard),
            "reverse": len(reverse.vpls),
            "kept": len(kept), "kept_reverse_share": kept.reverse_share}
    if state is not None:
        info["light_path_rays"] = state.paths.rays_last_frame
    return kept, info


METHOD = Method(
    "bidir", "Bidirectional IR", "Segovia et al. 2006: VPLs from the lights and from the camera, resampled by the "
                                 "power they bring to the image (robust when light comes through a door)",
    place, BidirSettings, start=start, advance=advance, reuses_light_paths=True)
