"""Textured materials read from real Blender scenes (the bpy module): the glTF importer's metallic-roughness
pattern with a normal map (``example_blends/cornell_pbr.blend``, made through Blender's own glTF importer), the
node chains users build (factors, Mapping, named UV maps), and broken textures that render with one warning."""
import math

import numpy as np
import pytest

from conftest import EXAMPLES, add_mesh, surface_material
from test_extract import bpy, extracted  # noqa: F401 (bpy: the fixture)

pytestmark = pytest.mark.blender


def test_the_gltf_importers_material_extracts_without_a_warning(ext):
    import bpy
    bpy.ops.wm.open_mainfile(filepath=str(EXAMPLES / "cornell_pbr.blend"))
    scene, warnings = extracted(bpy)
    assert warnings == []
    m = scene.materials
    pbr = next(i for i, name in enumerate(m.names) if name.startswith("PBR"))
    maps = {name: m.maps[m.mapped(name)[pbr]] for name in ("base_color", "roughness", "metallic", "normal")}
    assert all(m.mapped(name)[pbr] >= 0 for name in maps)
    assert (maps["roughness"].channel, maps["metallic"].channel, maps["base_color"].channel) == (1, 2, -1)
    assert maps["roughness"].image == maps["metallic"].image != maps["base_color"].image
    assert m.specular[pbr] == pytest.approx(0.5) and m.ior[pbr] == pytest.approx(1.5)
    rough = scene.textures[maps["roughness"].image][..., 1]
    assert rough.min() == pytest.approx(0.25, abs=0.02) and rough.max() == pytest.approx(0.85, abs=0.02)  # Non-Color
    assert scene.tangents is not None and np.isfinite(scene.tangents).all()
    textured = scene.material == pbr
    t = scene.tangents[textured][..., :3].reshape(-1, 3)
    n = scene.normals[textured].reshape(-1, 3)
    assert np.abs((t * n).sum(axis=1)).max() < 1e-3 and np.allclose(np.linalg.norm(t, axis=1), 1, atol=1e-3)


def _image(bpy, name, rgba):
    image = bpy.data.images.new(name, 2, 1, float_buffer=True)
    image.pixels.foreach_set(np.array(rgba, np.float32).ravel())
    return image


def test_factors_mapping_and_a_named_uv_map_are_followed(bpy):
    mat = bpy.data.materials.new("Chain")
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    bsdf = nodes["Principled BSDF"]
    tex = nodes.new("ShaderNodeTexImage")
    tex.image = _image(bpy, "colours", [[0.2, 0.4, 0.6, 1], [1, 1, 1, 1]])
    tex.extension = "EXTEND"
    mix = nodes.new("ShaderNodeMix")
    mix.data_type, mix.blend_type = "RGBA", "MULTIPLY"
    mix.inputs[0].default_value = 1.0
    mix.inputs[7].default_value = (0.5, 1.0, 2.0, 1.0)
    reroute = nodes.new("NodeReroute")
    links.new(tex.outputs["Color"], mix.inputs[6])
    links.new(mix.outputs[2], reroute.inputs[0])
    links.new(reroute.outputs[0], bsdf.inputs["Base Color"])
    math_node = nodes.new("ShaderNodeMath")
    math_node.operation = "MULTIPLY"
    math_node.inputs[1].default_value = 0.5
    links.new(tex.outputs["Alpha"], math_node.inputs[0])
    links.new(math_node.outputs[0], bsdf.inputs["Roughness"])
    mapping = nodes.new("ShaderNodeMapping")
    mapping.inputs["Location"].default_value = (0.25, 0.0, 0.0)
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, math.pi / 2)
    mapping.inputs["Scale"].default_value = (2.0, 3.0, 1.0)
    uv = nodes.new("ShaderNodeUVMap")
    uv.uv_map = "second"
    links.new(uv.outputs["UV"], mapping.inputs["Vector"])
    links.new(mapping.outputs["Vector"], tex.inputs["Vector"])
    obj = add_mesh(bpy, "Tri", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [(0, 1, 2)], material=mat)
    obj.data.uv_layers.new(name="first")
    second = obj.data.uv_layers.new(name="second")
    for loop, value in zip(second.data, [(0.1, 0.2), (0.3, 0.4), (0.5, 0.6)]):
        loop.uv = value
    scene, warnings = extracted(bpy)
    assert warnings == []
    m = scene.materials
    i = m.names.index("Chain")
    base, rough = m.maps[m.mapped("base_color")[i]], m.maps[m.mapped("roughness")[i]]
    assert np.allclose(base.factor, (0.5, 1.0, 2.0)) and base.channel == -1 and base.extension == "EXTEND"
    assert rough.channel == 3 and rough.factor[0] == pytest.approx(0.5)
    assert np.allclose(base.uv, (0.0, -3.0, 0.25, 2.0, 0.0, 0.0), atol=1e-6)  # R(90) S(2, 3) uv + (0.25, 0)
    assert np.allclose(scene.uvs[0], [(0.1, 0.2), (0.3, 0.4), (0.5, 0.6)], atol=1e-6)  # the named map
    assert scene.textures[rough.image].shape == (1, 2, 4)


def test_broken_textures_render_with_one_warning_each(bpy, tmp_path):
    from vpl_gi.vpl_addon.core import passes as P
    from vpl_gi.vpl_addon.render import RenderSettings, render

    def textured(name, image, obj_name, z, uv=True):
        mat = bpy.data.materials.new(name)
        tex = mat.node_tree.nodes.new("ShaderNodeTexImage")
        tex.image = image
        mat.node_tree.links.new(tex.outputs["Color"], mat.node_tree.nodes["Principled BSDF"].inputs["Base Color"])
        obj = add_mesh(bpy, obj_name, [(-1, -1, z), (1, -1, z), (1, 1, z), (-1, 1, z)], [(0, 1, 2, 3)], material=mat)
        if uv:
            obj.data.uv_layers.new(name="UVMap")

    missing = bpy.data.images.new("wood.png", 4, 4)
    missing.source, missing.filepath = "FILE", "/nonexistent/wood.png"  # as a .blend whose texture moved away
    textured("Missing", missing, "A", 0.0)
    (tmp_path / "broken.png").write_bytes(b"not a png")  # a file that loads as an image of no pixels
    broken = bpy.data.images.new("broken.png", 4, 4)
    broken.source, broken.filepath = "FILE", str(tmp_path / "broken.png")
    textured("Empty", broken, "B", -1.0)
    textured("NaN", _image(bpy, "nan", [[np.nan, np.inf, -1, 1], [0.5, 0.5, 0.5, 1]]), "C", -2.0)
    textured("NoUV", _image(bpy, "fine", [[0.5, 0.5, 0.5, 1]] * 2), "D", -3.0, uv=False)
    lamp = bpy.data.objects.new("Lamp", bpy.data.lights.new("Lamp", "SUN"))
    bpy.context.scene.collection.objects.link(lamp)
    bpy.context.scene.camera.location = (0, 0, 5)
    scene, warnings = extracted(bpy)
    for words in (("'Missing'", "'wood.png'"), ("'Empty'", "'broken.png'"), ("'D'", "'NoUV'", "'fine'")):
        assert len([w for w in warnings if all(word in w for word in words)]) == 1, (words, warnings)
    assert len(warnings) == 3  # the NaN texels are made 0 quietly, as Cycles renders them black
    out = render(scene, RenderSettings(samples=2, light_samples=1, method="none", passes=P.ALL)).passes
    assert all(np.isfinite(v).all() and (v >= 0).all() for v in out.values())


@pytest.mark.parametrize("pattern", ["gltf mask", "greater than", "blend", "power"])
def test_alpha_clip_and_blend_are_read_and_other_alpha_chains_warn(bpy, pattern):
    mat = bpy.data.materials.new("Leaf")
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    alpha = nodes["Principled BSDF"].inputs["Alpha"]
    tex = nodes.new("ShaderNodeTexImage")
    tex.image = _image(bpy, "leaf", [[0.2, 0.4, 0.6, 0.0], [1, 1, 1, 1]])
    factor = nodes.new("ShaderNodeMath")  # the glTF importer's alpha factor, applied before the clip
    factor.operation = "MULTIPLY"
    factor.inputs[1].default_value = 0.8
    links.new(tex.outputs["Alpha"], factor.inputs[0])
    first = nodes.new("ShaderNodeMath")
    if pattern == "gltf mask":  # 1 - (a < 0.4)
        less, first.operation = nodes.new("ShaderNodeMath"), "SUBTRACT"
        less.operation = "LESS_THAN"
        less.inputs[1].default_value = 0.4
        first.inputs[0].default_value = 1.0
        links.new(factor.outputs[0], less.inputs[0])
        links.new(less.outputs[0], first.inputs[1])
    elif pattern in ("greater than", "power"):
        first.operation = "GREATER_THAN" if pattern == "greater than" else "POWER"
        first.inputs[1].default_value = 0.4
        links.new(factor.outputs[0], first.inputs[0])
    else:
        first = factor
    links.new(first.outputs[0], alpha)
    obj = add_mesh(bpy, "Leaf", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [(0, 1, 2)], material=mat)
    obj.data.uv_layers.new(name="UVMap")
    scene, warnings = extracted(bpy)
    m = scene.materials
    i = m.names.index("Leaf")
    if pattern == "power":
        assert m.mapped("alpha")[i] < 0 and len(warnings) == 1
        assert all(word in warnings[0] for word in ("'Leaf'", "Alpha", "Math"))
        return
    assert warnings == []
    tmap = m.maps[m.mapped("alpha")[i]]
    assert tmap.channel == 3 and tmap.factor[0] == pytest.approx(0.8)
    assert tmap.cutoff == (-1.0 if pattern == "blend" else pytest.approx(0.4))


def test_node_groups_are_followed_in_and_out(bpy):
    """An asset-library pattern: the Principled BSDF inside a group, its Base Color from an image outside wired to
    a group input, its Roughness from an image's green channel inside, its Metallic the group node's unlinked input
    value; the group reached through a reroute."""
    group = bpy.data.node_groups.new("Surface", "ShaderNodeTree")
    group.interface.new_socket("Colour", in_out="INPUT", socket_type="NodeSocketColor")
    group.interface.new_socket("Metal", in_out="INPUT", socket_type="NodeSocketFloat")
    group.interface.new_socket("Shader", in_out="OUTPUT", socket_type="NodeSocketShader")
    inside, outside = group.nodes.new("NodeGroupInput"), group.nodes.new("NodeGroupOutput")
    bsdf = group.nodes.new("ShaderNodeBsdfPrincipled")
    rough = group.nodes.new("ShaderNodeTexImage")
    rough.image = _image(bpy, "rough", [[0.1, 0.3, 0.9, 1], [0.1, 0.7, 0.9, 1]])
    split = group.nodes.new("ShaderNodeSeparateColor")
    group.links.new(rough.outputs["Color"], split.inputs[0])
    group.links.new(split.outputs["Green"], bsdf.inputs["Roughness"])
    group.links.new(inside.outputs["Colour"], bsdf.inputs["Base Color"])
    group.links.new(inside.outputs["Metal"], bsdf.inputs["Metallic"])
    group.links.new(bsdf.outputs["BSDF"], outside.inputs["Shader"])

    def grouped(nodes, links):
        node = nodes.new("ShaderNodeGroup")
        node.node_tree = group
        node.inputs["Metal"].default_value = 0.7
        tex = nodes.new("ShaderNodeTexImage")
        tex.image = _image(bpy, "colours", [[0.2, 0.4, 0.6, 1], [1, 1, 1, 1]])
        links.new(tex.outputs["Color"], node.inputs["Colour"])
        reroute = nodes.new("NodeReroute")
        links.new(node.outputs["Shader"], reroute.inputs[0])
        return reroute.outputs[0]

    mat = surface_material(bpy, "Grouped", grouped)
    obj = add_mesh(bpy, "Tri", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [(0, 1, 2)], material=mat)
    obj.data.uv_layers.new(name="UVMap")
    scene, warnings = extracted(bpy)
    assert warnings == []
    m = scene.materials
    i = m.names.index("Grouped")
    assert m.metallic[i] == pytest.approx(0.7)
    base, roughness = m.maps[m.mapped("base_color")[i]], m.maps[m.mapped("roughness")[i]]
    assert scene.textures[base.image][0, 0, :3] == pytest.approx((0.2, 0.4, 0.6))
    assert roughness.channel == 1 and scene.textures[roughness.image][0, 1, 1] == pytest.approx(0.7)


def test_glossy_mix_and_add_shaders(bpy):
    def glossy(nodes, links):
        node = nodes.new("ShaderNodeBsdfGlossy")
        node.inputs["Color"].default_value = (0.9, 0.5, 0.1, 1)
        node.inputs["Roughness"].default_value = 0.3
        return node.outputs[0]

    def leaf(nodes, links):  # the older glTF importer's and many leaf assets' cut-out: Transparent first
        mix = nodes.new("ShaderNodeMixShader")
        tex = nodes.new("ShaderNodeTexImage")
        tex.image = _image(bpy, "leafalpha", [[1, 1, 1, 0], [1, 1, 1, 1]])
        links.new(tex.outputs["Alpha"], mix.inputs[0])
        links.new(nodes.new("ShaderNodeBsdfTransparent").outputs[0], mix.inputs[1])
        links.new(nodes.new("ShaderNodeBsdfDiffuse").outputs[0], mix.inputs[2])
        return mix.outputs[0]

    def veil(nodes, links):  # a constant 30 % opacity the other way round
        mix = nodes.new("ShaderNodeMixShader")
        mix.inputs[0].default_value = 0.7
        links.new(nodes.new("ShaderNodeBsdfPrincipled").outputs[0], mix.inputs[1])
        links.new(nodes.new("ShaderNodeBsdfTransparent").outputs[0], mix.inputs[2])
        return mix.outputs[0]

    def glow(nodes, links):
        add = nodes.new("ShaderNodeAddShader")
        emission = nodes.new("ShaderNodeEmission")
        emission.inputs["Color"].default_value = (1, 0.5, 0.25, 1)
        emission.inputs["Strength"].default_value = 4.0
        diffuse = nodes.new("ShaderNodeBsdfDiffuse")
        diffuse.inputs["Color"].default_value = (0.3, 0.3, 0.3, 1)
        links.new(diffuse.outputs[0], add.inputs[0])
        links.new(emission.outputs[0], add.inputs[1])
        return add.outputs[0]

    def mixed(first, factor=0.8, second=None):
        """A Mix Shader of ``first`` (a node type) and ``second`` (the Glossy BSDF above when None) by ``factor``:
        a number, or a factor node type whose first output feeds it (a Fresnel of IOR 1.6, a Layer Weight's Fresnel
        of Blend 0.3, an image)."""
        def build(nodes, links):
            mix = nodes.new("ShaderNodeMixShader")
            if isinstance(factor, str):
                curve = nodes.new(factor)
                if factor == "ShaderNodeTexImage":
                    curve.image = _image(bpy, "mask", [[0, 0, 0, 1], [1, 1, 1, 1]])
                else:
                    curve.inputs[0].default_value = 1.6 if factor == "ShaderNodeFresnel" else 0.3
                links.new(curve.outputs[0], mix.inputs[0])
            else:
                mix.inputs[0].default_value = factor
            under = nodes.new(first)
            under.inputs[0].default_value = (0.2, 0.4, 0.6, 1)
            links.new(under.outputs[0], mix.inputs[1])
            links.new((glossy(nodes, links).node if second is None else nodes.new(second)).outputs[0], mix.inputs[2])
            return mix.outputs[0]
        return build

    def nested(nodes, links):
        outer, inner = nodes.new("ShaderNodeMixShader"), nodes.new("ShaderNodeMixShader")
        outer.inputs[0].default_value = 0.3
        links.new(nodes.new("ShaderNodeBsdfPrincipled").outputs[0], inner.inputs[1])
        links.new(nodes.new("ShaderNodeBsdfPrincipled").outputs[0], inner.inputs[2])
        links.new(nodes.new("ShaderNodeBsdfDiffuse").outputs[0], outer.inputs[1])
        links.new(inner.outputs[0], outer.inputs[2])
        return outer.outputs[0]

    cases = {"Glossy": glossy, "Leaf": leaf, "Veil": veil, "Glow": glow,
             "Blend": mixed("ShaderNodeBsdfDiffuse"),  # Diffuse and Glossy: a metallic lobe of the mix's weight
             "Sheen": mixed("ShaderNodeBsdfDiffuse", "ShaderNodeFresnel"),  # by Fresnel: a dielectric layer
             "Layered": mixed("ShaderNodeBsdfDiffuse", "ShaderNodeLayerWeight"),
             "Other": mixed("ShaderNodeBsdfPrincipled"),  # two other BSDFs: blended by the factor
             "Masked": mixed("ShaderNodeBsdfPrincipled", "ShaderNodeTexImage"),  # ... or by an image
             "Lit": mixed("ShaderNodeBsdfPrincipled", 0.8, "ShaderNodeEmission"),  # a glow: the heavier stands
             "Nested": nested}  # a mix of a mix: the heavier stands, and the inner mix leaves no row behind
    for k, (name, build) in enumerate(cases.items()):
        obj = add_mesh(bpy, name, [(0, 0, k), (1, 0, k), (0, 1, k)], [(0, 1, 2)],
                       material=surface_material(bpy, name, build))
        obj.data.uv_layers.new(name="UVMap")
    scene, warnings = extracted(bpy)
    m = scene.materials
    ids = {name: m.names.index(name) for name in cases}
    second = {name: m.mix_other[ids[name]] for name in ("Other", "Masked")}
    assert m.names[second["Other"]] == "Other (Mix Shader: second shader)"
    assert set(m.names) - set(m.listed_names) == {m.names[i] for i in second.values()}  # not in Cryptomatte's list
    assert m.mix_factor[ids["Other"]] == pytest.approx(0.8)
    assert m.mix_factor[ids["Masked"]] == 1.0 and m.mapped("mix")[ids["Masked"]] >= 0
    assert (m.mix_other[[i for i in range(len(m.names)) if i not in (ids["Other"], ids["Masked"])]] < 0).all()
    for name in ("Other", "Masked"):  # the first row the Principled BSDF's, the second the Glossy's
        assert m.base_color[ids[name]] == pytest.approx((0.2, 0.4, 0.6)) and m.metallic[ids[name]] == 0.0
    for i in (ids["Glossy"], *second.values()):
        assert m.metallic[i] == 1.0 and m.roughness[i] == pytest.approx(0.3)
        assert m.base_color[i] == pytest.approx((0.9, 0.5, 0.1))
        assert (m.specular_tint[i] < 1).all() and m.specular_tint[i][0] > m.specular_tint[i][2]
    for name in ("Blend", "Sheen", "Layered"):  # the Diffuse's colour, the Glossy's roughness
        i = ids[name]
        assert m.base_color[i] == pytest.approx((0.2, 0.4, 0.6)) and m.roughness[i] == pytest.approx(0.3)
    blend, glossy_row = ids["Blend"], ids["Glossy"]
    assert m.metallic[blend] == pytest.approx(0.8) and m.metal_color[blend] == pytest.approx((0.9, 0.5, 0.1))
    assert m.specular_tint[blend] == pytest.approx(m.specular_tint[glossy_row]) and m.specular[blend] == 0.0
    assert (m.metal_color[[i for i, name in enumerate(m.names) if name not in ("Blend", "Sheen", "Layered")]] < 0).all()
    assert m.emission[ids["Lit"]].max() > 0.0 and m.mix_other[ids["Lit"]] < 0
    for name, ior in (("Sheen", 1.6), ("Layered", 1.0 / 0.7)):  # weighted by F(N . I) of that IOR
        i = ids[name]
        assert m.fresnel_mix[i] == pytest.approx(ior) and m.metal_color[i] == pytest.approx((0.9, 0.5, 0.1))
        assert m.specular[i] == 0.0
    assert m.fresnel_mix[blend] == 0.0
    alpha = m.maps[m.mapped("alpha")[ids["Leaf"]]]
    assert alpha.channel == 3 and m.metallic[ids["Leaf"]] == 0.0
    assert m.alpha[ids["Veil"]] == pytest.approx(0.3) and m.mapped("alpha")[ids["Veil"]] < 0
    assert m.emission[ids["Glow"]] == pytest.approx((4.0, 2.0, 1.0)) and m.base_color[ids["Glow"]] == pytest.approx(0.3)
    assert sum(name.endswith("second shader)") for name in m.names) == 2  # Other's and Masked's alone
    assert len(warnings) == 2 and all(word in warnings[0] for word in ("'Lit'", "Mix Shader", "Emission"))
    assert all(word in warnings[1] for word in ("'Nested'", "Mix Shader", "Diffuse"))


def test_bump_nodes_and_unrendered_layers(bpy):
    def bumped(nodes, links):  # image -> Bump (inverted) -> Normal, over a Normal Map
        bsdf, bump = nodes.new("ShaderNodeBsdfPrincipled"), nodes.new("ShaderNodeBump")
        height, normals, nmap = nodes.new("ShaderNodeTexImage"), nodes.new("ShaderNodeTexImage"), nodes.new(
            "ShaderNodeNormalMap")
        height.image, normals.image = _image(bpy, "height", [[0, 0, 0, 1], [1, 1, 1, 1]]), _image(
            bpy, "normals", [[0.5, 0.5, 1, 1], [0.5, 0.5, 1, 1]])
        bump.inputs["Distance"].default_value, bump.inputs["Strength"].default_value = 0.2, 0.7
        bump.invert = True
        links.new(height.outputs["Color"], bump.inputs["Height"])
        links.new(normals.outputs["Color"], nmap.inputs["Color"])
        links.new(nmap.outputs["Normal"], bump.inputs["Normal"])
        links.new(bump.outputs["Normal"], bsdf.inputs["Normal"])
        return bsdf.outputs[0]

    def linked_strength(nodes, links):  # a Bump whose Strength comes from a node: one warning, no bump
        bsdf, bump, value = nodes.new("ShaderNodeBsdfDiffuse"), nodes.new("ShaderNodeBump"), nodes.new(
            "ShaderNodeValue")
        links.new(value.outputs[0], bump.inputs["Strength"])
        links.new(nodes.new("ShaderNodeTexImage").outputs["Color"], bump.inputs["Height"])
        links.new(bump.outputs["Normal"], bsdf.inputs["Normal"])
        return bsdf.outputs[0]

    def coated(nodes, links):
        bsdf = nodes.new("ShaderNodeBsdfPrincipled")
        bsdf.inputs["Coat Weight"].default_value = 0.5
        links.new(nodes.new("ShaderNodeValue").outputs[0], bsdf.inputs["Sheen Weight"])
        return bsdf.outputs[0]

    for k, (name, build) in enumerate((("Bumped", bumped), ("Linked", linked_strength), ("Coated", coated))):
        obj = add_mesh(bpy, name, [(0, 0, k), (1, 0, k), (0, 1, k)], [(0, 1, 2)],
                       material=surface_material(bpy, name, build))
        obj.data.uv_layers.new(name="UVMap")
    scene, warnings = extracted(bpy)
    m = scene.materials
    i = m.names.index("Bumped")
    bump = m.maps[m.mapped("bump")[i]]
    assert bump.factor == pytest.approx((-0.2,) * 3) and bump.strength == pytest.approx(0.7)
    assert m.mapped("normal")[i] >= 0 and m.mapped("bump")[m.names.index("Linked")] < 0
    assert warnings == [
        "material 'Linked': Bump 'Bump' with a linked Strength or Distance is not supported; no bump",
        "material 'Coated': 'Principled BSDF' Coat Weight 0.5: not rendered (that layer is not supported yet)",
        "material 'Coated': 'Principled BSDF' Sheen Weight is linked: not rendered (that layer is not supported yet)"]


def test_checker_textures_of_uvs_are_read_and_others_warn(bpy):
    """A Checker Texture of UV coordinates becomes a 2x2 texture read closest (its Fac one of 1s and 0s); one at its
    default Generated coordinates, with a linked colour, or turned out of the UV plane (its z would vary) warns
    once, naming its material and node, and leaves the Base Color its value."""
    def checker(name, z, vector=None, rotation=None, linked=False, output="Color", into="Base Color"):
        mat = bpy.data.materials.new(name)
        nodes, links = mat.node_tree.nodes, mat.node_tree.links
        node = nodes.new("ShaderNodeTexChecker")
        node.name = f"{name} checker"
        if vector == "UV":
            uv = nodes.new("ShaderNodeTexCoord").outputs["UV"]
            if rotation is not None:
                mapping = nodes.new("ShaderNodeMapping")
                mapping.inputs["Rotation"].default_value = rotation
                links.new(uv, mapping.inputs["Vector"])
                uv = mapping.outputs["Vector"]
            links.new(uv, node.inputs["Vector"])
        if linked:
            links.new(nodes.new("ShaderNodeTexNoise").outputs["Color"], node.inputs["Color1"])
        links.new(node.outputs[output], nodes["Principled BSDF"].inputs[into])
        obj = add_mesh(bpy, name, [(-1, -1, z), (1, -1, z), (1, 1, z), (-1, 1, z)], [(0, 1, 2, 3)], material=mat)
        obj.data.uv_layers.new(name="UVMap")

    checker("Read", 0.0, "UV", rotation=(0.0, 0.0, 0.3))
    checker("Rough", 1.0, "UV", output="Fac", into="Roughness")  # Fac: 1 where Color1 would be, 0 elsewhere
    checker("Generated", -1.0)
    checker("Linked", -2.0, "UV", linked=True)
    checker("Tilted", -3.0, "UV", rotation=(0.4, 0.0, 0.0))
    lamp = bpy.data.objects.new("Lamp", bpy.data.lights.new("Lamp", "SUN"))
    bpy.context.scene.collection.objects.link(lamp)
    scene, warnings = extracted(bpy)
    for name in ("Generated", "Linked", "Tilted"):
        assert len([w for w in warnings if f"'{name}'" in w and f"{name} checker" in w]) == 1, (name, warnings)
    assert len(warnings) == 3, warnings
    m = scene.materials
    tmap = m.maps[m.map_of["base_color"][m.names.index("Read")]]
    assert tmap.closest and scene.textures[tmap.image].shape == (2, 2, 3)
    assert all(m.map_of["base_color"][i] < 0 for i, row in enumerate(m.names) if row != "Read")
    rough = m.maps[m.map_of["roughness"][m.names.index("Rough")]]
    assert sorted(np.unique(scene.textures[rough.image])) == [0.0, 1.0]
