"""A fence cut out of a plane by its image's alpha (the glTF importer's alpha clip: Alpha = 1 - (a < 0.5))
between a low sun and a floor, seen from above: the engine's ``Diffuse Direct`` against Cycles on the same .blend,
so the stripes of light through the fence fall where Cycles puts them (rMAE, not only the mean), and the camera
sees the floor through the fence's holes."""

import numpy as np
import pytest

from conftest import add_mesh, add_sun, assert_direct_as_cycles, camera_and_black_world, direct_against_cycles

pytestmark = pytest.mark.blender


def fence_blend(tmp_path):
    import bpy
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.resolution_x = scene.render.resolution_y = 48
    add_mesh(bpy, "Floor", [(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)], [(0, 1, 2, 3)])  # and an upright fence
    fence_obj = add_mesh(bpy, "Fence", [(-1.5, 0, 0), (1.5, 0, 0), (1.5, 0, 2), (-1.5, 0, 2)], [(0, 1, 2, 3)])
    fence = fence_obj.data
    layer = fence.uv_layers.new(name="UVMap")
    for loop, uv in zip(fence.loops, ((0, 0), (1, 0), (1, 1), (0, 1))):
        layer.data[loop.index].uv = uv

    # 16 x 16 RGBA: four opaque bars along v with holes between, and a ramp of alpha the clip turns into 0 or 1
    size = 16
    x = (np.arange(size) + 0.5) / size
    alpha = (((x * 8).astype(int) % 2 == 0) * (0.3 + 0.7 * x[:, None])).astype(np.float32)
    image = bpy.data.images.new("Bars", size, size, alpha=True)
    pixels = np.concatenate([np.full((size, size, 3), 0.8, np.float32), alpha[..., None]], axis=2)
    image.pixels.foreach_set(pixels.ravel())
    image.pack()
    mat = bpy.data.materials.new("Fence")
    if mat.node_tree is None:  # Blender < 5.0
        mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    bsdf = nodes["Principled BSDF"]
    bsdf.inputs["Specular IOR Level"].default_value = 0.0
    tex = nodes.new("ShaderNodeTexImage")
    tex.image = image
    less, one_minus = nodes.new("ShaderNodeMath"), nodes.new("ShaderNodeMath")  # as the glTF importer builds them
    less.operation, one_minus.operation = "LESS_THAN", "SUBTRACT"
    less.inputs[1].default_value = 0.5
    one_minus.inputs[0].default_value = 1.0
    links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    links.new(tex.outputs["Alpha"], less.inputs[0])
    links.new(less.outputs[0], one_minus.inputs[1])
    links.new(one_minus.outputs[0], bsdf.inputs["Alpha"])
    fence_obj.data.materials.append(mat)

    # from behind the fence, 35 degrees high: a long shadow
    add_sun(bpy, scene, (np.radians(-55.0), 0.0, 0.0), energy=3.0, angle=np.radians(1.0))
    camera_and_black_world(bpy, scene, (0.0, 0.0, 7.0))
    path = tmp_path / "fence.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    return path


def test_a_cut_out_fence_casts_the_shadow_cycles_renders(ext, tmp_path):
    e_ours, e_cycles, stderr = direct_against_cycles("fence", fence_blend(tmp_path), tmp_path)
    assert_direct_as_cycles(e_ours, e_cycles, stderr)
    # without the holes the floor under the fence would be dark: the stripes are the shadow's, not noise
    from vpl_gi.vpl_addon.core.exr import read_passes
    ref, _ = read_passes(str(tmp_path / "reference.exr"))
    lit = ref["Diffuse Direct"][..., 0]
    assert (lit > 0.5).mean() > 0.3 and (lit < 0.05).mean() > 0.03  # four bar shadows: 4.6 % of the pixels
