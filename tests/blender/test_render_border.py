"""Render border and crop (issue 22), as Cycles does them: only the border's pixels are traced, on the whole frame's
view plane, and Blender gets a result of the border's size, which it writes as it is (crop) or put back into the
full frame with nothing around it (no crop).

The border's pixels are those of the whole frame, not the same bytes: a block of pixels draws its random numbers from
(seed, block), and the border's blocks are not the frame's, so the sub-pixel positions and light samples differ.
Where the picture does not depend on them (inside a face lit by a sun: no noise) the pixels are equal to 1e-5; at
edges they differ by sub-pixel noise, which is checked to be far below what one pixel of misalignment would make.
The virtual lights are placed from the whole frame (their random numbers do not depend on the border), so the
indirect light of the border is the whole frame's too."""
import numpy as np
import pytest

from conftest import add_mesh, add_sun, camera_and_black_world, shader_material

pytestmark = pytest.mark.blender

# border corners (x from the left, y from the bottom, as Blender gives them) and the pixels they keep in a 32x24
# frame: columns int(0.15 * 32) = 4 .. int(0.65 * 32) = 20, y from the bottom int(0.05 * 24) = 1 .. int(0.55 * 24)
# = 13, so rows 11..23 from the top: the cube's foot, its shadow and the floor around
BORDER = (0.15, 0.65, 0.05, 0.55)
ROWS, COLS = slice(11, 23), slice(4, 20)


def _shifted(image, dy, dx):
    """The frame's pixels ``dy`` rows and ``dx`` columns away from those of the border."""
    return image[ROWS.start + dy:ROWS.stop + dy, COLS.start + dx:COLS.stop + dx]


def _uniform(image):
    """Where the frame's pixel of the border and its 8 neighbours hold one non-zero value."""
    window = np.stack([_shifted(image, dy, dx) for dy in (-1, 0, 1) for dx in (-1, 0, 1)])
    return (np.abs(window - image[ROWS, COLS][None]).max(axis=(0, 3)) < 1e-6) & (image[ROWS, COLS].max(2) > 0)


def _cube_on_a_floor(bpy, size=(32, 24)):
    from mathutils import Vector
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = size
    add_mesh(bpy, "Floor", [(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)], [(0, 1, 2, 3)])
    c = [(x, y, z) for x in (-0.6, 0.6) for y in (-0.6, 0.6) for z in (0.0, 1.2)]
    blue = shader_material(bpy, "Blue", "ShaderNodeBsdfDiffuse", {"Color": (0.2, 0.4, 0.8, 1.0)})
    add_mesh(bpy, "Cube", c, [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)],
             blue)
    add_sun(bpy, scene, (np.radians(40.0), 0.0, np.radians(30.0)), energy=3.0, angle=0.0)
    where = Vector((3.5, -4.5, 4.0))
    camera_and_black_world(bpy, scene, where, (Vector((0.0, 0.0, 0.4)) - where).to_track_quat("-Z", "Y").to_euler())
    scene.render.film_transparent = True
    return scene


def _render(bpy, tmp_path, name, border=None, crop=False, size=(32, 24), **settings):
    from vpl_gi.operators.engine import render_engine as engine
    from vpl_gi.operators.output.render_file import render_to
    from vpl_gi.vpl_addon.core.exr import read_passes
    scene = _cube_on_a_floor(bpy, size)
    scene.render.engine = engine.VPLGIRenderEngine.bl_idname
    layer = scene.view_layers[0]
    layer.use_pass_diffuse_direct = layer.use_pass_diffuse_indirect = layer.use_pass_diffuse_color = True
    # the estimate itself (the denoiser, tested in test_denoise.py, sees the border's pixels only, not the frame's)
    for key, value in {"samples": 16, "light_samples": 2, "method": "none", "denoise": False, **settings}.items():
        setattr(scene.vpl_gi, key, value)
    if border is not None:
        r = scene.render
        r.use_border, r.use_crop_to_border = True, crop
        r.border_min_x, r.border_max_x, r.border_min_y, r.border_max_y = border
    path = tmp_path / f"{name}.exr"
    render_to(scene, str(path))
    assert not [m for level, m in engine.LAST_REPORTS if level == "ERROR"]
    return read_passes(str(path))[0]


def test_a_border_renders_the_frames_pixels_cropped_or_in_place(ext, tmp_path):
    import bpy
    full = _render(bpy, tmp_path, "full", samples=64)
    cropped = _render(bpy, tmp_path, "crop", BORDER, crop=True, samples=64)
    in_place = _render(bpy, tmp_path, "in_place", BORDER, crop=False, samples=64)
    assert cropped["Combined"].shape == (12, 16, 4) and in_place["Combined"].shape == (24, 32, 4)
    outside = np.ones((24, 32), bool)
    outside[ROWS, COLS] = False
    for name, image in cropped.items():  # the same computation: the same bytes, in the border's place
        np.testing.assert_array_equal(in_place[name][ROWS, COLS], image, err_msg=name)
        assert (in_place[name][outside] == 0.0).all(), name
    # inside the faces, where the whole frame's pixel and its 8 neighbours see one surface in one light, the
    # border's pixel is the frame's
    inside = _uniform(full["Diffuse Color"]) & _uniform(full["Diffuse Direct"])
    assert inside.sum() > 60
    for name in ("Combined", "Diffuse Direct", "Diffuse Color"):
        mine, frame = cropped[name], full[name]
        same = np.abs(mine - frame[ROWS, COLS])[~inside].mean()
        shifted = min(np.abs(mine - _shifted(frame, dy, dx))[~inside].mean() for dy, dx in ((0, 1), (1, 0)))
        print(f"{name}: max difference at {inside.sum()} pixels inside faces "
              f"{np.abs(mine - frame[ROWS, COLS])[inside].max():.2e}; mean difference at the others {same:.4f}, "
              f"{shifted:.4f} one pixel off")
        np.testing.assert_allclose(mine[inside], frame[ROWS, COLS][inside], rtol=1e-5, atol=1e-6)
        # at edges, sub-pixel noise: far less than one pixel of misalignment
        assert same < 0.2 * shifted


@pytest.mark.parametrize("method, tolerance", [("ir", 0.02), ("vbnl", 0.05)])
def test_the_indirect_methods_light_a_border_as_the_whole_frame(ext, tmp_path, method, tolerance):
    """The same virtual lights light the border and the frame, and the filter reads the pixels around the border
    too, so the border's edge pixels are filtered as in the frame. ``ir`` sums each pixel's VPLs (no noise but
    where its 16 gathering samples land: border / frame 1.006 and 0.997 for seeds 0 and 3); ``vbnl`` samples its
    lights per pixel (at 64 sample pairs, border / frame 0.987 to 1.022 over 8 seeds; 0.92 to 1.09 at 16)."""
    import bpy
    settings = dict(method=method, vpls=1024, photons=16384, vbnl_samples=64, indirect_samples=16)
    full = _render(bpy, tmp_path, "full", **settings)["Diffuse Indirect"][ROWS, COLS]
    border = _render(bpy, tmp_path, "border", BORDER, crop=True, **settings)["Diffuse Indirect"]
    print(f"{method}: Diffuse Indirect mean of the border {border.mean():.4f}, of the frame there {full.mean():.4f}")
    assert np.isfinite(border).all() and border.mean() > 0.0
    assert border.mean() == pytest.approx(full.mean(), rel=tolerance)


def test_f12_shows_each_finished_band_of_rows(ext, tmp_path):
    """Progressive F12: a 128 x 96 frame is three blocks of 4096 pixels, so Blender is handed three bands of finished
    rows before the whole result (each through begin_result / end_result, as Cycles' tiles); with a border, the
    border's rows, in the border's result."""
    import bpy
    from vpl_gi.operators.engine import render_engine as engine
    for border, size, bands in ((None, (128, 96), 3), (BORDER, (256, 192), 3)):
        image = _render(bpy, tmp_path, "bands", border, crop=True, size=size, samples=1, light_samples=1)["Combined"]
        assert engine.LAST_STATS["bands_shown"] == bands
        assert image.shape[2] == 4 and image[..., 3].mean() > 0.5
