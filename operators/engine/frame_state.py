"""The sequence state the render engine uses for the frame it is rendering, and the frames it rendered with one.

The engine reads it (``active_sequence``); a bake sets it around each frame (``rendering``); for ``blender -b -a``
(``render(animation=True)``) it is kept here per scene and settings. Both the engine and the bake import this
module and neither imports the other for it, so the state has one owner. ``MovingObjects`` finds what a bake's
state is told moves in its sequence (``SequenceState.animated``).
"""
from __future__ import annotations

import contextlib
import hashlib
import json

import numpy as np

from ...vpl_addon.sequence.state import SequenceState, frame_seed
from ..scene.extract import GEOMETRY_TYPES

_ACTIVE: SequenceState | None = None  # set by a bake around each frame
_ANIMATION: dict[str, tuple[SequenceState, int]] = {}  # animation render: key -> (state, last frame)
# Frames rendered with a sequence state, as the engine reports them (frame, light paths, reused, BVH builds, the
# objects named as moving).
FRAME_LOG: list[dict] = []


def settings_key(scene) -> dict:
    """Everything about the scene's settings that changes the baked pixels (not the frame range)."""
    props = scene.vpl_gi
    values = {p.identifier: getattr(props, p.identifier) for p in props.bl_rna.properties
              if p.identifier not in {"rna_type", "name", "bake_directory", "bake_overwrite"}
              and not p.identifier.startswith("viewport_")}  # the 3D view's settings render no frame
    r = scene.render
    values.update(resolution=[r.resolution_x, r.resolution_y, r.resolution_percentage],
                  film_transparent=r.film_transparent,
                  border=[r.use_border, r.use_crop_to_border, r.border_min_x, r.border_max_x, r.border_min_y,
                          r.border_max_y] if r.use_border else None)
    return values


@contextlib.contextmanager
def rendering(state: SequenceState):
    """The engine renders with ``state`` inside the block (one frame of a bake)."""
    global _ACTIVE
    _ACTIVE = state
    try:
        yield
    finally:
        _ACTIVE = None


def active_sequence(scene, settings, is_animation: bool):
    """(sequence state or None, the seed for placing lights) for the frame the engine is about to render: in a
    sequence ``frame_seed(seed, frame)``, so a frame's lights do not depend on where the bake started."""
    if _ACTIVE is not None:
        return _ACTIVE, frame_seed(settings.seed, scene.frame_current)
    if is_animation:
        key = json.dumps([scene.name, settings_key(scene)], sort_keys=True, default=str)
        if key not in _ANIMATION or _ANIMATION[key][1] >= scene.frame_current:
            for old, _ in _ANIMATION.values():  # a new animation render: start cold
                old.close()
            _ANIMATION.clear()
            fresh = SequenceState(settings.method)
            fresh.learns = True  # it cannot look ahead for the objects that move, as a bake does: it learns them
            _ANIMATION[key] = (fresh, scene.frame_current)
        state = _ANIMATION[key][0]
        _ANIMATION[key] = (state, scene.frame_current)
        return state, frame_seed(settings.seed, scene.frame_current)
    return None, None


def animated_objects(scene, frames) -> tuple[str, ...]:
    """The names of the geometry objects that move, deform, appear or vanish anywhere in ``frames`` (sorted),
    ``MovingObjects`` looked over every frame at once. The scene is left at the frame it was at."""
    movers, current = MovingObjects(scene), scene.frame_current
    try:
        for frame in frames:
            movers.look(frame)
    finally:
        scene.frame_set(current)
    return movers.names()


class MovingObjects:
    """What moves in the frames looked at so far (``look``, one frame at a time, so that work which must answer in
    between, a bake's steps, can: a rig's evaluation can take a tenth of a second a frame, and 250 frames would hold
    the interface for half a minute). Each frame's evaluated objects (as the scene's view layer evaluates them) are
    digested by their instances' transforms, their meshes' vertices and whether they are hidden from render, a few
    milliseconds a frame for 150,000 triangles. ``look`` leaves the scene at the frame it looked at."""

    def __init__(self, scene):
        self.scene = scene
        self.looked = 0
        self._seen: dict[str, set[str]] = {}
        self._present: dict[str, int] = {}

    def look(self, frame: int) -> None:
        import bpy
        scene = self.scene
        scene.frame_set(frame)
        depsgraph = bpy.context.evaluated_depsgraph_get() if bpy.context.scene == scene else \
            scene.view_layers[0].depsgraph
        digests: dict[str, hashlib.blake2b] = {}
        for inst in depsgraph.object_instances:
            obj = inst.object
            if obj.type not in GEOMETRY_TYPES:
                continue
            if obj.name not in digests:  # hidden from render in some frames: it vanishes from those
                digests[obj.name] = hashlib.blake2b(_vertices(obj).tobytes() + bytes([obj.hide_render]),
                                                    digest_size=16)
            digests[obj.name].update(np.array(inst.matrix_world, np.float64).tobytes())
        for name, digest in digests.items():
            self._seen.setdefault(name, set()).add(digest.hexdigest())
            self._present[name] = self._present.get(name, 0) + 1
        self.looked += 1

    def names(self) -> tuple[str, ...]:
        """The objects that changed, or were missing from some frame, in the frames looked at (sorted)."""
        return tuple(sorted(name for name, shapes in self._seen.items()
                            if len(shapes) > 1 or self._present[name] < self.looked))


def _vertices(obj) -> np.ndarray:
    """The evaluated object's vertex positions in its own space (a curve's, text's or metaball's as a mesh)."""
    mesh = obj.data if obj.type == "MESH" else obj.to_mesh()
    try:
        co = np.empty(len(mesh.vertices) * 3, np.float32) if mesh is not None else np.zeros(0, np.float32)
        if mesh is not None:
            mesh.vertices.foreach_get("co", co)
        return co
    finally:
        if obj.type != "MESH":
            obj.to_mesh_clear()
