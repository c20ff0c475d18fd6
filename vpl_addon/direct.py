"""Direct diffuse lighting by next-event estimation: Cycles' ``Diffuse Direct`` pass.

For each shading point, ``samples`` light samples: a light chosen in proportion to its power (``LightSet``), a point
or direction on it, one shadow ray. The result is the outgoing radiance of a white Lambertian surface,
(1/pi) * integral L_i cos(theta) d omega, which is how Cycles defines the pass (light reflected by the diffuse
BSDF, divided by the diffuse colour).

When the points are the samples of pixels (the G-buffer), the caller can hand in the light-sample numbers: those of
all samples of a pixel then form one scrambled Sobol net (``sampling.stratified_2d``) dealt out in random order,
so a pixel's shadow rays cover the light evenly instead of clumping as independent numbers do.
"""
from __future__ import annotations

import numpy as np

from .sampling import dot

RAYS_PER_BATCH = 1 << 20


def diffuse_direct(surface, lights, tracer, samples: int, rng: np.random.Generator,
                   numbers: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """(K,3) direct diffuse radiance at each point of a ``Surface``, averaged over ``samples`` light samples.

    ``numbers`` = (u1, u2), each (K, samples): the uniform numbers of every light sample, instead of independent
    ones."""
    k = len(surface)
    out = np.zeros((k, 3))
    if k == 0 or len(lights) == 0 or samples <= 0:
        return out
    p = surface.position
    ng = surface.geometric_normal
    ns = surface.shading_normal
    for lo in range(0, k, max(1, RAYS_PER_BATCH // samples)):
        hi = min(k, lo + max(1, RAYS_PER_BATCH // samples))
        idx = np.repeat(np.arange(lo, hi), samples)
        # stratify the light-selection and position numbers over the samples of one point
        strata = (np.tile(np.arange(samples), hi - lo) + rng.random(len(idx))) / samples
        if numbers is None:
            u1, u2 = rng.random(len(idx)), rng.random(len(idx))
        else:
            u1, u2 = numbers[0][lo:hi].ravel(), numbers[1][lo:hi].ravel()
        wi, dist, weight, target_n = lights.sample_incident(p[idx], ns[idx], strata, u1, u2)
        cos = dot(ns[idx], wi)
        ok = (cos > 0.0) & (dot(ng[idx], wi) > 0.0) & (weight.max(axis=1) > 0.0) & np.isfinite(weight).all(axis=1)
        sel = np.nonzero(ok)[0]
        if len(sel):
            vis = tracer.visible(p[idx[sel]], ng[idx[sel]], wi[sel], dist[sel], target_n[sel])
            contrib = weight[sel] * (cos[sel] * vis / np.pi)[:, None]
            for c in range(3):
                out[lo:hi, c] += np.bincount(idx[sel] - lo, weights=contrib[:, c], minlength=hi - lo)
    return out / samples
