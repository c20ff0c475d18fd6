"""The picture denoised as Cycles' render denoiser does it (issue 23): OpenImageDenoise on Combined, guided by the
Denoising Albedo and Denoising Normal passes, which carry Cycles' names and meanings."""
import numpy as np
import pytest

from conftest import ROOT

pytestmark = pytest.mark.blender

TOGGLES = ("use_pass_diffuse_color", "use_pass_glossy_color", "use_pass_normal")


def _render(bpy, path, engine_name, denoise, samples, size=64, method="vbnl", light_samples=1):
    """The PBR Cornell box (textures, metal) with the Denoising Data passes."""
    from vpl_gi.operators.output import render_to
    from vpl_gi.vpl_addon.core.exr import read_passes
    bpy.ops.wm.open_mainfile(filepath=str(ROOT / "example_blends" / "cornell_pbr.blend"))
    scene = bpy.context.scene
    scene.render.resolution_x = scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    layer = scene.view_layers[0]
    layer.cycles.denoising_store_passes = True
    for toggle in TOGGLES:
        setattr(layer, toggle, True)
    scene.render.engine = engine_name
    if engine_name == "CYCLES":
        scene.cycles.samples, scene.cycles.use_denoising, scene.cycles.use_adaptive_sampling = samples, denoise, False
    else:
        scene.vpl_gi.samples, scene.vpl_gi.light_samples, scene.vpl_gi.denoise = samples, light_samples, denoise
        scene.vpl_gi.method = method
    render_to(scene, str(path))
    return read_passes(str(path))[0]


def test_denoising_albedo_and_normal_are_cycles(ext, tmp_path):
    """Denoising Albedo is Diffuse + Glossy Color, Denoising Normal the Normal in camera space (x right, y up, z
    forward), as Cycles writes them: means over the covered pixels within 1 % (per channel of the albedo; the
    normal's mean direction within 0.01)."""
    import bpy
    from vpl_gi.operators import engine
    cycles = _render(bpy, tmp_path / "cycles.exr", "CYCLES", True, 16)
    ours = _render(bpy, tmp_path / "ours.exr", engine.VPLGIRenderEngine.bl_idname, True, 16)
    covered = (cycles["Combined"][..., 3] > 0.999) & (ours["Combined"][..., 3] > 0.999)
    assert covered.sum() > 0.5 * 64 * 64
    theirs, mine = cycles["Denoising Albedo"][covered].mean(0), ours["Denoising Albedo"][covered].mean(0)
    np.testing.assert_allclose(mine, theirs, rtol=0.01)
    theirs, mine = cycles["Denoising Normal"][covered].mean(0), ours["Denoising Normal"][covered].mean(0)
    assert np.abs(mine - theirs).max() < 0.01, (mine, theirs)
    assert np.abs(mine).max() > 0.3  # the walls' normals do not cancel out: the space is the camera's
    assert ours["Noisy Image"].shape == ours["Combined"].shape
    assert not [m for level, m in engine.LAST_REPORTS if level == "WARNING"]


def test_denoise_brings_a_few_samples_close_to_the_converged_picture(ext, tmp_path):
    """Direct light at 4 camera samples and 1 light sample, denoised, against the same engine converged (256 x 4),
    64 x 64: rMAE 0.140 noisy, 0.081 denoised. At 96 x 96 (256 x 8): 0.128 noisy, 0.070 denoised with the
    prefiltered guides; OIDN without guides 0.081, with them unfiltered 0.078 as clean, 0.079 as noisy guides."""
    import bpy
    from vpl_gi.operators import engine
    from vpl_gi.vpl_addon.evaluation.metrics import errors
    name = engine.VPLGIRenderEngine.bl_idname
    converged = _render(bpy, tmp_path / "converged.exr", name, False, 256, 64, "none", 4)["Combined"]
    ours = _render(bpy, tmp_path / "ours.exr", name, True, 4, 64, "none")
    covered = converged[..., 3] > 0.999
    noisy = errors(ours["Noisy Image"], converged, covered)["rmae"]
    clean = errors(ours["Combined"], converged, covered)["rmae"]
    print(f"Combined rMAE against the converged render: noisy {noisy:.4f}, denoised {clean:.4f}")
    assert clean < 0.6 * noisy
    assert np.array_equal(ours["Combined"][..., 3], ours["Noisy Image"][..., 3])
