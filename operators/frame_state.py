"""The sequence state the render engine uses for the frame it is rendering, and the frames it rendered with one.

The engine reads it (``active_sequence``); a bake sets it around each frame (``rendering``); for ``blender -b -a``
(``render(animation=True)``) it is kept here per scene and settings. Both the engine and the bake import this
module and neither imports the other for it, so the state has one owner.
"""
from __future__ import annotations

import contextlib
import json

from ..vpl_addon.sequence.state import SequenceState, frame_seed

_ACTIVE: SequenceState | None = None  # set by a bake around each frame
_ANIMATION: dict[str, tuple[SequenceState, int]] = {}  # animation render: key -> (state, last frame)
# Frames rendered with a sequence state, as the engine reports them (frame, light paths, reused, BVH builds).
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
            _ANIMATION[key] = (SequenceState(settings.method), scene.frame_current)
        state = _ANIMATION[key][0]
        _ANIMATION[key] = (state, scene.frame_current)
        return state, frame_seed(settings.seed, scene.frame_current)
    return None, None
