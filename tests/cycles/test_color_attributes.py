"""Colour attributes (vertex colours) read as Cycles reads them: the Color Attribute node alone or multiplied with
an image (the glTF importer's COLOR_0 pattern), per corner or per point, byte or float, named or the default, and a
missing one black with one warning. Judged on the Diffuse Color pass against Cycles' (both noise-free but for
anti-aliasing)."""
import numpy as np
import pytest

from conftest import add_mesh, add_sun, camera_and_black_world, pass_errors, run_cli, surface_material
from test_extract import bpy, extracted  # noqa: F401 (bpy: the fixture)

pytestmark = pytest.mark.blender

# a 2 x 2 grid of quads: corner colours differ per face, so a per-corner attribute is not a per-point one
GRID = [(x, y, 0.0) for y in (-1.0, 0.0, 1.0) for x in (-1.0, 0.0, 1.0)]
QUADS = [(0, 1, 4, 3), (1, 2, 5, 4), (3, 4, 7, 6), (4, 5, 8, 7)]


def _colour_attributes(mesh):
    """A byte per-corner attribute 'Paint' (render default) and a float per-point one 'Heat'."""
    rng = np.random.default_rng(3)
    paint = mesh.color_attributes.new("Paint", "BYTE_COLOR", "CORNER")
    paint.data.foreach_set("color", np.c_[rng.random((len(mesh.loops), 3)), np.ones(len(mesh.loops))].ravel())
    heat = mesh.color_attributes.new("Heat", "FLOAT_COLOR", "POINT")
    heat.data.foreach_set("color", np.c_[rng.random((len(mesh.vertices), 3)) * 0.8,
                                         np.ones(len(mesh.vertices))].ravel())
    mesh.color_attributes.render_color_index = mesh.color_attributes.find("Paint")


def _materials(bpy):
    image = bpy.data.images.new("stripes", 4, 1, float_buffer=True)
    image.pixels.foreach_set(np.array([[1, 1, 1, 1], [0.5, 0.8, 0.2, 1], [1, 1, 1, 1], [0.3, 0.3, 0.9, 1]],
                                      np.float32).ravel())
    image.pack()

    def gltf(nodes, links):  # Principled Base Color = image x Color Attribute (default), as glTF imports COLOR_0
        bsdf = nodes.new("ShaderNodeBsdfPrincipled")
        tex, colour, mix = nodes.new("ShaderNodeTexImage"), nodes.new("ShaderNodeVertexColor"), nodes.new(
            "ShaderNodeMix")
        tex.image, tex.interpolation = image, "Closest"
        mix.data_type, mix.blend_type = "RGBA", "MULTIPLY"
        mix.inputs[0].default_value = 1.0
        links.new(tex.outputs["Color"], mix.inputs[6])
        links.new(colour.outputs["Color"], mix.inputs[7])
        links.new(mix.outputs[2], bsdf.inputs["Base Color"])
        return bsdf.outputs[0]

    def heat(nodes, links):  # a Diffuse BSDF coloured by a named per-point attribute through an Attribute node
        bsdf, attribute = nodes.new("ShaderNodeBsdfDiffuse"), nodes.new("ShaderNodeAttribute")
        attribute.attribute_name = "Heat"
        links.new(attribute.outputs["Color"], bsdf.inputs["Color"])
        return bsdf.outputs[0]

    def missing(nodes, links):
        bsdf, colour = nodes.new("ShaderNodeBsdfDiffuse"), nodes.new("ShaderNodeVertexColor")
        colour.layer_name = "Missing"
        links.new(colour.outputs["Color"], bsdf.inputs["Color"])
        return bsdf.outputs[0]

    return [surface_material(bpy, name, build) for name, build in
            (("Painted", gltf), ("Heat", heat), ("Unpainted", missing))]


def _scene(bpy):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    for i, material in enumerate(_materials(bpy)):
        obj = add_mesh(bpy, material.name, GRID, QUADS, material, location=(2.2 * (i - 1), 0.0, 0.0))
        obj.data.uv_layers.new(name="UVMap")
        if material.name != "Unpainted":
            _colour_attributes(obj.data)
    camera_and_black_world(bpy, scene, (0.0, 0.0, 5.0))
    scene.camera.data.type, scene.camera.data.ortho_scale = "ORTHO", 6.6
    add_sun(bpy, scene, (0.0, 0.0, 0.0))
    scene.render.resolution_x, scene.render.resolution_y = 66, 22
    scene.view_layers[0].use_pass_diffuse_color = True
    return scene


def test_colour_attributes_are_extracted_per_corner_and_per_point(bpy):
    _scene(bpy)
    scene, warnings = extracted(bpy)
    assert warnings == ["object 'Unpainted': material 'Unpainted' reads colour attribute 'Missing', which the mesh "
                        "does not have (per point or corner); black, as in Cycles"]
    m = scene.materials
    painted, heat, unpainted = (m.names.index(name) for name in ("Painted", "Heat", "Unpainted"))
    base = m.maps[m.mapped("base_color")[painted]]
    assert base.vertex and base.image >= 0 and base.closest
    assert m.maps[m.mapped("base_color")[heat]].image == -1
    mesh = bpy.data.objects["Painted"].data
    loops = np.empty(len(mesh.loops) * 4, np.float32)
    mesh.color_attributes["Paint"].data.foreach_get("color", loops)
    corners = scene.colors[scene.material == painted].reshape(-1, 3)
    assert {tuple(np.round(c, 4)) for c in corners} == {tuple(np.round(c, 4)) for c in loops.reshape(-1, 4)[:, :3]}
    assert len({tuple(np.round(c, 4)) for c in scene.colors[scene.material == heat].reshape(-1, 3)}) == 9  # points
    assert (scene.colors[scene.material == unpainted] == 0.0).all()


def test_colour_attributes_match_cycles_diffuse_color(ext, bpy, tmp_path):
    _scene(bpy)
    blend = tmp_path / "colours.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    ours, cycles = tmp_path / "ours.exr", tmp_path / "cycles.exr"
    code, _, stderr = run_cli("render", blend, "-o", ours, "--samples", "16", "--method", "none")
    assert code == 0, stderr
    code, _, stderr = run_cli("reference", blend, "-o", cycles, "--samples", "16", "--cache-dir", tmp_path / "c")
    assert code == 0, stderr
    errors = pass_errors(ours, cycles, "Diffuse Color")
    print(f"Diffuse Color against Cycles: rMAE {errors['rmae']:.4f}, mean ratio {errors['mean_ratio']:.4f}")
    assert errors["mean_ratio"] == pytest.approx(1.0, abs=0.01)
    assert errors["rmae"] < 0.02
