"""Reverse VPLs (Segovia et al. 2006, sec. 3.1): VPLs at the ends x_2 of length-2 camera paths.

x_1 is a point the camera sees (uniform over the image), x_2 the hit of a cosine-sampled ray from x_1. The set
estimates the indirect light at visible points with weight 1 / (p(x_2) * attempts), where p(x_2) is the density of
reaching x_2 by such a path, estimated by eq. 7 from M camera points x_j:

    p(x_2) = (1/M) sum_j p(x_j -> x_2),   p(x_j -> x_2) = V cos(theta_j) / pi * cos(theta_2) / d^2.

One of the M terms is the path's own x_1 (the others are independent): with it the estimate is the density of x_2
given the M points, had x_2 come from any one of them at random, so 1 / p is an unbiased weight (the mixture
density of multiple importance sampling with the balance heuristic) and never infinite. The own term needs no
shadow ray: the ray that found x_2 joins the two (a shadow ray there can miss its end by the offsets and leave a
weight of 1e300, which then takes every draw of the resampling).
The VPL's outgoing radiance is diffuse: albedo x (direct light + light of the standard VPLs), the latter by shadow
rays to a random subset of the standard VPLs (the bidirectional estimate the paper describes), both also as they
arrive over metal (``paths.over_metal``: a camera path continued from x_2 through metallic surfaces)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...core.sampling import dot
from ...gather.summing import sum_pairs
from ...gather.virtual_lights import REVERSE, VirtualLights
from ...lights.direct import diffuse_direct
from ...materials.surface import Surface, diffuse_bounce
from ...paths.camera_points import CameraPoints
from ...paths.over_metal import over_metal


def path_density(x1, x2, tracer=None) -> np.ndarray:
    """p(x_1 -> x_2) per row: cosine sampling at x_1 turned into area density at x_2, times visibility (traced
    by ``tracer``; None for pairs joined by the ray that found x_2, visible by construction).

    x1 and x2 are (position, geometric normal, shading normal) triples of (K,3) arrays."""
    p1, ng1, ns1 = x1
    p2, ng2, _ = x2
    w = p2 - p1
    d2 = dot(w, w)
    d = np.sqrt(d2)
    w = w / np.maximum(d, 1e-300)[:, None]
    cos1 = dot(ns1, w)
    cos2 = np.abs(dot(ng2, w))
    ok = np.nonzero((cos1 > 0.0) & (dot(ng1, w) > 0.0) & (d > 0.0))[0]
    out = np.zeros(len(p1))
    if len(ok):
        vis = 1.0 if tracer is None else tracer.visible(p1[ok], ng1[ok], w[ok], d[ok], ng2[ok])
        out[ok] = vis * cos1[ok] / np.pi * cos2[ok] / np.maximum(d2[ok], 1e-300)
    return out


def density(positions, geometric_normals, own_x1, camera_points: CameraPoints, m: int, tracer, rng) -> np.ndarray:
    """Eq. 7 with M = m camera points, one of them the path's own x_1 (``own_x1``: triple of arrays)."""
    k = len(positions)
    if k == 0:
        return np.zeros(0)
    total = path_density(own_x1, (positions, geometric_normals, None))
    if m > 1 and len(camera_points):
        j = camera_points.choose_stratified(k, m - 1, rng)
        s = camera_points.surface
        rep = np.repeat(np.arange(k), m - 1)
        others = path_density((s.position[j], s.geometric_normal[j], s.shading_normal[j]),
                              (positions[rep], geometric_normals[rep], None), tracer)
        total = total + np.bincount(rep, weights=others, minlength=k)
    return camera_points.hit_fraction * total / m


@dataclass
class ReverseSet:
    vpls: VirtualLights  # weighted by 1 / (p attempts)
    geometric_normal: np.ndarray  # (K,3) at x_2
    x1: tuple  # (position, geometric normal, shading normal) of each path's x_1
    density: np.ndarray  # (K,) the p(x_2) used in the weights
    attempts: int  # camera samples drawn, misses included

    def refine(self, rows: np.ndarray, camera_points, m: int, tracer, rng) -> np.ndarray:
        """Factor p_old / p_new for re-weighting the lights ``rows`` with a density from ``m`` camera points."""
        own = tuple(a[rows] for a in self.x1)
        fine = density(self.vpls.position[rows], self.geometric_normal[rows], own, camera_points, m, tracer, rng)
        return self.density[rows] / np.maximum(fine, 1e-300)


def place(scene, tracer, lights, camera_points, seen, target: int, standard: VirtualLights, rng, max_bounces: int,
          density_paths: int, direct_samples: int, standard_samples: int, d_min: float) -> ReverseSet:
    """About ``target`` reverse VPLs from length-2 camera paths whose x_1 are drawn by ``seen(count, rng)``
    (``MethodContext.seen``), their density estimated with the pool ``camera_points``."""
    empty = ReverseSet(VirtualLights.empty(), np.zeros((0, 3)), (np.zeros((0, 3)),) * 3, np.zeros(0), 0)
    if target <= 0 or max_bounces <= 0:
        return empty
    parts, attempts, found = [], 0, 0
    while found < target and attempts < 64 * target + 1024:
        count = max(64, int((target - found) / max(found / attempts, 0.05)) if attempts else target)
        pts = seen(count, rng)
        attempts += count
        s1 = pts.surface
        s2, src, _, _ = diffuse_bounce(scene, tracer, s1, rng)
        parts.append((s2, (s1.position[src], s1.geometric_normal[src], s1.shading_normal[src])))
        found += len(s2)
    if not parts:
        return empty
    s2 = Surface.concat([p[0] for p in parts])
    x1 = tuple(np.concatenate([p[1][i] for p in parts]) for i in range(3))
    feeding = np.nonzero(standard.bounce <= max_bounces - 1)[0]  # keep the whole path within the bounce limit

    def standard_light(points):
        """Light of the standard VPLs at ``points``: a uniform sample of the feeding ones, scaled to their sum."""
        k = len(points)
        if len(feeding) == 0 or standard_samples <= 0:
            return np.zeros((k, 3))
        rep = np.repeat(np.arange(k), standard_samples)
        vi = feeding[rng.integers(0, len(feeding), k * standard_samples)]
        return sum_pairs(points, rep, standard, vi, tracer, d_min, rep, k) * (len(feeding) / standard_samples)
    # x_2's own light also comes over metal (the lights' and the standard VPLs', ``paths.over_metal``)
    incident = diffuse_direct(s2, lights, tracer, direct_samples, rng) + standard_light(s2) + \
        over_metal(s2, None, scene, tracer, lights, rng, standard_light, max_bounces - 1)
    k = len(s2)
    p = density(s2.position, s2.geometric_normal, x1, camera_points, density_paths, tracer, rng)
    weight = 1.0 / np.maximum(p * attempts, 1e-300)
    vpls = VirtualLights(s2.position, s2.smooth_normal, s2.albedo * incident * weight[:, None],
                         np.ones(k, np.int32), np.full(k, REVERSE, np.int8), np.arange(k))
    return ReverseSet(vpls, s2.geometric_normal, x1, p, attempts)
