"""Depth of field against Cycles: emissive stripes 6 m away (on a black backdrop, so that every pixel is covered and
counts) and a small glowing square at 2 m, seen through a wide
open lens (f/0.25 at 50 mm) focused on an empty beside the square; the stripes blur as in Cycles and the square
stays sharp. The focus object decides the focus (its distance along the view axis), not the focus distance."""

import numpy as np
import pytest

from conftest import add_mesh, camera_and_black_world, combined_against_cycles, shader_material

pytestmark = pytest.mark.blender


def lens_blend(tmp_path, dof: bool = True):
    import bpy
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 48, 32
    glow = shader_material(bpy, "Glow", "ShaderNodeEmission", {"Color": (1.0, 0.9, 0.7, 1.0), "Strength": 1.0})
    for i in range(-5, 5):  # 0.5 m stripes, 0.5 m apart, on a plane 6 m ahead
        x = 1.0 * i
        add_mesh(bpy, f"Stripe{i}", [(x, 6, -3), (x, 6, 3), (x + 0.5, 6, 3), (x + 0.5, 6, -3)], [(0, 1, 2, 3)], glow)
    black = shader_material(bpy, "Black", "ShaderNodeBsdfDiffuse", {"Color": (0.0, 0.0, 0.0, 1.0)})
    add_mesh(bpy, "Backdrop", [(-20, 6.1, -20), (-20, 6.1, 20), (20, 6.1, 20), (20, 6.1, -20)], [(0, 1, 2, 3)], black)
    add_mesh(bpy, "Square", [(0.2, 2, -0.1), (0.2, 2, 0.1), (0.4, 2, 0.1), (0.4, 2, -0.1)], [(0, 1, 2, 3)], glow)
    camera_and_black_world(bpy, scene, (0.0, 0.0, 0.0), (np.radians(90.0), 0.0, 0.0))  # looking along +Y
    dof_settings = scene.camera.data.dof
    dof_settings.use_dof = dof
    dof_settings.aperture_fstop = 0.25
    dof_settings.aperture_blades = 5
    dof_settings.focus_distance = 10.0  # not used: the focus object is 2 m ahead along the view
    target = bpy.data.objects.new("Focus", None)
    target.location = (-1.5, 2.0, 0.8)
    scene.collection.objects.link(target)
    dof_settings.focus_object = target
    path = tmp_path / ("lens.blend" if dof else "pinhole.blend")
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    return path


def test_depth_of_field_blurs_and_keeps_in_focus_what_cycles_does(ext, tmp_path):
    import bpy
    from vpl_gi.operators.scene.extract import camera_of
    blend = lens_blend(tmp_path)
    camera = camera_of(bpy.context.scene, bpy.context.evaluated_depsgraph_get())
    assert abs(camera.focus - 2.0) < 1e-6 and abs(camera.aperture - 0.05 / 0.5) < 1e-9 and camera.blades == 5
    e_ours, e_pinhole, e_cycles = combined_against_cycles(blend, lens_blend(tmp_path, dof=False), tmp_path)
    print(f"depth of field: rMAE ours {e_ours['rmae']:.4f}, pinhole {e_pinhole['rmae']:.4f}, Cycles 64 spp "
          f"{e_cycles['rmae']:.4f}; mean ratio {e_ours['mean_ratio']:.4f}")
    assert e_ours["rmae"] <= 1.5 * e_cycles["rmae"] + 0.01 and abs(e_ours["mean_ratio"] - 1.0) < 0.02
    assert e_pinhole["rmae"] > 3.0 * e_ours["rmae"]  # the stripes sharp where Cycles blurs them
