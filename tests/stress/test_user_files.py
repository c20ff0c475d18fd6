"""The user's files (issue 8, item 4): a render never writes over the .blend it renders or an existing image
without --overwrite, never saves the .blend, writes its image atomically, and a failed or killed render leaves
nothing under the final name (and its partial file does not outlive the next render). The engine's own bugs reach
the user as one line, in Blender's reports and on the command line, never as a traceback."""
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from conftest import ROOT, run_cli

pytestmark = pytest.mark.blender


@pytest.fixture
def blend(small_blend):
    """A floor under a camera and a point light, saved to tmp_path/scene.blend."""
    return small_blend(name="scene.blend")


def spoil_gather(monkeypatch):
    """Make the (real) gather of the extension's engine produce one NaN: an engine bug, injected."""
    import vpl_gi.vpl_addon.render as engine_render
    real = engine_render.gather

    def gather(*args, **kwargs):
        out = real(*args, **kwargs)
        out.reshape(-1)[:1] = np.nan
        return out
    monkeypatch.setattr(engine_render, "gather", gather)


@pytest.mark.parametrize("overwrite", [False, True], ids=["plain", "--overwrite"])
def test_the_scene_file_is_never_the_output(blend, overwrite):
    """`render scene.blend -o scene.blend` is refused in one line, even with --overwrite; the .blend is intact."""
    before = blend.read_bytes()
    code, _, stderr = run_cli("render", blend, "-o", blend, "--samples", "1", *(["--overwrite"] * overwrite))
    assert code != 0 and "Traceback" not in stderr
    assert [line for line in stderr.splitlines() if line.startswith("vpl_addon: error:")]
    assert blend.read_bytes() == before


def test_rendering_does_not_save_the_blend(blend, tmp_path):
    """A successful CLI render leaves the .blend byte-identical and makes no .blend1 backup."""
    before = blend.read_bytes()
    code, _, stderr = run_cli("render", blend, "-o", tmp_path / "out.exr", "--samples", "1", "--method", "none")
    assert code == 0, stderr
    assert blend.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.exr", "scene.blend"]


def test_engine_bug_in_blender_is_one_error_report_and_saves_nothing(blend, monkeypatch, capfd):
    """F12 path (bpy.ops.render.render with the VPL GI engine): a NaN made by the gather becomes one ERROR report
    naming method and stage, no traceback is printed, and the .blend is not touched."""
    import bpy
    from vpl_gi.operators.engine import render_engine as engine
    spoil_gather(monkeypatch)
    bpy.ops.wm.open_mainfile(filepath=str(blend))
    scene = bpy.context.scene
    scene.render.engine = "VPL_GI"
    scene.vpl_gi.method, scene.vpl_gi.samples, scene.vpl_gi.vpls = "ir", 1, 16
    before = blend.read_bytes()
    with pytest.raises(RuntimeError, match="stage 'gather'"):  # how bpy.ops hands an ERROR report to Python
        bpy.ops.render.render(scene=scene.name)
    errors = [m for level, m in engine.LAST_REPORTS if level == "ERROR"]
    assert len(errors) == 1 and "method 'ir', stage 'gather'" in errors[0] and "\n" not in errors[0]
    assert "Traceback" not in capfd.readouterr().err
    assert blend.read_bytes() == before and not list(blend.parent.glob("*.blend1"))


def test_failed_render_keeps_the_existing_image_even_with_overwrite(blend, tmp_path, monkeypatch, capsys):
    """The CLI with --overwrite over an existing image, and an engine bug mid-render: one error line naming the
    stage, the old image byte-identical, no partial file left."""
    from vpl_gi.operators.cli.commands import main
    spoil_gather(monkeypatch)
    out = tmp_path / "keep.exr"
    out.write_bytes(b"precious")
    code = main(["render", str(blend), "-o", str(out), "--overwrite", "--samples", "1", "--method", "ir",
                 "--vpls", "16"])
    err = capsys.readouterr().err
    assert code != 0 and "Traceback" not in err
    lines = [line for line in err.splitlines() if line.startswith("vpl_addon: error:")]
    assert len(lines) == 1 and lines[0].startswith("vpl_addon: error: method 'ir', stage 'gather': ")
    assert out.read_bytes() == b"precious"
    assert not list(tmp_path.glob(".partial-*"))


def test_killed_render_leaves_no_file_under_the_final_name(blend, tmp_path):
    """SIGKILL in the middle of a render: nothing appears under the output name; the dead run's partial file is
    removed by the next render into the same folder, which then succeeds."""
    out = tmp_path / "out.exr"
    proc = subprocess.Popen([sys.executable, "-m", "vpl_addon", "render", str(blend), "-o", str(out),
                             "--percentage", "800", "--samples", "256", "--method", "ir"], cwd=ROOT,
                            env={**os.environ, "PYTHONPATH": str(ROOT)}, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 120
        while not list(tmp_path.glob(".partial-*")) and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
        assert proc.poll() is None, "the render ended before it could be killed"
        time.sleep(0.5)
        proc.send_signal(signal.SIGKILL)
    finally:
        proc.kill()
        proc.wait()
    assert proc.returncode == -signal.SIGKILL
    assert not out.exists()
    assert list(tmp_path.glob(".partial-*"))  # the killed process could not clean up after itself
    code, _, stderr = run_cli("render", blend, "-o", out, "--samples", "1", "--method", "none")
    assert code == 0, stderr
    assert out.exists() and not list(tmp_path.glob(".partial-*"))
