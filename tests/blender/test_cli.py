"""The command line with the real bpy module: render, compare, and bad input answered in one line."""
import json
import shutil

import numpy as np
import pytest

from conftest import EXAMPLES, ROOT, run_cli

pytestmark = pytest.mark.blender


def assert_one_line_error(code, err, *words):
    assert code != 0
    assert "Traceback" not in err
    lines = [l for l in err.splitlines() if l.startswith("vpl_addon: error:")]
    assert len(lines) == 1, err
    for word in words:
        assert word in lines[0]


def test_render_writes_cycles_named_passes_and_a_timing_line(small_blend, tmp_path):
    from vpl_addon.core.exr import read_passes
    out = tmp_path / "out.exr"
    code, stdout, stderr = run_cli("render", small_blend(), "-o", out, "--samples", "4", "--frame", "1")
    assert code == 0, stderr
    assert f"wrote {out}" in stdout and "rays" in stdout
    passes, _ = read_passes(str(out))
    assert {"Combined", "Diffuse Direct", "Diffuse Color"} <= set(passes)
    assert passes["Diffuse Direct"].mean() > 0 and np.isfinite(passes["Combined"]).all()
    assert passes["Combined"][..., 3].min() == 1.0  # the floor fills the frame


def test_vbnl_settings_reach_the_engine_from_the_command_line(tmp_path):
    out = tmp_path / "vbnl.exr"
    code, stdout, stderr = run_cli("render", EXAMPLES / "cornell_area.blend", "-o", out, "--percentage", "12",
                                   "--samples", "2", "--light-samples", "1", "--method", "vbnl", "--vpls", "300",
                                   "--photons", "5000", "--vbnl-samples", "3", "--elimination", "uniform",
                                   "--no-path-extension")
    assert code == 0, stderr
    assert "vbnl 300 VPLs, 5000 light paths" in stdout


def test_denoise_whole_reaches_the_engine(tmp_path):
    """``--denoise-whole`` turns the scene's Indirect Light Apart off: the same render (its light passes the same to
    the bit), denoised another way."""
    from vpl_addon.core.exr import read_passes
    images = []
    for flags in ((), ("--denoise-whole",)):
        out = tmp_path / f"denoised{len(flags)}.exr"
        code, _, stderr = run_cli("render", EXAMPLES / "cornell_area.blend", "-o", out, "--percentage", "12",
                                  "--samples", "2", "--light-samples", "1", "--denoise", *flags)
        assert code == 0, stderr
        images.append(read_passes(str(out))[0])
    np.testing.assert_array_equal(images[0]["Diffuse Direct"], images[1]["Diffuse Direct"])
    assert np.abs(images[0]["Combined"] - images[1]["Combined"]).max() > 1e-4


def test_clamp_indirect_reaches_the_engine_and_is_off_by_default(ext, tmp_path):
    """The panel's Clamp Indirect is 0 (off) until set; ``--clamp-indirect`` bounds every sample of the unfiltered
    Diffuse Indirect, which goes well above it unclamped."""
    import bpy
    from vpl_addon.core.exr import read_passes
    bpy.ops.wm.open_mainfile(filepath=str(EXAMPLES / "cornell_area.blend"))
    assert bpy.context.scene.vpl_gi.clamp_indirect == 0.0
    assert bpy.context.scene.vpl_gi.render_settings(("Combined",)).gather.clamp_indirect == 0.0
    peaks = []
    for flags in ((), ("--clamp-indirect", "0.05")):
        out = tmp_path / f"clamp{len(flags)}.exr"
        code, _, stderr = run_cli("render", EXAMPLES / "cornell_area.blend", "-o", out, "--percentage", "12",
                                  "--samples", "2", "--light-samples", "1", "--method", "ir", "--no-filter", *flags)
        assert code == 0, stderr
        peaks.append(read_passes(str(out))[0]["Diffuse Indirect"][..., :3].max())
    assert peaks[0] > 0.1 and peaks[1] <= 0.05 * (1 + 1e-6)


def test_gather_samples_follow_the_samples_until_set(ext):
    """The render panel's Gather Samples is 0 until set: vbnl then gathers one pair per camera sample, so a user
    who raises Samples (as in Cycles) raises the indirect light's samples too; a number set by hand holds."""
    import bpy
    from vpl_addon.methods.vbnl import gather_samples
    settings = bpy.context.scene.vpl_gi
    assert settings.vbnl_samples == 0 and settings.samples == 16
    settings.samples = 48
    built = settings.render_settings(("Combined",))
    assert gather_samples(built.placement, built.samples) == 48
    settings.vbnl_samples = 8
    built = settings.render_settings(("Combined",))
    assert gather_samples(built.placement, built.samples) == 8
    settings.samples, settings.vbnl_samples = 16, 0


def test_smc_warmup_draws_reach_the_engine_and_are_checked(ext, tmp_path):
    import bpy
    settings = bpy.context.scene.vpl_gi
    assert settings.smc_warmup_rounds == 16
    settings.smc_warmup_rounds = 100  # the paper's warm-up
    assert settings.render_settings(("Combined",)).placement.smc.warmup_rounds == 100
    settings.smc_warmup_rounds = 16
    code, _, stderr = run_cli("render", EXAMPLES / "cornell_area.blend", "-o", tmp_path / "smc.exr", "--method",
                              "smc", "--smc-warmup-rounds", "0")
    assert_one_line_error(code, stderr, "--smc-warmup-rounds 0", "at least 1")
    assert not (tmp_path / "smc.exr").exists()


def test_existing_output_is_not_overwritten_without_asking(small_blend, tmp_path):
    out = tmp_path / "keep.exr"
    out.write_bytes(b"precious")
    code, _, stderr = run_cli("render", small_blend(), "-o", out, "--samples", "1")
    assert_one_line_error(code, stderr, "--overwrite")
    assert out.read_bytes() == b"precious"


def test_missing_file(tmp_path):
    code, _, stderr = run_cli("render", tmp_path / "nope.blend", "-o", tmp_path / "o.exr")
    assert_one_line_error(code, stderr, "no such file", "nope.blend")
    assert not (tmp_path / "o.exr").exists()


def test_bench_from_an_installed_extension_says_where_it_runs(tmp_path):
    """The extension ships without bench/ (manifest excludes): ``bench`` says so in one line."""
    for part in ("__init__.py", "blender_manifest.toml", "vpl_addon", "operators", "importers"):
        copy = shutil.copytree if (ROOT / part).is_dir() else shutil.copy
        copy(ROOT / part, tmp_path / part)
    code, _, stderr = run_cli("bench", EXAMPLES / "cornell_area.blend", "--quick", cwd=tmp_path)
    assert_one_line_error(code, stderr, "from a clone of the repository", "bench/")


def test_scene_without_camera(small_blend, tmp_path):
    code, _, stderr = run_cli("render", small_blend(camera=False), "-o", tmp_path / "o.exr")
    assert_one_line_error(code, stderr, "no active camera")
    assert not list(tmp_path.glob("*.exr"))


def test_scene_without_lights_renders_black_and_says_so(small_blend, tmp_path):
    from vpl_addon.core.exr import read_passes
    code, _, stderr = run_cli("render", small_blend(light=False), "-o", tmp_path / "o.exr", "--samples", "2")
    assert code == 0 and "no lights" in stderr
    passes, _ = read_passes(str(tmp_path / "o.exr"))
    assert passes["Diffuse Direct"].max() == 0.0


def test_degenerate_triangles_are_skipped_with_a_warning_naming_the_object(small_blend, tmp_path):
    code, _, stderr = run_cli("render", small_blend(degenerate=True), "-o", tmp_path / "o.exr", "--samples", "2")
    assert code == 0 and "'Sliver'" in stderr and "degenerate" in stderr


def test_compare_prints_json_per_pass_and_writes_a_heatmap(small_blend, tmp_path):
    blend = small_blend()
    a, b = tmp_path / "a.exr", tmp_path / "b.exr"
    assert run_cli("render", blend, "-o", a, "--samples", "2", "--seed", "1")[0] == 0
    assert run_cli("render", blend, "-o", b, "--samples", "2", "--seed", "2")[0] == 0
    code, stdout, stderr = run_cli("compare", a, b, "--heatmap", tmp_path / "err.png")
    assert code == 0, stderr
    result = json.loads(stdout)
    dd = result["Diffuse Direct"]
    assert 0 < dd["rmae"] < 0.5 and abs(dd["mean_ratio"] - 1) < 0.1
    assert (tmp_path / "err.png").stat().st_size > 1000


def test_compare_of_a_missing_file(tmp_path):
    code, _, stderr = run_cli("compare", tmp_path / "a.exr", EXAMPLES / "nothing.exr")
    assert_one_line_error(code, stderr, "no such file")
