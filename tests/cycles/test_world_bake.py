"""Worlds read through Cycles (``operators/scene/world_bake.py``): a Sky Texture lights a scene as Cycles lights it, and
the baked map has the engine's orientation, is cached by the tree and baked again when the tree changes."""
import math

import numpy as np
import pytest

from conftest import add_mesh, assert_direct_as_cycles, direct_against_cycles
from test_extract import CUBE_F, CUBE_V, extracted

pytestmark = pytest.mark.blender


@pytest.fixture
def world_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("VPL_GI_CACHE", str(tmp_path / "cache"))
    return tmp_path / "cache" / "worlds"


def _world(bpy, name):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    world = bpy.data.worlds.new(name)
    bpy.context.scene.world = world
    return world, world.node_tree.nodes, world.node_tree.links


def test_the_baked_map_is_oriented_as_the_engine_reads_it_and_cached(ext, world_cache):
    import bpy
    world, nodes, links = _world(bpy, "Directions")  # each direction's colour is the direction: (d + 1) / 2
    coords, scaled = nodes.new("ShaderNodeTexCoord"), nodes.new("ShaderNodeVectorMath")
    scaled.operation = "MULTIPLY_ADD"
    scaled.inputs[1].default_value = scaled.inputs[2].default_value = (0.5, 0.5, 0.5)
    links.new(coords.outputs["Generated"], scaled.inputs[0])
    links.new(scaled.outputs[0], nodes["Background"].inputs["Color"])
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    bpy.context.scene.collection.objects.link(cam)
    bpy.context.scene.camera = cam
    scene, warnings = extracted(bpy)
    assert warnings == [] and scene.environment is not None
    from vpl_gi.vpl_addon.lights.environment import EnvironmentLight
    light = EnvironmentLight(scene.environment.image, scene.environment.rotation)
    w = np.random.default_rng(1).normal(size=(2000, 3))
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    assert np.abs(light.radiance(w) - (w + 1) / 2).max() < 0.03

    from vpl_gi.operators.scene.world_bake import world_digest
    cached = sorted(world_cache.glob("*.npy"))
    assert [p.stem for p in cached] == [world_digest(world)]
    before = world_digest(world)
    scaled.inputs[1].default_value = (0.25, 0.5, 0.5)
    assert world_digest(world) != before
    scene, _ = extracted(bpy)
    assert len(list(world_cache.glob("*.npy"))) == 2  # the changed tree is baked again
    red = EnvironmentLight(scene.environment.image).radiance(w)[:, 0]
    assert np.abs(red - (0.25 * w[:, 0] + 0.5)).max() < 0.03


def sky_blend(tmp_path):
    import bpy
    world, nodes, links = _world(bpy, "Sky")
    sky = nodes.new("ShaderNodeTexSky")
    sky.sun_elevation, sky.sun_rotation = math.radians(35.0), math.radians(60.0)
    links.new(sky.outputs["Color"], nodes["Background"].inputs["Color"])
    nodes["Background"].inputs["Strength"].default_value = 0.2
    scene = bpy.context.scene
    scene.render.resolution_x = scene.render.resolution_y = 48
    add_mesh(bpy, "Floor", [(-4, -4, 0), (4, -4, 0), (4, 4, 0), (-4, 4, 0)], [(0, 1, 2, 3)])
    add_mesh(bpy, "Box", CUBE_V, CUBE_F, location=(0, 0, 1))
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.location, cam.rotation_euler = (0, -9, 7), (math.radians(52), 0, 0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    path = tmp_path / "sky.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    return path


def test_a_sky_texture_lights_the_scene_as_cycles_does(ext, tmp_path, world_cache):
    e_ours, e_cycles, stderr = direct_against_cycles("sky", sky_blend(tmp_path), tmp_path)
    assert_direct_as_cycles(e_ours, e_cycles, stderr)  # the sun's shadow of the box where Cycles puts it


def test_esc_stops_the_bake_which_says_what_it_does_and_caches_nothing(ext, world_cache):
    """While Cycles bakes, the engine's status line is told so (F12 shows it) and ESC stops the bake at once."""
    import bpy
    from vpl_gi.operators.scene.extract import extract
    from vpl_gi.vpl_addon.render import Cancelled
    world, nodes, links = _world(bpy, "Sky to cancel")
    links.new(nodes.new("ShaderNodeTexSky").outputs["Color"], nodes["Background"].inputs["Color"])
    bpy.context.scene.camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    told = []
    with pytest.raises(Cancelled):
        extract(bpy.context.evaluated_depsgraph_get(), lambda text: bool(told.append(text)))  # False: ESC
    assert len(told) == 1 and told[0].startswith("baking the world with Cycles (256 samples")
    assert not list(world_cache.glob("*.npy"))
