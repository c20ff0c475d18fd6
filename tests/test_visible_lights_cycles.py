"""An area light the camera sees (its Ray Visibility > Camera on, as the converted scenes' lights have it): seen
from below, through an orthographic camera, in front of a ceiling. Cycles adds the light's radiance to what the ray
finds behind it (the light hides nothing) and to the Denoising Albedo; the Emit pass holds the light alone. Before,
the engine drew no light at all: cornell_measured's ceiling lamp was missing from our picture (rMAE of the denoised
picture 0.0383 against Cycles + OIDN's 0.0310 at 64 samples, 0.0297 with the lamp drawn)."""

import numpy as np
import pytest

from conftest import add_mesh, camera_and_black_world

pytestmark = pytest.mark.blender


def lamp_under_a_ceiling(bpy, visible):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.resolution_x = scene.render.resolution_y = 32
    add_mesh(bpy, "Floor", [(-2, -2, 0), (2, -2, 0), (2, 2, 0), (-2, 2, 0)], [(0, 1, 2, 3)])
    add_mesh(bpy, "Ceiling", [(-2, -2, 1.5), (-2, 2, 1.5), (2, 2, 1.5), (2, -2, 1.5)], [(0, 1, 2, 3)])
    lamp = bpy.data.objects.new("Lamp", bpy.data.lights.new("Lamp", "AREA"))
    lamp.data.size, lamp.data.energy = 0.8, 20.0
    lamp.location, lamp.visible_camera = (0.0, 0.0, 1.0), visible
    scene.collection.objects.link(lamp)
    camera_and_black_world(bpy, scene, (0.0, 0.0, 0.2), (np.pi, 0.0, 0.0))  # looking up
    scene.camera.data.type, scene.camera.data.ortho_scale, scene.camera.data.clip_start = "ORTHO", 2.0, 0.01
    layer = scene.view_layers[0]
    layer.cycles.denoising_store_passes, layer.use_pass_emit = True, True


def rendered(bpy, tmp_path, engine_name, visible=True):
    from vpl_gi.operators.output import render_to
    from vpl_gi.vpl_addon.core.exr import LAYER, read_passes
    lamp_under_a_ceiling(bpy, visible)
    scene = bpy.context.scene
    scene.render.engine = engine_name
    if engine_name == "CYCLES":
        scene.cycles.samples, scene.cycles.use_denoising = 16, False
    else:
        scene.vpl_gi.denoise = False
    path = tmp_path / f"{engine_name}_{visible}.exr"
    render_to(scene, str(path))
    return read_passes(str(path), LAYER)[0]


def test_an_area_light_the_camera_sees_is_drawn_as_cycles_draws_it(ext, tmp_path):
    import bpy
    from vpl_gi.operators import engine
    cycles = rendered(bpy, tmp_path, "CYCLES")
    ours = rendered(bpy, tmp_path, engine.VPLGIRenderEngine.bl_idname)
    radiance = 20.0 / (0.8 * 0.8 * np.pi)  # Blender: an area light's power over its area and pi
    assert ours["Emit"][16, 16, :3] == pytest.approx([radiance] * 3, rel=1e-3)
    for name in ("Combined", "Denoising Albedo"):  # the light and, behind it, the ceiling
        assert ours[name][16, 16, :3] == pytest.approx(cycles[name][16, 16, :3], rel=0.02), name
    assert ours["Combined"][16, 16, 0] > radiance  # the ceiling shows through
    hidden = rendered(bpy, tmp_path, engine.VPLGIRenderEngine.bl_idname, visible=False)
    assert hidden["Emit"].max() == 0.0 and hidden["Combined"][16, 16, 0] < 1.0
