"""Baking a frame range to one multilayer EXR per frame, carrying each method's state from frame to frame.

The unit a render farm splits is a frame range; ``bake`` renders one, in order, through the engine (so the files
are exactly what F12 or ``blender -b -a`` would write) with a ``sequence.SequenceState`` that the engine picks up
(``active_sequence``). Every frame appears atomically (``output.render_to``: a ``.partial-<pid>-`` file renamed into
place), then the state after that frame is saved atomically under ``.bake-state/`` in the output folder. A bake
started again over the same folder and settings skips the finished frames and continues from the last saved state,
so it writes the same bytes as an uninterrupted bake (frame ``f`` renders with ``frame_seed(seed, f)``; the EXR
header carries no date or render time). A range that starts cold, with no saved state before it, warms the state up
first (the methods' ``start``), so chunks of one range can be rendered on different machines.

``bake.json`` in the folder records the settings; a folder that holds a bake of other settings is refused unless
``overwrite`` is given, so nothing the user had is replaced without asking.
"""
from __future__ import annotations

import glob
import json
import os
import re
import tempfile
from dataclasses import dataclass, field
from typing import Callable

import bpy

from ..vpl_addon.sequence import SequenceState, frame_seed

MANIFEST = "bake.json"
STATE_DIR = ".bake-state"
FRAME_NAME = "frame_{:04d}.exr"

# The state the engine uses for the frame being rendered: set by ``Bake`` around each frame; for
# ``blender -b -a`` (``render(animation=True)``) the engine keeps one per scene and settings in ``_ANIMATION``.
_ACTIVE: SequenceState | None = None
_ANIMATION: dict[str, tuple[SequenceState, int]] = {}  # key -> (state, last frame)
# Frames rendered with a sequence state, as the engine reports them (frame, light paths, reused, BVH builds).
FRAME_LOG: list[dict] = []


class BakeError(RuntimeError):
    """A problem with the bake's input or output folder; the message explains it."""


def settings_key(scene) -> dict:
    """Everything about the scene's settings that changes the baked pixels (not the frame range)."""
    props = scene.vpl_gi
    values = {p.identifier: getattr(props, p.identifier) for p in props.bl_rna.properties
              if p.identifier not in {"rna_type", "name"}}
    r = scene.render
    values.update(resolution=[r.resolution_x, r.resolution_y, r.resolution_percentage])
    return values


def active_sequence(scene, settings, is_animation: bool):
    """(sequence state or None, seed) for the frame the engine is about to render."""
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
    return None, settings.seed


def frame_path(out_dir: str, frame: int) -> str:
    return os.path.join(out_dir, FRAME_NAME.format(frame))


def _state_path(out_dir: str, frame: int) -> str:
    return os.path.join(out_dir, STATE_DIR, f"frame_{frame:04d}.pkl")


def saved_state_frames(out_dir: str) -> list[int]:
    found = []
    for path in glob.glob(os.path.join(glob.escape(out_dir), STATE_DIR, "frame_*.pkl")):
        m = re.fullmatch(r"frame_(-?\d+)\.pkl", os.path.basename(path))
        if m:
            found.append(int(m.group(1)))
    return sorted(found)


def _write_atomic(path: str, data: bytes) -> None:
    folder = os.path.dirname(path)
    os.makedirs(folder, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".partial-{os.getpid()}-", suffix=".pkl", dir=folder)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


@dataclass
class BakeReport:
    rendered: list[int] = field(default_factory=list)
    skipped: list[int] = field(default_factory=list)  # already finished by an earlier run
    resumed_from: int | None = None  # the frame whose saved state the bake continued from
    frames: list[dict] = field(default_factory=list)  # per rendered frame: light paths, rays, reused, seconds


class Bake:
    """Render ``frames`` of ``scene`` (its engine must be VPL GI) into ``out_dir``."""

    def __init__(self, scene, out_dir: str, frames: range, overwrite: bool = False):
        if len(frames) == 0:
            raise BakeError(f"the frame range {frames.start}:{frames.stop - 1} is empty")
        self.scene, self.out_dir, self.frames = scene, os.path.abspath(out_dir), frames
        self.key = settings_key(scene)
        self.report = BakeReport()
        self._check_folder(overwrite)

    def _check_folder(self, overwrite: bool) -> None:
        if os.path.exists(self.out_dir) and not os.path.isdir(self.out_dir):
            raise BakeError(f"{self.out_dir} is a file; the bake needs a folder")
        os.makedirs(self.out_dir, exist_ok=True)
        manifest = os.path.join(self.out_dir, MANIFEST)
        if os.path.exists(manifest):
            try:
                with open(manifest) as f:
                    stored = json.load(f)
            except (OSError, ValueError):
                stored = None
            if stored != json.loads(json.dumps(self.key, default=str)):
                if not overwrite:
                    raise BakeError(f"{self.out_dir} holds a bake with other settings; pass --overwrite to "
                                    f"replace it (or choose another folder)")
                self._clear()
        elif not overwrite:
            taken = [f for f in self.frames if os.path.exists(frame_path(self.out_dir, f))]
            if taken:
                raise BakeError(f"{frame_path(self.out_dir, taken[0])} exists and is not from a bake; pass "
                                f"--overwrite to replace it")
        elif overwrite:
            self._clear()
        _write_atomic(manifest, json.dumps(self.key, sort_keys=True, default=str, indent=1).encode())

    def _clear(self) -> None:
        for f in self.frames:
            for path in (frame_path(self.out_dir, f), _state_path(self.out_dir, f)):
                if os.path.exists(path):
                    os.unlink(path)
        for f in saved_state_frames(self.out_dir):
            os.unlink(_state_path(self.out_dir, f))

    def run(self, progress: Callable[[float, str], bool] | None = None,
            render_frame: Callable[[str], None] | None = None) -> BakeReport:
        """Render the unfinished frames in order; ``progress(fraction, text)`` returning False stops after the
        current frame. ``render_frame(path)`` renders the scene's current frame to ``path`` atomically."""
        global _ACTIVE
        from . import engine
        from .output import render_to
        render_frame = render_frame or (lambda path: render_to(self.scene, path))
        report = self.report = BakeReport()
        scene = self.scene
        saved = saved_state_frames(self.out_dir)
        state: SequenceState | None = None
        stamps = {name: getattr(scene.render, name) for name in ("use_stamp_date", "use_stamp_render_time")}
        original_frame = scene.frame_current
        try:
            for name in stamps:  # no wall-clock values in the EXR header: a resumed bake writes the same bytes
                setattr(scene.render, name, False)
            for number, frame in enumerate(self.frames):
                if os.path.exists(frame_path(self.out_dir, frame)) and any(g >= frame for g in saved):
                    report.skipped.append(frame)
                    continue
                if state is None:
                    previous = _state_path(self.out_dir, frame - 1)
                    if os.path.exists(previous):
                        with open(previous, "rb") as f:
                            state = SequenceState.loads(f.read())
                        report.resumed_from = frame - 1
                    else:
                        state = SequenceState(scene.vpl_gi.method)
                scene.frame_set(frame)
                _ACTIVE = state
                try:
                    render_frame(frame_path(self.out_dir, frame))
                finally:
                    _ACTIVE = None
                _write_atomic(_state_path(self.out_dir, frame), state.dumps())
                if os.path.exists(_state_path(self.out_dir, frame - 1)):
                    os.unlink(_state_path(self.out_dir, frame - 1))
                stats = dict(engine.LAST_STATS)
                info = stats.get("info", {})
                entry = {"frame": frame, "light_paths": info.get("light_paths"), "reused": bool(info.get("reused")),
                         "rays": stats.get("rays"), "bvh_builds": state.bvh_builds,
                         "seconds": sum(stats.get("seconds", {}).values())}
                report.rendered.append(frame)
                report.frames.append(entry)
                if progress is not None and progress((number + 1) / len(self.frames), f"frame {frame}") is False:
                    break
        finally:
            _ACTIVE = None
            if state is not None:
                state.close()
            for name, value in stamps.items():
                setattr(scene.render, name, value)
            scene.frame_set(original_frame)
        return report
