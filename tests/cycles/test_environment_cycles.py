"""An HDR environment (an Environment Texture rotated by a Mapping node) lights a floor and a block: the engine's
``Diffuse Direct`` against Cycles on the same .blend, so the map's orientation, strength and importance sampling are
Cycles'. The block's shadow from the map's small bright sun is where Cycles puts it (rMAE, not only the mean)."""

import numpy as np
import pytest

from conftest import add_mesh, direct_against_cycles
from test_environment import sky

pytestmark = pytest.mark.blender


def hdri_blend(tmp_path):
    import bpy
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.resolution_x = scene.render.resolution_y = 48
    add_mesh(bpy, "Floor", [(-4, -4, 0), (4, -4, 0), (4, 4, 0), (-4, 4, 0)], [(0, 1, 2, 3)])
    c = [(x, y, z) for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (0.0, 1.0)]
    add_mesh(bpy, "Block", c, [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)])
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.location = (0, 0, 9)
    scene.collection.objects.link(cam)
    scene.camera = cam

    import OpenEXR
    image = sky(h=64, w=128, sun=(0.30, 0.75), sun_radiance=300.0).astype(np.float32)
    # written as the exact numbers (Blender's image.save() colour-manages a generated float image); EXR rows run
    # from the top, Blender's pixels from the bottom
    with OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage},
                      {"RGB": np.ascontiguousarray(image[::-1])}) as f:
        f.write(str(tmp_path / "sky.exr"))
    world = bpy.data.worlds.new("Sky")
    scene.world = world
    world.use_nodes = True
    nodes, links = world.node_tree.nodes, world.node_tree.links
    background = nodes["Background"]
    background.inputs["Strength"].default_value = 0.5
    env = nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.load(str(tmp_path / "sky.exr"))
    mapping = nodes.new("ShaderNodeMapping")
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, np.radians(60.0))
    coords = nodes.new("ShaderNodeTexCoord")
    links.new(coords.outputs["Generated"], mapping.inputs["Vector"])
    links.new(mapping.outputs["Vector"], env.inputs["Vector"])
    links.new(env.outputs["Color"], background.inputs["Color"])
    path = tmp_path / "hdri.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    return path


def test_an_hdri_lights_and_shadows_as_in_cycles(ext, tmp_path):
    e_ours, e_cycles, stderr = direct_against_cycles("hdri", hdri_blend(tmp_path), tmp_path)
    assert "warning" not in stderr, stderr
    assert abs(e_ours["mean_ratio"] - 1.0) <= 0.02
    assert e_ours["rmae"] <= 1.5 * e_cycles["rmae"]
