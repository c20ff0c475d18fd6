"""An 8-bit sRGB image texture magnified on a plane, seen by an orthographic camera: the engine's ``Diffuse Color``
across the blend between two texels against Cycles'. Cycles keeps such an image sRGB-encoded and makes the result
of its bilinear lookup linear, so the blend from black to white is the sRGB curve, not a straight line (at its
middle 0.21, not 0.5): the checkerboard's edges of cornell_textured were where our picture differed most from
Cycles'. And a Checker Texture node of UV coordinates (veach_ajar's floor), straight and through a Mapping node,
drawn cell for cell as Cycles draws it."""

import numpy as np
import pytest

from conftest import add_mesh, add_sun, camera_and_black_world, run_cli

pytestmark = pytest.mark.blender


def plane_blend(tmp_path, name, size, colour):
    """A plane with UVs 0-1 that an orthographic camera sees whole (``size`` pixels), lit by a sun; its material's
    Base Color comes from the output ``colour(bpy, nodes, links)`` returns."""
    import bpy
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = size
    plane = add_mesh(bpy, "Plane", [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], [(0, 1, 2, 3)])
    layer = plane.data.uv_layers.new(name="UVMap")
    for loop, uv in zip(plane.data.loops, ((0, 0), (1, 0), (1, 1), (0, 1))):
        layer.data[loop.index].uv = uv
    mat = bpy.data.materials.new(name)
    if mat.node_tree is None:  # Blender < 5.0
        mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    links.new(colour(bpy, nodes, links), nodes["Principled BSDF"].inputs["Base Color"])
    plane.data.materials.append(mat)
    add_sun(bpy, scene, (0.0, 0.0, 0.0), energy=1.0)
    camera_and_black_world(bpy, scene, (0.0, 0.0, 5.0))
    scene.camera.data.type, scene.camera.data.ortho_scale = "ORTHO", 2.0
    path = tmp_path / f"{name}.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    return path


def ramp_blend(tmp_path, colorspace):
    """A 2 x 1 image (black, white) in ``colorspace`` stretched over the plane: 64 pixels across, the blend
    between the two texel centres over the middle 32."""
    def ramp(bpy, nodes, links):
        image = bpy.data.images.new("Ramp", 2, 1, alpha=False)
        image.colorspace_settings.name = colorspace
        image.pixels.foreach_set(np.array([0, 0, 0, 1, 1, 1, 1, 1], np.float32))
        image.pack()
        tex = nodes.new("ShaderNodeTexImage")
        tex.image, tex.interpolation, tex.extension = image, "Linear", "EXTEND"
        return tex.outputs["Color"]
    return plane_blend(tmp_path, f"ramp_{colorspace.replace(' ', '_')}", (64, 4), ramp)


@pytest.mark.parametrize("colorspace", ["sRGB", "Non-Color"])
def test_an_8_bit_image_blends_its_texels_as_cycles_does(ext, tmp_path, colorspace):
    from vpl_gi.vpl_addon.core.exr import read_passes
    blend = ramp_blend(tmp_path, colorspace)
    ours, cycles = tmp_path / "ours.exr", tmp_path / "cycles.exr"
    code, _, stderr = run_cli("render", blend, "-o", ours, "--samples", "16", "--method", "none")
    assert code == 0, stderr
    code, _, stderr = run_cli("reference", blend, "-o", cycles, "--samples", "16", "--cache-dir", tmp_path / "cache")
    assert code == 0, stderr
    row = [read_passes(str(path))[0]["Diffuse Color"][2, :, 0] for path in (ours, cycles)]
    middle = slice(16, 48)  # between the texel centres: the blend
    print(colorspace, np.round(row[0][middle][::4], 3), np.round(row[1][middle][::4], 3))
    assert np.abs(row[0][middle] - row[1][middle]).max() < 0.02
    # the blend at the middle: the sRGB curve's 0.21 (Cycles'), a straight line's 0.5 for data
    assert row[1][31:33].mean() == pytest.approx(0.21 if colorspace == "sRGB" else 0.5, abs=0.05)


def checker_blend(tmp_path, mapped):
    """The plane coloured by a Checker Texture of UV coordinates, straight (Scale 4) or through a Mapping node
    (moved, turned about z, scaled unevenly, and lifted in z by 0.4 so that the pattern's colours swap) with Scale
    3; 48 x 48 pixels."""
    def checker(bpy, nodes, links):
        node = nodes.new("ShaderNodeTexChecker")
        node.inputs["Color1"].default_value = (0.9, 0.5, 0.1, 1.0)
        node.inputs["Color2"].default_value = (0.05, 0.2, 0.6, 1.0)
        node.inputs["Scale"].default_value = 3.0 if mapped else 4.0
        vector = nodes.new("ShaderNodeTexCoord").outputs["UV"]
        if mapped:
            mapping = nodes.new("ShaderNodeMapping")
            mapping.inputs["Location"].default_value = (0.1, 0.2, 0.4)
            mapping.inputs["Rotation"].default_value = (0.0, 0.0, 0.5)
            mapping.inputs["Scale"].default_value = (1.5, 2.0, 1.0)
            links.new(vector, mapping.inputs["Vector"])
            vector = mapping.outputs["Vector"]
        links.new(vector, node.inputs["Vector"])
        return node.outputs["Color"]
    return plane_blend(tmp_path, f"checker_{mapped}", (48, 48), checker)


@pytest.mark.parametrize("mapped", [False, True])
def test_a_checker_texture_of_uvs_is_drawn_as_cycles_draws_it(ext, tmp_path, mapped):
    from vpl_gi.vpl_addon.core.exr import read_passes
    blend = checker_blend(tmp_path, mapped)
    ours, cycles = tmp_path / "ours.exr", tmp_path / "cycles.exr"
    code, _, stderr = run_cli("render", blend, "-o", ours, "--samples", "16", "--method", "none")
    assert code == 0, stderr
    assert "Checker" not in stderr  # read, not warned about
    code, _, stderr = run_cli("reference", blend, "-o", cycles, "--samples", "16", "--cache-dir", tmp_path / "cache")
    assert code == 0, stderr
    red = [read_passes(str(path))[0]["Diffuse Color"][..., 0] for path in (ours, cycles)]  # Color1 0.9, Color2 0.05
    gap = np.abs(red[0] - red[1])
    print(mapped, gap.max(), gap.mean())
    assert gap.max() < 0.85 / 2  # no cell of the other colour: at most a pixel an edge crosses, sampled otherwise
    assert gap.mean() < 0.03  # edges sampled 16 times differ by some 0.02; the mean colour everywhere is 0.4 off
