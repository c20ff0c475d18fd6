"""Which VPLs are indirectly visible, by mail-boxing (Hedman, Karras, Lehtinen, Sequential Monte Carlo Instant
Radiosity, sec. 3.2.2, Fig. 6).

Each VPL keeps an associated point (its "mailbox") that both the camera and the VPL see; a new VPL is associated
with the directly visible point it was generated from. In a new frame a VPL is valid if its point is still in the
view, seen by the camera, and still sees the VPL. The rest get ``iterations`` (2) chances: every directly visible
point casts a ray toward ``rays_per_point`` (V = 16) randomly chosen still-invalid VPLs; a VPL reached by a ray is
valid again and adopts that point. Not exhaustive, and the sampler is robust to the occasional misclassification.
"""
from __future__ import annotations

import numpy as np

from ...core.sampling import dot


def in_view(camera, points: np.ndarray) -> np.ndarray:
    """Points inside the camera's view window (in front of it)."""
    rot, pos = camera.to_world[:3, :3], camera.to_world[:3, 3]
    local = (np.asarray(points, np.float64) - pos) @ rot
    x0, x1, y0, y1 = camera.window
    if camera.orthographic:
        sx, sy, front = local[:, 0], local[:, 1], local[:, 2] < 0
    else:
        depth = -local[:, 2]
        front = depth > 0
        with np.errstate(divide="ignore", invalid="ignore"):
            sx, sy = local[:, 0] / depth, local[:, 1] / depth
    return front & (sx >= x0) & (sx <= x1) & (sy >= y0) & (sy <= y1)


def seen_by_camera(camera, tracer, points: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """In view and not occluded from the camera."""
    ok = in_view(camera, points)
    rows = np.nonzero(ok)[0]
    if len(rows) == 0:
        return ok
    p, n = points[rows], normals[rows]
    if camera.orthographic:
        dirs = np.broadcast_to(camera.to_world[:3, 2], p.shape).copy()
        dist = np.full(len(rows), np.inf)
    else:
        to_camera = camera.position - p
        dist = np.linalg.norm(to_camera, axis=1)
        dirs = to_camera / np.maximum(dist, 1e-300)[:, None]
    facing = dot(n, dirs) > 0.0
    vis = np.zeros(len(rows), bool)
    vis[facing] = tracer.visible(p[facing], n[facing], dirs[facing], dist[facing])
    ok[rows] = vis
    return ok


def mutually_visible(tracer, a: np.ndarray, a_normal: np.ndarray, b: np.ndarray, b_normal: np.ndarray):
    """Each a[i] and b[i] face each other (their normals) and nothing lies between them."""
    d = b - a
    dist = np.linalg.norm(d, axis=1)
    dirs = d / np.maximum(dist, 1e-300)[:, None]
    ok = (dot(a_normal, dirs) > 0.0) & (dot(b_normal, -dirs) > 0.0) & (dist > 0.0)
    rows = np.nonzero(ok)[0]
    if len(rows):
        ok[rows] = tracer.visible(a[rows], a_normal[rows], dirs[rows], dist[rows], b_normal[rows])
    return ok


def validate(camera, tracer, vpl_position, vpl_normal, mailbox_position, mailbox_normal, points, point_normals,
             rng: np.random.Generator, rays_per_point: int = 16, iterations: int = 2):
    """(valid mask, new mailbox positions, new mailbox normals) of the VPLs, given this frame's directly visible
    points (positions and normals facing the camera)."""
    box_p, box_n = mailbox_position.copy(), mailbox_normal.copy()
    valid = np.zeros(len(vpl_position), bool)
    if len(vpl_position) == 0:
        return valid, box_p, box_n
    seen = seen_by_camera(camera, tracer, box_p, box_n)
    rows = np.nonzero(seen)[0]
    valid[rows] = mutually_visible(tracer, box_p[rows], box_n[rows], vpl_position[rows], vpl_normal[rows])
    for _ in range(iterations):
        invalid = np.nonzero(~valid)[0]
        if len(invalid) == 0 or len(points) == 0:
            break
        origin = np.repeat(np.arange(len(points)), rays_per_point)
        target = invalid[rng.integers(0, len(invalid), len(origin))]
        hit = mutually_visible(tracer, points[origin], point_normals[origin], vpl_position[target],
                               vpl_normal[target])
        found, first = np.unique(target[hit], return_index=True)
        source = origin[np.nonzero(hit)[0][first]]
        valid[found] = True
        box_p[found], box_n[found] = points[source], point_normals[source]
    return valid, box_p, box_n
