"""What moved between two frames of an animation, read from the extracted scenes alone.

Moreau, Doggett and Sintorn (Path Verification for Dynamic Indirect Illumination, sec. 3) re-trace only the light
path segments that cross the bounding boxes of objects that moved and re-emit only from lights that changed; Hedman
et al. (Sequential Monte Carlo Instant Radiosity, sec. 3.2) revalidate VPLs when the camera moves. Both need the
same answer, given here: a ``Snapshot`` digests each object's triangles, each light's parameters, the camera and
the shading (materials, textures, world, bounce limit) of one frame, and ``Motion.between`` compares two of them.
Digests are exact (bytes of the float arrays), so a frame in which nothing changed is recognised as static and
costs nothing downstream (no light paths, no BVH).
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass, field, fields, is_dataclass

import numpy as np

from .persisted import record


def _digest(*arrays) -> str:
    h = hashlib.blake2b(digest_size=16)
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(str((a.dtype.str, a.shape)).encode())
        h.update(a.tobytes())
    return h.hexdigest()


def light_digest(light) -> str:
    """Digest of a light's type and every parameter (position, direction, power, size, ...)."""
    items = [(f.name, getattr(light, f.name)) for f in fields(light)] if is_dataclass(light) else \
        sorted(vars(light).items())
    h = hashlib.blake2b(digest_size=16)
    h.update(type(light).__name__.encode())
    for name, value in items:
        h.update(name.encode())
        try:
            h.update(_digest(np.asarray(value, np.float64)).encode())
        except (TypeError, ValueError):  # names, flags: their text
            h.update(repr(value).encode())
    return h.hexdigest()


@record
@dataclass
class Snapshot:
    """Digests of one frame's scene."""
    objects: dict[str, str]  # object name -> digest of its triangles and normals
    bounds: dict[str, tuple[np.ndarray, np.ndarray]]  # object name -> (lo, hi) of its triangles
    lights: list[str]  # digest per light, in scene order
    camera: str
    shading: str  # materials, textures, world, bounce limit
    triangles: str  # the whole triangle array (what the BVH is built from)

    @staticmethod
    def of(scene) -> "Snapshot":
        objects, bounds = {}, {}
        ids = np.asarray(scene.object_id)
        order = np.argsort(ids, kind="stable")
        cuts = np.flatnonzero(np.diff(ids[order])) + 1
        for rows in np.split(order, cuts) if len(order) else []:
            name = scene.object_names[ids[rows[0]]] if 0 <= ids[rows[0]] < len(scene.object_names) else str(ids[rows[0]])
            tri = scene.triangles[rows]
            objects[name] = _digest(tri, scene.normals[rows], scene.material[rows])
            pts = tri.reshape(-1, 3).astype(np.float64)
            bounds[name] = (pts.min(axis=0), pts.max(axis=0))
        m = scene.materials
        maps = np.frombuffer(repr(m.maps).encode(), np.uint8)  # the same text in every process (not hash())
        shading = _digest(m.base_color, m.roughness, m.metallic, m.emission, m.specular_tint, m.ior, m.specular,
                          m.alpha, m.transmission, maps, *m.map_of.values(), np.asarray(scene.world),
                          *(() if m.metal_color is None else (m.metal_color,)),
                          *(() if m.fresnel_mix is None else (m.fresnel_mix,)),
                          *(() if m.mix_other is None else (m.mix_other, m.mix_factor)),
                          np.array([scene.max_bounces]), *scene.textures, scene.uvs,
                          *(() if scene.tangents is None else (scene.tangents,)),
                          *(() if scene.colors is None else (scene.colors,)),
                          *(() if scene.environment is None else (scene.environment.image, scene.environment.rotation)))
        cam = scene.camera
        camera = _digest(np.asarray(cam.to_world, np.float64), np.asarray(cam.window, np.float64),
                         np.array([cam.width, cam.height, float(cam.orthographic), *cam.optics]))
        return Snapshot(objects, bounds, [light_digest(l) for l in scene.lights], camera, shading,
                        _digest(scene.triangles))


@record
@dataclass
class Motion:
    """The difference between two snapshots (``previous`` None: the first frame, everything is new)."""
    first: bool = False
    moved_objects: list[str] = field(default_factory=list)  # changed, appeared or vanished
    boxes: list[tuple[np.ndarray, np.ndarray]] = field(default_factory=list)  # old and new box of each
    changed_lights: list[int] = field(default_factory=list)  # indices into this frame's lights
    lights_changed: bool = False  # any light changed, appeared or vanished
    camera_moved: bool = False
    shading_changed: bool = False

    @staticmethod
    def between(previous: Snapshot | None, current: Snapshot) -> "Motion":
        if previous is None:
            return Motion(first=True, moved_objects=list(current.objects), lights_changed=True,
                          changed_lights=list(range(len(current.lights))), camera_moved=True, shading_changed=True)
        moved = sorted(n for n in set(previous.objects) | set(current.objects)
                       if previous.objects.get(n) != current.objects.get(n))
        boxes = [b for n in moved for b in (previous.bounds.get(n), current.bounds.get(n)) if b is not None]
        old = set(previous.lights)
        changed = [i for i, d in enumerate(current.lights) if d not in old]
        return Motion(moved_objects=moved, boxes=boxes, changed_lights=changed,
                      lights_changed=bool(changed) or sorted(previous.lights) != sorted(current.lights),
                      camera_moved=previous.camera != current.camera,
                      shading_changed=previous.shading != current.shading)

    @property
    def geometry_changed(self) -> bool:
        return self.first or bool(self.moved_objects)

    def static(self, view_dependent: bool = True) -> bool:
        """Nothing that the light transport depends on changed (the camera only counts for ``view_dependent``)."""
        return not (self.first or self.moved_objects or self.lights_changed or self.shading_changed or
                    (view_dependent and self.camera_moved))
