"""Baking a frame range to one multilayer EXR per frame, carrying each method's state from frame to frame.

The unit a render farm splits is a frame range; ``bake`` renders one, in order, through the engine (so the files are
exactly what F12 or ``blender -b -a`` would write) with a ``sequence.state.SequenceState`` that the engine picks up
(``frame_state.rendering``). Every frame appears atomically (``output.render_to``: a ``.partial-<pid>-`` file renamed
into place), then the state after that frame is saved atomically under ``.bake-state/`` in the output folder, as data
(arrays and JSON, ``SequenceState.dumps``) keyed to the scene, the settings and the frame: a state of another bake, of
an earlier engine (a pickle, never unpickled) or a damaged one is refused with one warning and the frame starts cold. A
bake started again over the same folder and settings skips the finished frames and continues from the last saved state,
so it writes the same bytes as an uninterrupted bake (frame ``f`` places its lights with ``frame_seed(seed, f)``, its
pixels use ``seed`` in every frame as Cycles does without an animated seed; the EXR header carries no date or render
time). A range that starts cold, with no saved state before it, warms the state up first (the methods' ``start``), so
chunks of one range can be rendered on different machines. A chunk of a longer sequence (``first``, the sequence's first
frame, before the chunk's) does not start cold: it takes the nearest state saved before it (another chunk's, when there
is one) or a cold start at ``first``, and carries it through the frames in between by placing their lights without
rendering their pixels (``place_only``), so it continues exactly the state an uninterrupted bake would have: the chunks
of a farm write the same bytes as one bake, without a seam where a chunk starts.

``bake.json`` in the folder records the settings; a folder that holds a bake of other settings is refused unless
``overwrite`` is given, so nothing the user had is replaced without asking. While a bake runs it claims its frames
(``BakeClaim``): a second bake of any of them into the same folder is refused; the disjoint chunks of one farm job
coexist. Finished, stopped or failed, a bake leaves
the scene's output path and image format (``output.render_to``), stamps and current frame as the user had them.
"""
from __future__ import annotations

import glob
import hashlib
import json
import os
import re
import socket
import tempfile
import time
from dataclasses import dataclass, field
from typing import Callable

import bpy

from ...vpl_addon.methods import METHODS
from ...vpl_addon.sequence.state import SequenceState
from ..engine import render_engine as engine
from ..engine.frame_state import MovingObjects, rendering, settings_key
from .render_file import _alive, render_to

MANIFEST = "bake.json"
STATE_DIR = ".bake-state"
CLAIM_DIR = ".bake-claims"
FRAME_NAME = "frame_{:04d}.exr"


LOOK_AHEAD_STRETCH = 0.2  # seconds of looking over the frames for what moves between two steps of a bake


class BakeError(RuntimeError):
    """A problem with the bake's input or output folder; the message explains it."""


def frame_path(out_dir: str, frame: int) -> str:
    return os.path.join(out_dir, FRAME_NAME.format(frame))


def _state_path(out_dir: str, frame: int) -> str:
    return os.path.join(out_dir, STATE_DIR, f"frame_{frame:04d}.npz")


def saved_states(out_dir: str) -> list[tuple[int, str]]:
    """(frame, path) of each state saved in the folder, by frame: this engine's (``.npz``) and those an earlier
    one left (``.pkl``, found so that they are refused with a warning and cleared), the former after the latter."""
    found = []
    for path in glob.glob(os.path.join(glob.escape(out_dir), STATE_DIR, "frame_*")):
        m = re.fullmatch(r"frame_(-?\d+)\.(pkl|npz)", os.path.basename(path))
        if m:
            found.append((int(m.group(1)), m.group(2) == "npz", path))
    return [(frame, path) for frame, _, path in sorted(found)]


def _write_atomic(path: str, data: bytes) -> None:
    folder = os.path.dirname(path)
    os.makedirs(folder, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".partial-{os.getpid()}-", suffix=os.path.splitext(path)[1], dir=folder)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


class BakeClaim:
    """A bake's claim on frames ``frames`` of a folder: ``.bake-claims/FIRST-LAST.json`` holding the owner's host and
    pid. Claims that share a frame refuse each other, so two bakes never write the same frames at once; disjoint
    claims (the chunks of a render farm's job) coexist. The claim is made first and the others are read after, so
    two bakes that race can both be refused, never both admitted. A claim left by a process of this host that has
    died is stale and removed; one from another host is removed by hand (the message says which file)."""

    def __init__(self, out_dir: str, frames: range):
        self.folder = os.path.join(out_dir, CLAIM_DIR)
        self.frames = frames
        self.path = os.path.join(self.folder, f"{frames.start}-{frames.stop - 1}.json")
        self.held = False

    def acquire(self) -> None:
        os.makedirs(self.folder, exist_ok=True)
        me = {"host": socket.gethostname(), "pid": os.getpid(), "frames": [self.frames.start, self.frames.stop - 1]}
        while True:
            try:
                fd = os.open(self.path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
                break
            except FileExistsError:
                self._refuse_unless_stale(self.path)  # removed when stale: try again
        with os.fdopen(fd, "w") as f:
            json.dump(me, f)
        self.held = True
        for other in glob.glob(os.path.join(glob.escape(self.folder), "*.json")):
            m = re.fullmatch(r"(-?\d+)-(-?\d+)\.json", os.path.basename(other))
            if other != self.path and m and int(m.group(1)) < self.frames.stop and int(m.group(2)) >= self.frames.start:
                try:
                    self._refuse_unless_stale(other)
                except BakeError:
                    self.release()
                    raise

    def _refuse_unless_stale(self, path: str) -> None:
        try:
            with open(path) as f:
                owner = json.load(f)
        except FileNotFoundError:
            return
        except (OSError, ValueError):
            owner = {}  # being written by its owner this instant
        if owner.get("host") == socket.gethostname() and isinstance(owner.get("pid"), int) and \
                not _alive(owner["pid"]):
            try:
                os.unlink(path)
            except FileNotFoundError:
                pass
            return
        first, last = owner.get("frames", ["?", "?"])
        raise BakeError(f"{os.path.dirname(self.folder)} is being baked (frames {first}:{last}) by process "
                        f"{owner.get('pid', '?')} on {owner.get('host', '?')}; wait for it, or delete {path} if that "
                        f"bake is gone")

    def release(self) -> None:
        if self.held:
            self.held = False
            try:
                os.unlink(self.path)
            except FileNotFoundError:
                pass


@dataclass
class BakeReport:
    rendered: list[int] = field(default_factory=list)
    skipped: list[int] = field(default_factory=list)  # already finished by an earlier run
    resumed_from: int | None = None  # the frame whose saved state the bake continued from
    replayed: list[int] = field(default_factory=list)  # frames whose lights were placed, not rendered (``first``)
    frames: list[dict] = field(default_factory=list)  # per rendered frame: light paths, rays, reused, seconds
    warnings: list[str] = field(default_factory=list)  # e.g. a saved state it could not read (it started cold)


class Bake:
    """Render ``frames`` of ``scene`` (its engine must be VPL GI) into ``out_dir``; ``frames`` may be a chunk of a
    sequence that starts at ``first``. ``claim`` False: the frames are claimed by the caller (a farm's client, whose
    chunks these are), the bake does not claim them itself."""

    def __init__(self, scene, out_dir: str, frames: range, overwrite: bool = False, first: int | None = None,
                 claim: bool = True, last: int | None = None):
        if len(frames) == 0:
            raise BakeError(f"the frame range {frames.start}:{frames.stop - 1} is empty")
        self.first = frames.start if first is None else first
        if self.first > frames.start:
            raise BakeError(f"the sequence starts at frame {self.first}, after the chunk's first frame {frames.start}")
        self.scene, self.out_dir, self.frames = scene, os.path.abspath(out_dir), frames
        # the frames looked over for what moves (``MovingObjects``): from the sequence's first to the later of
        # its last and the scene's end frame, the same for every chunk of a job that lies within the scene's range
        self.last = max(frames.stop - 1 if last is None else last, scene.frame_end)
        self.key = settings_key(scene)
        self.report = BakeReport()
        if os.path.exists(self.out_dir) and not os.path.isdir(self.out_dir):
            raise BakeError(f"{self.out_dir} is a file; the bake needs a folder")
        os.makedirs(self.out_dir, exist_ok=True)
        self.claim = BakeClaim(self.out_dir, frames)
        if claim:
            self.claim.acquire()
        try:
            self._check_folder(overwrite)
        except BaseException:
            self.claim.release()
            raise

    def release(self) -> None:
        """Give up the claim on the frames (a bake's steps do when they end; this is for a bake never run)."""
        self.claim.release()

    def _check_folder(self, overwrite: bool) -> None:
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
        for _, path in saved_states(self.out_dir):
            os.unlink(path)

    def state_key(self, frame: int) -> str:
        """What a state saved after ``frame`` belongs to: the scene's name, the bake's settings and the frame."""
        return hashlib.blake2b(json.dumps([self.scene.name, self.key, frame], sort_keys=True, default=str).encode(),
                               digest_size=16).hexdigest()

    def run(self, progress: Callable[[float, str], bool] | None = None,
            render_frame: Callable[[str], None] | None = None) -> BakeReport:
        """Render the unfinished frames in order; ``progress(fraction, text)`` (``steps``' progress) returning False
        stops after the current frame, or before the first while a cold start looks ahead. ``render_frame(path)``
        renders the scene's current frame to ``path`` atomically."""
        steps = self.steps(render_frame)
        try:
            for fraction, text in steps:
                if progress is not None and progress(fraction, text) is False:
                    break
        finally:
            steps.close()
        return self.report

    def steps(self, render_frame: Callable[[str], None] | None = None):
        """The bake one frame at a time (for a modal operator): yields (fraction done, what it did: "frame 12")
        after each frame it renders, and every ``LOOK_AHEAD_STRETCH`` seconds while a cold start looks over the
        sequence for what moves; closing the generator ends the bake cleanly after the last finished frame."""
        render_frame = render_frame or (lambda path: render_to(self.scene, path))
        report = self.report = BakeReport()
        scene = self.scene
        state: SequenceState | None = None
        after = None  # the frame whose state ``state`` is
        stamps = {name: getattr(scene.render, name) for name in ("use_stamp_date", "use_stamp_render_time")}
        original_frame = scene.frame_current
        try:
            for name in stamps:  # no wall-clock values in the EXR header: a resumed bake writes the same bytes
                setattr(scene.render, name, False)
            for number, frame in enumerate(self.frames):
                if os.path.exists(frame_path(self.out_dir, frame)):  # complete (written atomically), of this bake
                    report.skipped.append(frame)
                    continue
                if state is None:
                    state, after = yield from self._nearest_state(frame, number / len(self.frames))
                for earlier in range(after + 1, frame):  # frames another bake rendered: their lights, no pixels
                    place_only(scene, state, earlier)
                    report.replayed.append(earlier)
                scene.frame_set(frame)
                with rendering(state):
                    render_frame(frame_path(self.out_dir, frame))
                _write_atomic(_state_path(self.out_dir, frame), state.dumps(self.state_key(frame)))
                after = frame
                if frame - 1 in self.frames:  # a chunk's last state stays for the next one
                    for path in [path for saved, path in saved_states(self.out_dir) if saved == frame - 1]:
                        os.unlink(path)
                stats = dict(engine.LAST_STATS)
                info = stats.get("info", {})
                report.rendered.append(frame)
                report.frames.append({"frame": frame, "light_paths": info.get("light_paths"),
                                      "light_path_rays": info.get("light_path_rays"),
                                      "reused": bool(info.get("reused")), "rays": stats.get("rays"),
                                      "bvh_builds": state.bvh_builds,
                                      "seconds": sum(stats.get("seconds", {}).values())})
                yield (number + 1) / len(self.frames), f"frame {frame}"
        finally:
            if state is not None:
                state.close()
            for name, value in stamps.items():
                setattr(scene.render, name, value)
            scene.frame_set(original_frame)
            self.release()

    def _nearest_state(self, frame: int, fraction: float):
        """(state, the frame it is after) to continue from before ``frame``, returned by a generator that yields
        ``steps``' progress (``fraction`` done) while a cold start looks ahead: the latest state saved in the folder
        from frame ``first - 1`` on, else a cold start before ``first``."""
        for saved, path in reversed([s for s in saved_states(self.out_dir) if self.first - 1 <= s[0] < frame]):
            try:
                with open(path, "rb") as f:
                    state = SequenceState.loads(f.read(), self.state_key(saved))
            except FileNotFoundError:  # another chunk moved on from it this instant
                continue
            except (OSError, ValueError) as err:
                self.report.warnings.append(f"{path}: {err}; frame {frame} starts cold" + (
                    f" (its state placed again from frame {self.first})" if self.first < frame else ""))
                continue
            self.report.resumed_from = saved
            return state, saved
        state = SequenceState(self.scene.vpl_gi.method)
        if state.method in METHODS and METHODS[state.method].uses_still:
            movers, since = MovingObjects(self.scene), time.perf_counter()
            for looked in range(self.first, self.last + 1):  # ``steps`` puts the scene back at its frame if stopped
                movers.look(looked)
                if time.perf_counter() - since >= LOOK_AHEAD_STRETCH:
                    yield fraction, f"looking over frame {looked} of {self.first}-{self.last} for what moves"
                    since = time.perf_counter()
            state.animated = movers.names()
            state.learns = True  # and what the look-ahead cannot see (an object hidden in the viewport only)
        return state, self.first - 1


def place_only(scene, state: SequenceState, frame: int) -> None:
    """Carry ``state`` through ``frame`` as rendering it would, without its pixels: the engine renders a corner of
    2x2 pixels (a frame's lights do not depend on the pixels rendered, and the state keeps nothing of them) and
    nothing is written. The scene's render border is the user's again after."""
    r = scene.render
    names = ("use_border", "use_crop_to_border", "border_min_x", "border_max_x", "border_min_y", "border_max_y")
    kept = {name: getattr(r, name) for name in names}
    size = [max(1, int(n * r.resolution_percentage / 100)) for n in (r.resolution_x, r.resolution_y)]
    try:
        r.use_border, r.use_crop_to_border = True, True
        r.border_min_x, r.border_max_x = 0.0, min(1.0, 2.5 / size[0])
        r.border_min_y, r.border_max_y = 0.0, min(1.0, 2.5 / size[1])
        scene.frame_set(frame)
        failure = None
        with rendering(state):
            try:
                bpy.ops.render.render(scene=scene.name)
            except RuntimeError as err:  # an engine error report arrives as "Error: <report>"
                failure = err
        _engine_error()
        if failure is not None:
            raise failure
    finally:
        for name, value in kept.items():
            setattr(r, name, value)


def _engine_error():
    errors = [m for level, m in engine.LAST_REPORTS if level == "ERROR"]
    if errors:
        raise BakeError(errors[0])


class VPLGI_OT_bake_sequence(bpy.types.Operator):
    """Render the scene's frame range with VPL GI to one multilayer EXR per frame, carrying the method's state
    from frame to frame; a bake started again continues after its last finished frame"""
    bl_idname = "vpl_gi.bake_sequence"
    bl_label = "Bake Indirect Sequence"
    bl_options = {"REGISTER"}

    _steps = None
    _timer = None

    @classmethod
    def poll(cls, context):
        return context.scene is not None and context.scene.render.engine == "VPL_GI"

    def _start(self, context):
        scene = context.scene
        folder = bpy.path.abspath(scene.vpl_gi.bake_directory)
        if not folder:
            raise BakeError("set the bake folder first")
        bake = Bake(scene, folder, range(scene.frame_start, scene.frame_end + 1),
                    overwrite=scene.vpl_gi.bake_overwrite)
        return bake, bake.steps(lambda path: render_to(scene, path, _engine_error))

    def execute(self, context):  # scripts and background mode: the whole range, blocking
        try:
            bake, steps = self._start(context)
            for _ in steps:
                pass
        except (BakeError, OSError, RuntimeError) as err:
            self.report({"ERROR"}, str(err))
            return {"CANCELLED"}
        for warning in bake.report.warnings:
            self.report({"WARNING"}, warning)
        self.report({"INFO"}, f"baked {len(bake.report.rendered)} frames to {bake.out_dir}")
        return {"FINISHED"}

    def invoke(self, context, event):  # the UI: one frame per timer tick, progress on the cursor, ESC stops
        try:
            self._bake, self._steps = self._start(context)
        except (BakeError, OSError) as err:
            self.report({"ERROR"}, str(err))
            return {"CANCELLED"}
        wm = context.window_manager
        wm.progress_begin(0, len(self._bake.frames))
        self._timer = wm.event_timer_add(0.05, window=context.window)
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        if event.type == "ESC":
            self._finish(context)
            self.report({"WARNING"}, f"bake stopped after {len(self._bake.report.rendered)} frames; bake again "
                                     f"to continue")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        try:
            fraction, text = next(self._steps)
        except StopIteration:
            self._finish(context)
            self.report({"INFO"}, f"baked {len(self._bake.report.rendered)} frames to {self._bake.out_dir}")
            return {"FINISHED"}
        except (BakeError, OSError, RuntimeError) as err:
            self._finish(context)
            self.report({"ERROR"}, str(err))
            return {"CANCELLED"}
        context.window_manager.progress_update(int(round(fraction * len(self._bake.frames))))
        context.workspace.status_text_set(f"VPL GI bake: {text} ({fraction * 100:.0f} %), ESC to stop")
        return {"RUNNING_MODAL"}

    def _finish(self, context):
        self._steps.close()
        self._bake.release()  # steps that never ran hold it still
        for warning in self._bake.report.warnings:
            self.report({"WARNING"}, warning)
        wm = context.window_manager
        wm.event_timer_remove(self._timer)
        wm.progress_end()
        context.workspace.status_text_set(None)


class RENDER_PT_vpl_gi_bake(bpy.types.Panel):
    bl_label = "Bake Sequence"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "render"
    bl_parent_id = "RENDER_PT_vpl_gi"
    COMPAT_ENGINES = {"VPL_GI"}

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        settings = context.scene.vpl_gi
        layout.prop(settings, "bake_directory")
        layout.prop(settings, "bake_overwrite")
        layout.label(text=f"Frames {context.scene.frame_start} to {context.scene.frame_end}")
        layout.operator(VPLGI_OT_bake_sequence.bl_idname, icon="RENDER_ANIMATION")


CLASSES = (VPLGI_OT_bake_sequence, RENDER_PT_vpl_gi_bake)


register, unregister = bpy.utils.register_classes_factory(CLASSES)
