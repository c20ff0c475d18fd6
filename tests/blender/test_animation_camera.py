"""Animation renders through Blender (issue 22): ``render(animation=True)`` (Ctrl+F12, ``blender -a``) must render
every frame from that frame's camera. The engine reads the camera from the render depsgraph's evaluated object: the
original object's matrix is not moved by the animation system during an animation render, and reading it froze the
camera at its first position while everything else moved."""
import numpy as np
import pytest

from conftest import add_mesh, add_sun

pytestmark = pytest.mark.blender


def _animated_camera_scene(bpy):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.resolution_x = scene.render.resolution_y = 32
    add_mesh(bpy, "Floor", [(-4, -4, 0), (4, -4, 0), (4, 4, 0), (-4, 4, 0)], [(0, 1, 2, 3)])
    bpy.ops.mesh.primitive_cube_add(size=1.5, location=(0.0, 0.0, 0.75))
    add_sun(bpy, scene, (np.radians(40.0), 0.0, np.radians(30.0)), energy=3.0)
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(cam)
    scene.camera = cam
    # frame 1 looks at the cube's lit side from the front, frame 3 straight down from above, with a longer lens
    for frame, location, rotation, lens in ((1, (0.0, -7.0, 2.0), (np.radians(80.0), 0.0, 0.0), 35.0),
                                            (3, (0.0, 0.0, 9.0), (0.0, 0.0, 0.0), 50.0)):
        cam.location, cam.rotation_euler, cam.data.lens = location, rotation, lens
        cam.keyframe_insert("location", frame=frame)
        cam.keyframe_insert("rotation_euler", frame=frame)
        cam.data.keyframe_insert("lens", frame=frame)
    world = bpy.data.worlds.new("Black")
    scene.world = world
    scene.frame_start, scene.frame_end = 1, 3
    scene.frame_set(1)
    return scene


def test_an_animated_camera_renders_each_frame_from_where_it_is(ext, tmp_path):
    import bpy
    from vpl_gi.operators.engine import render_engine as engine
    from vpl_gi.operators.output.render_file import configure_multilayer_exr
    from vpl_gi.operators.output.reference import configure_cycles
    from vpl_gi.vpl_addon.core.exr import read_passes

    means = {}
    for who in ("cycles", "ours"):
        scene = _animated_camera_scene(bpy)
        configure_cycles(scene, 64)
        if who == "ours":
            scene.render.engine = engine.VPLGIRenderEngine.bl_idname
            scene.vpl_gi.method, scene.vpl_gi.samples, scene.vpl_gi.light_samples = "none", 16, 4
        configure_multilayer_exr(scene)
        scene.render.filepath = str(tmp_path / f"{who}_####.exr")
        bpy.ops.render.render(animation=True)
        frames = [read_passes(str(tmp_path / f"{who}_{f:04d}.exr"))[0] for f in (1, 2, 3)]
        # a divided pass gives a pixel its surface's full light whatever share of it the surface covers, so its mean
        # grows with the samples that find the edges' slivers; times the coverage (alpha) it does not
        means[who] = [(f["Diffuse Direct"][..., :3] * f["Combined"][..., 3:]).mean() for f in frames]
    cycles, ours = np.array(means["cycles"]), np.array(means["ours"])
    assert abs(cycles[2] / cycles[0] - 1) > 0.1  # the frames differ: the camera moved
    np.testing.assert_allclose(ours, cycles, rtol=0.02)
