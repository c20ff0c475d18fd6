"""Texel samples inside other geometry found and pushed out of it, as Godot's lightmapper "unoccludes" its texels
(``lm_compute.glsl``, ``unocclude``) and Unity marks texels invalid that see back faces.

A sample where a wall stands on the floor lies under the wall, inside it: its light would be the wall's inside,
dark, or (for a one-sided wall) the outside's, which leaks into the room along the seam once the texel is filtered
or dilated. From each sample, rays go a texel's width along the surface (four directions in the tangent plane,
tilted a little off it) and along the normal; one that meets the back of a face (its winding's normal along the
ray) is inside the geometry behind that face. Such a sample moves to the nearest back face it met, a small step
past it along that face's normal: onto the outside of the occluder, where the texel's light is.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from ..core.sampling import normalize

TILT = 0.1  # the tangent rays' lift off the surface (as a share of their length), so they clear coplanar faces
STEP = 0.05  # how far past the back face (in texel widths) a moved sample lands


def _directions(normal: np.ndarray) -> np.ndarray:
    """(K,5,3) unit directions: four along the tangent plane of each ``normal`` (tilted by ``TILT``) and the
    normal itself."""
    helper = np.where(np.abs(normal[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    t = normalize(np.cross(normal, helper))
    b = np.cross(normal, t)
    lift = TILT * normal
    return normalize(np.stack([t + lift, -t + lift, b + lift, -b + lift, normal], axis=1))


def unocclude(surface, footprint: np.ndarray, tracer, face_normals: np.ndarray):
    """(``surface`` with its samples that see back faces moved out of the geometry, the mask of those moved):
    ``footprint`` (K,) the texel width at each sample, ``face_normals`` (T,3) the scene's winding normals."""
    k = len(surface)
    if k == 0:
        return surface, np.zeros(0, bool)
    dirs = _directions(surface.geometric_normal)
    count = dirs.shape[1]
    origin = np.repeat(tracer.offset_origin(surface.position, surface.geometric_normal), count, axis=0)
    flat = dirs.reshape(-1, 3)
    hits = tracer.intersect(origin, flat, np.repeat(footprint, count))
    hit = hits.prim >= 0
    back = np.zeros(len(flat), bool)
    back[hit] = np.einsum("ij,ij->i", face_normals[hits.prim[hit]], flat[hit]) > 0.0
    t = np.where(back, hits.t, np.inf).reshape(k, count)
    nearest = np.argmin(t, axis=1)
    moved = np.isfinite(t[np.arange(k), nearest])
    if not moved.any():
        return surface, moved
    ray = np.nonzero(moved)[0] * count + nearest[moved]
    position = surface.position.copy()
    position[moved] = origin[ray] + flat[ray] * hits.t[ray, None] + \
        face_normals[hits.prim[ray]] * (STEP * footprint[moved])[:, None]
    return dataclasses.replace(surface, position=position), moved
