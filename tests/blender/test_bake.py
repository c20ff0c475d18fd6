"""Baking a frame range through Blender: ``python -m vpl_addon bake``, ``render(animation=True)`` (what
``blender -b -a`` runs), resuming after SIGKILL, and the bake's care for the output folder."""
import os
import pickle
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from conftest import EXAMPLES, ROOT, run_cli

SMALL = ("--percentage", "25", "--samples", "2", "--light-samples", "2", "--vpls", "128")


def frames_in(folder):
    return sorted(p.name for p in folder.glob("frame_*.exr"))


class RunsCode:
    """Pickles as a call that writes ``marker``: what a crafted bake state would make ``pickle.loads`` run."""

    def __init__(self, marker):
        self.marker = str(marker)

    def __reduce__(self):
        return exec, (f"open({self.marker!r}, 'w').write('ran')",)


def test_a_static_bake_traces_light_paths_in_frame_one_only_and_resumes_by_skipping(tmp_path):
    out = tmp_path / "bake"
    code, stdout, stderr = run_cli("bake", EXAMPLES / "cornell_area.blend", "--frames", "1:3", "-o", out,
                                   "--method", "bidir", *SMALL)
    assert code == 0, stderr
    assert "kernels of bidir ready in" in stdout  # compiled before the frames, the other methods' left alone
    lines = [line for line in stdout.splitlines() if line.startswith("frame ")]
    assert len(lines) == 3 and " 0 light paths" not in lines[0]
    assert all(" 0 light paths (reused)" in line for line in lines[1:])
    assert frames_in(out) == ["frame_0001.exr", "frame_0002.exr", "frame_0003.exr"]
    assert not list(out.glob(".partial-*"))
    from vpl_addon.core.exr import read_passes
    first, _ = read_passes(out / "frame_0001.exr")
    third, _ = read_passes(out / "frame_0003.exr")
    assert {"Combined", "Diffuse Indirect", "Diffuse Direct", "Diffuse Color"} <= set(third)
    a, b = first["Diffuse Indirect"], third["Diffuse Indirect"]
    np.testing.assert_array_equal(a, b)  # a static frame renders exactly as frame 1
    before = {p: p.stat().st_mtime_ns for p in out.glob("frame_*.exr")}
    code, stdout, stderr = run_cli("bake", EXAMPLES / "cornell_area.blend", "--frames", "1:3", "-o", out,
                                   "--method", "bidir", *SMALL)
    assert code == 0 and "skipped 3 finished frames" in stdout and "baked 0 frames" in stdout, stdout + stderr
    assert before == {p: p.stat().st_mtime_ns for p in out.glob("frame_*.exr")}


def test_a_folder_with_another_bake_or_foreign_frames_is_not_overwritten_without_asking(tmp_path):
    out = tmp_path / "bake"
    out.mkdir()
    (out / "frame_0001.exr").write_bytes(b"precious")
    code, _, stderr = run_cli("bake", EXAMPLES / "cornell_area.blend", "--frames", "1:1", "-o", out, *SMALL,
                              "--method", "ir")
    assert code != 0 and "frame_0001.exr exists" in stderr and (out / "frame_0001.exr").read_bytes() == b"precious"
    (out / "frame_0001.exr").unlink()
    assert run_cli("bake", EXAMPLES / "cornell_area.blend", "--frames", "1:1", "-o", out, *SMALL, "--method",
                   "ir")[0] == 0
    code, _, stderr = run_cli("bake", EXAMPLES / "cornell_area.blend", "--frames", "1:1", "-o", out, *SMALL,
                              "--method", "bidir")
    assert code != 0 and "other settings" in stderr
    code, _, stderr = run_cli("bake", EXAMPLES / "cornell_area.blend", "--frames", "3:1", "-o", out)
    assert code != 0 and "before the first" in stderr


def test_killed_bake_resumes_to_the_same_files_as_an_uninterrupted_one(tmp_path):
    """SIGKILL in the middle of a frame: no partial EXR carries a final name; started again, the bake continues
    from the saved state and writes byte for byte what an uninterrupted bake writes."""
    args = ["bake", str(EXAMPLES / "seq_moving_light.blend"), "--frames", "1:8", "--method", "bidir",
            "--percentage", "50", "--samples", "4", "--light-samples", "2", "--vpls", "256"]
    whole, killed = tmp_path / "whole", tmp_path / "killed"
    proc = subprocess.Popen([sys.executable, "-m", "vpl_addon", *args, "-o", str(killed)], cwd=ROOT,
                            env={**os.environ, "PYTHONPATH": str(ROOT)}, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 300
        while proc.poll() is None and time.monotonic() < deadline and not (
                (killed / "frame_0003.exr").exists() and list(killed.glob(".partial-*.exr"))):
            time.sleep(0.01)
        assert proc.poll() is None, "the bake ended before it could be killed"
        proc.send_signal(signal.SIGKILL)
    finally:
        proc.kill()
        proc.wait()
    assert proc.returncode == -signal.SIGKILL
    done = frames_in(killed)
    assert 3 <= len(done) < 8
    from vpl_addon.core.exr import read_passes
    for name in done:  # every file under a final name is a whole image
        assert read_passes(killed / name)[0]["Combined"].shape == (64, 64, 4)
    code, stdout, stderr = run_cli(*args, "-o", killed)
    assert code == 0, stderr
    assert f"skipped {len(done)} finished frames, resumed from the state after frame {len(done)}" in stdout
    code, _, stderr = run_cli(*args, "-o", whole)
    assert code == 0, stderr
    assert frames_in(killed) == frames_in(whole) == [f"frame_{f:04d}.exr" for f in range(1, 9)]
    for name in frames_in(whole):
        assert (killed / name).read_bytes() == (whole / name).read_bytes(), name
    assert not list(killed.glob(".partial-*")) and not list((killed / ".bake-state").glob(".partial-*"))


def test_animation_render_carries_the_state_from_frame_to_frame(ext, tmp_path):
    """``blender -b scene.blend -E VPL_GI -s 1 -e 3 -a`` renders through the same engine: frames 2 and 3 of a
    static scene reuse frame 1's lights; the frames of a moving light are placed again; vbnl's state learns what
    moves."""
    import bpy
    from vpl_gi.operators.engine import render_engine as engine, frame_state
    for blend, reused in (("cornell_area", [False, True, True]), ("seq_moving_light", [False, False, False])):
        bpy.ops.wm.open_mainfile(filepath=str(EXAMPLES / f"{blend}.blend"))
        scene = bpy.context.scene
        scene.render.engine = engine.VPLGIRenderEngine.bl_idname
        scene.render.resolution_percentage = 25
        scene.vpl_gi.method, scene.vpl_gi.vpls, scene.vpl_gi.samples = "ir", 128, 1
        scene.frame_start, scene.frame_end = 1, 3
        scene.render.filepath = str(tmp_path / f"{blend}_")
        frame_state.FRAME_LOG.clear()
        bpy.ops.render.render(animation=True)
        log = frame_state.FRAME_LOG
        assert [e["frame"] for e in log] == [1, 2, 3]
        assert [e["reused"] for e in log] == reused
        assert [e["light_paths"] == 0 for e in log] == reused
        assert log[-1]["bvh_builds"] == 1
    # vbnl's state learns the moving block in the frame it first moves (the render cannot look ahead)
    bpy.ops.wm.open_mainfile(filepath=str(EXAMPLES / "seq_moving_object.blend"))
    scene = bpy.context.scene
    scene.render.engine = engine.VPLGIRenderEngine.bl_idname
    scene.render.resolution_percentage = 25
    scene.vpl_gi.method, scene.vpl_gi.vpls, scene.vpl_gi.samples = "vbnl", 128, 1
    scene.frame_start, scene.frame_end = 1, 3
    scene.render.filepath = str(tmp_path / "vbnl_")
    frame_state.FRAME_LOG.clear()
    bpy.ops.render.render(animation=True)
    assert [e["animated"] for e in frame_state.FRAME_LOG] == [None, ("ShortBox",), ("ShortBox",)]


def _small_scene(bpy, engine, blend):
    bpy.ops.wm.open_mainfile(filepath=str(EXAMPLES / f"{blend}.blend"))
    scene = bpy.context.scene
    scene.render.engine = engine.VPLGIRenderEngine.bl_idname
    scene.render.resolution_percentage = 25
    scene.vpl_gi.method, scene.vpl_gi.vpls, scene.vpl_gi.samples, scene.vpl_gi.light_samples = "bidir", 128, 1, 1
    return scene


def test_bake_operator_renders_the_frame_range_and_stopping_keeps_what_is_done(ext, tmp_path):
    """The render panel's "Bake Indirect Sequence" bakes frame_start..frame_end into the bake folder; a bake stopped
    after a frame (ESC) continues from that frame's state when started again."""
    import bpy
    from vpl_gi.operators.output import bake
    from vpl_gi.operators.engine import render_engine as engine
    scene = _small_scene(bpy, engine, "seq_moving_light")
    scene.frame_start, scene.frame_end = 3, 5
    scene.vpl_gi.bake_directory = str(tmp_path / "op")
    assert bpy.ops.vpl_gi.bake_sequence() == {"FINISHED"}
    assert frames_in(tmp_path / "op") == ["frame_0003.exr", "frame_0004.exr", "frame_0005.exr"]
    assert scene.frame_current == 1 and scene.render.use_stamp_date  # the user's scene is as it was

    stopped = bake.Bake(scene, str(tmp_path / "esc"), range(3, 6))
    report = stopped.run(progress=lambda fraction, text: False)  # ESC after the first frame
    assert report.rendered == [3] and frames_in(tmp_path / "esc") == ["frame_0003.exr"]
    report = bake.Bake(scene, str(tmp_path / "esc"), range(3, 6)).run()
    assert report.skipped == [3] and report.resumed_from == 3 and report.rendered == [4, 5]
    for name in frames_in(tmp_path / "op"):
        assert (tmp_path / "op" / name).read_bytes() == (tmp_path / "esc" / name).read_bytes()

    # a pickle that runs code when unpickled, where an earlier engine kept its states (.pkl) and where this one
    # keeps them (.npz): read as data, it is refused, frame 4 starts cold with one warning, and nothing runs
    pickle.loads(pickle.dumps(RunsCode(tmp_path / "proof")))
    assert (tmp_path / "proof").exists()  # the payload is live
    marker = tmp_path / "marker"
    for folder, name in (("old", "frame_0003.pkl"), ("crafted", "frame_0003.npz")):
        bake.Bake(scene, str(tmp_path / folder), range(3, 6)).run(progress=lambda fraction, text: False)
        states = tmp_path / folder / ".bake-state"
        (states / "frame_0003.npz").unlink()
        (states / name).write_bytes(pickle.dumps(RunsCode(marker)))
        report = bake.Bake(scene, str(tmp_path / folder), range(3, 6)).run()
        assert report.resumed_from is None and report.rendered == [4, 5], report
        assert len(report.warnings) == 1 and "frame 4 starts cold" in report.warnings[0], report.warnings
        assert [p.name for p in states.iterdir()] == ["frame_0005.npz"]  # the refused state is cleared
        assert (tmp_path / folder / "frame_0004.exr").read_bytes() == (tmp_path / "op" / "frame_0004.exr").read_bytes()
    assert not marker.exists()


def test_a_resumed_bake_of_a_stateful_method_writes_the_same_bytes(ext, tmp_path):
    """smc (its VPL set) and ir (its kept light paths, verified against the moving block) resume from the saved
    state exactly where an uninterrupted bake would be."""
    import bpy
    from vpl_gi.operators.output import bake
    from vpl_gi.operators.engine import render_engine as engine
    for method in ("smc", "ir"):
        scene = _small_scene(bpy, engine, "seq_moving_object")
        scene.vpl_gi.method, scene.vpl_gi.smc_warmup = method, 3
        whole = bake.Bake(scene, str(tmp_path / f"{method}_whole"), range(1, 4)).run()
        assert whole.rendered == [1, 2, 3]
        if method == "ir":
            paths = [e["light_paths"] for e in whole.frames]
            assert 0 < paths[1] < paths[0] and 0 < paths[2] < paths[0]  # only the paths the block cuts
        folder = str(tmp_path / f"{method}_resumed")
        bake.Bake(scene, folder, range(1, 4)).run(progress=lambda fraction, text: False)
        report = bake.Bake(scene, folder, range(1, 4)).run()
        assert report.resumed_from == 1 and report.rendered == [2, 3]
        for name in frames_in(tmp_path / f"{method}_whole"):
            whole, resumed = (tmp_path / f"{method}_{run}" / name for run in ("whole", "resumed"))
            assert whole.read_bytes() == resumed.read_bytes(), (method, name)


def test_a_vbnl_bake_finds_what_moves_and_keeps_its_lights_where_they_were(ext, tmp_path):
    """Before its first frame a vbnl bake looks over the sequence for the objects that move: the short box (its
    own keys), a cube that follows an animated empty, one that only deforms (a shape key), one hidden from
    render in some frames; not the static walls, and not one hidden in the viewport (it is learnt in the frame
    it moves). Its state keeps their names, frame 2's lights are frame 1's (the box moved, the
    view did not), and a chunk of the sequence writes the frames one bake writes."""
    import bpy
    from vpl_gi.operators.output import bake
    from vpl_gi.operators.engine import render_engine as engine, frame_state
    from vpl_gi.vpl_addon.sequence.state import SequenceState
    scene = _small_scene(bpy, engine, "seq_moving_object")
    scene.vpl_gi.method = "vbnl"
    empty = bpy.data.objects.new("Mover", None)
    scene.collection.objects.link(empty)
    for frame, x in ((1, 0.0), (24, 1.0)):
        empty.location.x = x
        empty.keyframe_insert("location", index=0, frame=frame)
    for name in ("Follower", "Bent", "Blinking"):
        bpy.ops.mesh.primitive_cube_add(size=0.01, location=(5.0, 5.0, 5.0))  # out of the camera's view
        bpy.context.object.name = name
    bpy.data.objects["Follower"].parent = empty
    bent = bpy.data.objects["Bent"]
    bent.shape_key_add(name="Basis")
    key = bent.shape_key_add(name="Push")
    key.data[0].co.x += 1.0
    for frame, value in ((1, 0.0), (24, 1.0)):
        key.value = value
        key.keyframe_insert("value", frame=frame)
    blinking = bpy.data.objects["Blinking"]
    for frame, hidden in ((1, False), (12, True)):  # shown in the viewport, hidden from render from frame 12
        blinking.hide_render = hidden
        blinking.keyframe_insert("hide_render", frame=frame)
    # rendered, hidden in the viewport, inside the tall box (no ray meets it, and the scene's bounds stay)
    bpy.ops.mesh.primitive_cube_add(size=0.01, location=(-0.35, 0.3, 0.5))
    hidden = bpy.context.object
    hidden.name, hidden.hide_viewport = "Unseen", True
    for frame, z in ((1, 0.5), (24, 0.7)):
        hidden.location.z = z
        hidden.keyframe_insert("location", index=2, frame=frame)
    scene.frame_set(5)
    assert frame_state.animated_objects(scene, range(1, 25)) == ("Bent", "Blinking", "Follower", "ShortBox")
    assert frame_state.animated_objects(scene, range(30, 33)) == ()  # past the keys nothing moves
    assert scene.frame_current == 5

    lights = {}
    for last in (1, 2):
        folder = tmp_path / f"to{last}"
        baked = bake.Bake(scene, str(folder), range(1, last + 1))
        assert baked.run().rendered == list(range(1, last + 1))
        state = SequenceState.loads((folder / ".bake-state" / f"frame_{last:04d}.npz").read_bytes(),
                                    baked.state_key(last))
        # looked over 1..24, the scene's frames; the object the look-ahead cannot see is learnt when it moves
        assert state.animated == ("Bent", "Blinking", "Follower", "ShortBox", *(("Unseen",) if last > 1 else ()))
        lights[last] = state.method_state.lights.position
    assert len(lights[1]) == 128 and np.array_equal(lights[1], lights[2])
    # a chunk of the sequence starting cold at its first frame looks over the same frames: the same bytes
    assert bake.Bake(scene, str(tmp_path / "chunk"), range(2, 3), first=1).run().replayed == [1]
    assert (tmp_path / "chunk" / "frame_0002.exr").read_bytes() == (tmp_path / "to2" / "frame_0002.exr").read_bytes()


def test_a_cold_start_looks_ahead_in_steps_that_report_progress_and_can_stop(ext, tmp_path, monkeypatch):
    """A rig can take a tenth of a second a frame to evaluate, so a vbnl bake's look-ahead over 250 frames would
    hold the interface for half a minute: it pauses every ``LOOK_AHEAD_STRETCH`` seconds (here 0: every frame) with
    its progress, where a stop (ESC) ends the bake before any frame, with the scene back at its frame; started
    again, the bake looks ahead and renders every frame."""
    import bpy
    from vpl_gi.operators.output import bake
    from vpl_gi.operators.engine import render_engine as engine
    scene = _small_scene(bpy, engine, "seq_moving_object")
    scene.vpl_gi.method = "vbnl"
    scene.frame_start, scene.frame_end = 3, 5
    scene.frame_set(1)
    monkeypatch.setattr(bake, "LOOK_AHEAD_STRETCH", 0.0)
    told = []

    def stop(fraction, text):
        told.append(text)
        return False
    report = bake.Bake(scene, str(tmp_path / "b"), range(3, 6)).run(progress=stop)
    assert told == ["looking over frame 3 of 3-5 for what moves"] and report.rendered == []
    assert scene.frame_current == 1 and frames_in(tmp_path / "b") == []
    told.clear()
    report = bake.Bake(scene, str(tmp_path / "b"), range(3, 6)).run(progress=lambda f, text: told.append((f, text)))
    assert told == [(0.0, f"looking over frame {f} of 3-5 for what moves") for f in (3, 4, 5)] + \
        [((f - 2) / 3, f"frame {f}") for f in (3, 4, 5)]
    assert report.rendered == [3, 4, 5] and scene.frame_current == 1


def _output_settings(scene) -> dict:
    """What a bake may touch of the user's scene: the output path, file extension, stamps, current frame and every
    setting of the image format (its colour spaces too)."""
    def values(struct, prefix=""):
        found = {}
        for prop in struct.bl_rna.properties:
            value = getattr(struct, prop.identifier)
            if prop.type == "POINTER" and value is not None and prop.identifier != "rna_type":
                found.update(values(value, f"{prefix}{prop.identifier}."))
            elif prop.type not in {"POINTER", "COLLECTION"}:
                found[prefix + prop.identifier] = value[:] if getattr(prop, "is_array", False) else value
        return found
    r = scene.render
    kept = {name: getattr(r, name) for name in ("filepath", "use_file_extension", "use_stamp_date",
                                                "use_stamp_render_time")}
    return {**kept, "frame_current": scene.frame_current, **values(r.image_settings, "image_settings.")}


def test_the_bake_operator_leaves_the_scenes_output_settings_as_they_were(ext, tmp_path):
    """Finished, stopped (ESC: the bake's steps closed after a frame) or failed in its second frame (a timeline
    marker switches to a panoramic camera, which the engine refuses), the bake leaves the output path, the image
    format (file format, colour depth, EXR codec, colour space), the stamps and the current frame as the user had
    them: it renders each frame to its own file with settings of its own."""
    import bpy
    from vpl_gi.operators.output import bake
    from vpl_gi.operators.engine import render_engine as engine
    scene = _small_scene(bpy, engine, "seq_moving_light")
    scene.frame_start, scene.frame_end = 3, 4
    scene.frame_set(7)
    r = scene.render
    r.filepath, r.use_file_extension, r.use_stamp_date, r.use_stamp_render_time = "//renders/shot_", False, True, True
    image = r.image_settings
    image.media_type, image.file_format = "IMAGE", "OPEN_EXR"
    image.color_depth, image.exr_codec, image.linear_colorspace_settings.name = "16", "DWAA", "ACEScg"
    before = _output_settings(scene)

    scene.vpl_gi.bake_directory = str(tmp_path / "finished")
    assert bpy.ops.vpl_gi.bake_sequence() == {"FINISHED"}
    assert frames_in(tmp_path / "finished") == ["frame_0003.exr", "frame_0004.exr"]
    assert _output_settings(scene) == before

    report = bake.Bake(scene, str(tmp_path / "stopped"), range(3, 5)).run(progress=lambda fraction, text: False)
    assert report.rendered == [3] and _output_settings(scene) == before

    pano = bpy.data.objects.new("Pano", bpy.data.cameras.new("Pano"))
    pano.data.type = "PANO"
    scene.collection.objects.link(pano)
    scene.timeline_markers.new("shot", frame=1).camera = scene.camera
    scene.timeline_markers.new("pano", frame=4).camera = pano
    scene.vpl_gi.bake_directory = str(tmp_path / "failed")
    with pytest.raises(RuntimeError, match="camera 'Pano'"):
        bpy.ops.vpl_gi.bake_sequence()
    assert frames_in(tmp_path / "failed") == ["frame_0003.exr"]
    assert _output_settings(scene) == before
