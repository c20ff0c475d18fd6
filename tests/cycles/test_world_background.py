"""The world seen by camera rays (issue 22), as Cycles shows it: with *Film > Transparent* off, Combined holds the
world's radiance where camera rays miss and alpha is 1; with it on, the background is 0 and alpha the coverage. The
Environment pass holds the background either way, so Combined = the surfaces' passes + Environment (film not
transparent). A pixel on an edge blends the two with the weight of the samples that hit and miss."""
import numpy as np
import pytest

from conftest import add_mesh, add_sun

pytestmark = pytest.mark.blender

WORLD = np.array([0.2, 0.4, 0.8]) * 1.5  # Background Color x Strength


def _render(bpy, scene, path):
    from vpl_gi.operators.output.render_file import render_to
    from vpl_gi.vpl_addon.core.exr import read_passes
    render_to(scene, str(path))
    return read_passes(str(path))[0]


def _cube_under_a_blue_sky(bpy):
    """A cube lit by a sun and a blue world, seen from above at an angle with sky all around it. The cube is convex:
    no light goes from one of its faces to another, so Cycles' Combined has no indirect light to compare."""
    from mathutils import Vector
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 32, 24
    c = [(x, y, z) for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)]
    add_mesh(bpy, "Cube", c, [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)])
    add_sun(bpy, scene, (np.radians(35.0), 0.0, np.radians(20.0)), energy=2.0)
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.location = (3.0, -3.0, 2.5)
    cam.rotation_euler = (-Vector(cam.location)).to_track_quat("-Z", "Y").to_euler()
    scene.collection.objects.link(cam)
    scene.camera = cam
    world = bpy.data.worlds.new("Sky")
    world.use_nodes = True
    background = world.node_tree.nodes["Background"]
    background.inputs["Color"].default_value = (0.2, 0.4, 0.8, 1.0)
    background.inputs["Strength"].default_value = 1.5
    scene.world = world
    return scene


def test_the_world_shows_behind_the_geometry_unless_the_film_is_transparent(ext, tmp_path):
    import bpy
    from vpl_gi.operators.engine import render_engine as engine
    from vpl_gi.operators.output.reference import configure_cycles

    out = {}
    for who in ("cycles", "ours"):
        for transparent in (False, True):
            scene = _cube_under_a_blue_sky(bpy)
            configure_cycles(scene, 64)  # every pass on, Environment too
            scene.render.film_transparent = transparent
            if who == "ours":
                scene.render.engine = engine.VPLGIRenderEngine.bl_idname
                scene.vpl_gi.method, scene.vpl_gi.samples, scene.vpl_gi.light_samples = "none", 16, 4
                scene.vpl_gi.denoise = False  # Combined pixel by pixel: the estimate
            out[who, transparent] = _render(bpy, scene, tmp_path / f"{who}_{transparent}.exr")
    opaque, clear = out["ours", False], out["ours", True]
    alpha = clear["Combined"][..., 3]
    background, edge = alpha == 0.0, (alpha > 0.0) & (alpha < 1.0)
    assert background.sum() > 100 and edge.sum() > 10 and (alpha == 1.0).sum() > 30
    # Film > Transparent off: alpha 1 everywhere, the world's colour where nothing is hit
    assert (opaque["Combined"][..., 3] == 1.0).all()
    np.testing.assert_allclose(opaque["Combined"][background][:, :3], np.broadcast_to(WORLD, (background.sum(), 3)),
                               rtol=1e-6)
    # on: no background in Combined; alpha is where Cycles puts it
    assert (clear["Combined"][background][:, :3] == 0.0).all()
    assert alpha.mean() == pytest.approx(out["cycles", True]["Combined"][..., 3].mean(), rel=0.03)
    # an edge pixel blends the surface and the world by the share of its samples that miss: the passes add up
    np.testing.assert_allclose(opaque["Combined"][..., :3], clear["Combined"][..., :3] + clear["Environment"],
                               rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(clear["Environment"], (1.0 - alpha)[..., None] * WORLD, rtol=1e-5, atol=1e-6)
    # the Environment pass and Combined as Cycles has them (the cube is lit by the sun and by the sky)
    for name, transparent in (("Environment", False), ("Environment", True), ("Combined", False),
                              ("Combined", True)):
        ours = out["ours", transparent][name][..., :3].mean()
        cycles = out["cycles", transparent][name][..., :3].mean()
        print(f"{name} (transparent {transparent}): mean ours {ours:.4f}, Cycles {cycles:.4f}")
        assert ours == pytest.approx(cycles, rel=0.02), name


def test_an_hdri_shows_behind_the_geometry_as_in_cycles(ext, tmp_path):
    """The Environment Texture (rotated by a Mapping node) seen by camera rays: the same world light the engine
    samples for direct light, looked up along each ray's direction, pixel by pixel as Cycles shows it."""
    import bpy
    from test_environment_cycles import hdri_blend
    from vpl_gi.operators.engine import render_engine as engine
    from vpl_gi.operators.output.reference import configure_cycles

    blend = hdri_blend(tmp_path)
    out = {}
    for who in ("cycles", "ours"):
        bpy.ops.wm.open_mainfile(filepath=str(blend))
        scene = bpy.context.scene
        scene.render.resolution_x, scene.render.resolution_y = 32, 24
        scene.camera.location, scene.camera.rotation_euler = (0.0, -6.0, 1.0), (np.radians(95.0), 0.0, 0.0)
        configure_cycles(scene, 64)
        scene.render.film_transparent = False
        if who == "ours":
            scene.render.engine = engine.VPLGIRenderEngine.bl_idname
            scene.vpl_gi.method, scene.vpl_gi.samples, scene.vpl_gi.light_samples = "none", 16, 4
            scene.vpl_gi.denoise = False
        out[who] = _render(bpy, scene, tmp_path / f"{who}.exr")
    ours, cycles = out["ours"]["Environment"], out["cycles"]["Environment"]
    sky = cycles.mean(axis=2) > 0.0
    assert sky.sum() > 200  # most of the image is sky, the floor's far edge below it
    error = np.abs(ours - cycles)[sky].mean() / cycles[sky].mean()
    print(f"HDRI background: mean ours {ours[sky].mean():.4f}, Cycles {cycles[sky].mean():.4f}, "
          f"mean abs. difference {error:.4f} of the mean")
    assert ours[sky].mean() == pytest.approx(cycles[sky].mean(), rel=0.02)
    assert error < 0.03
    assert (out["ours"]["Combined"][..., 3] == 1.0).all()
