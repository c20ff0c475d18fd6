"""Extraction from real Blender scenes (the bpy module): geometry, materials, lights, world, camera."""
import math

import numpy as np
import pytest

from conftest import add_mesh

pytestmark = pytest.mark.blender


@pytest.fixture
def bpy(ext):
    import bpy
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(cam)
    scene.camera = cam
    scene.render.resolution_x = scene.render.resolution_y = 32
    return bpy


def extracted(bpy):
    from vpl_gi.operators.scene.extract import extract
    return extract(bpy.context.evaluated_depsgraph_get())


CUBE_V = [(x, y, z) for z in (-1, 1) for y in (-1, 1) for x in (-1, 1)]
CUBE_F = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]


def test_modifiers_are_evaluated_and_hidden_objects_skipped(bpy):
    cube = add_mesh(bpy, "Cube", CUBE_V, CUBE_F)
    cube.modifiers.new("sub", "SUBSURF").levels = 1
    hidden = add_mesh(bpy, "Hidden", CUBE_V, CUBE_F, location=(5, 0, 0))
    hidden.hide_render = True
    scene, _ = extracted(bpy)
    assert len(scene.triangles) == 6 * 4 * 2  # one subdivision level: each quad becomes four
    assert scene.object_names == ["Cube"]


def test_instances_curves_and_text_become_triangles(bpy):
    coll = bpy.data.collections.new("Src")
    src = bpy.data.objects.new("Quad", bpy.data.meshes.new("Quad"))
    src.data.from_pydata([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)], [], [(0, 1, 2, 3)])
    coll.objects.link(src)
    for i in range(3):
        empty = bpy.data.objects.new(f"Inst{i}", None)
        empty.instance_type = "COLLECTION"
        empty.instance_collection = coll
        empty.location = (3 * i, 0, 0)
        bpy.context.scene.collection.objects.link(empty)
    text = bpy.data.objects.new("Text", bpy.data.curves.new("Text", "FONT"))
    text.data.body = "Hi"
    bpy.context.scene.collection.objects.link(text)
    scene, _ = extracted(bpy)
    quads = scene.object_id == scene.object_names.index("Quad")
    assert quads.sum() == 6  # three instances of a two-triangle quad
    xs = np.sort(np.unique(np.round(scene.triangles[quads][..., 0].min(axis=1))))
    assert list(xs) == [0, 3, 6]
    assert (scene.object_id == scene.object_names.index("Text")).sum() > 10


def test_smooth_and_flat_normals(bpy):
    obj = add_mesh(bpy, "Cube", CUBE_V, CUBE_F)
    scene, _ = extracted(bpy)
    assert np.allclose(scene.normals, scene.geometric_normals[:, None, :], atol=1e-5)  # flat by default
    obj.data.shade_smooth()
    scene, _ = extracted(bpy)
    corners = np.abs(scene.normals).reshape(-1, 3)
    assert np.allclose(corners, 1 / math.sqrt(3), atol=1e-4)  # smooth cube: corner normals point diagonally


def test_world_transform_is_applied(bpy):
    obj = add_mesh(bpy, "Cube", CUBE_V, CUBE_F, location=(10, 0, 0))
    obj.scale = (2, 1, 1)
    scene, _ = extracted(bpy)
    assert scene.triangles[..., 0].min() == pytest.approx(8) and scene.triangles[..., 0].max() == pytest.approx(12)


def test_principled_textured_emissive_and_unsupported_materials(bpy):
    plain = bpy.data.materials.new("Plain")
    bsdf = plain.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (0.2, 0.4, 0.6, 1)
    bsdf.inputs["Roughness"].default_value = 0.3
    bsdf.inputs["Metallic"].default_value = 0.25
    glow = bpy.data.materials.new("Glow")
    g = glow.node_tree.nodes["Principled BSDF"]
    g.inputs["Emission Color"].default_value = (1, 0.5, 0, 1)
    g.inputs["Emission Strength"].default_value = 4
    tex = bpy.data.materials.new("Tex")
    image = bpy.data.images.new("img", 2, 2)
    image.pixels.foreach_set(np.tile([0.5, 0.5, 0.5, 1.0], 4).astype(np.float32))
    node = tex.node_tree.nodes.new("ShaderNodeTexImage")
    node.image = image
    tex.node_tree.links.new(node.outputs["Color"], tex.node_tree.nodes["Principled BSDF"].inputs["Base Color"])
    glass = bpy.data.materials.new("Glassy")
    out = glass.node_tree.nodes["Material Output"]
    glass.node_tree.links.new(glass.node_tree.nodes.new("ShaderNodeBsdfGlass").outputs[0], out.inputs["Surface"])
    toon = bpy.data.materials.new("Toony")
    out = toon.node_tree.nodes["Material Output"]
    toon.node_tree.links.new(toon.node_tree.nodes.new("ShaderNodeBsdfToon").outputs[0], out.inputs["Surface"])
    for i, mat in enumerate((plain, glow, tex, glass, toon)):
        add_mesh(bpy, f"M{i}", [(0, 0, i), (1, 0, i), (0, 1, i)], [(0, 1, 2)], material=mat)
    scene, warnings = extracted(bpy)
    m = scene.materials
    ids = {name: m.names.index(name) for name in ("Plain", "Glow", "Tex", "Glassy", "Toony")}
    assert np.allclose(m.base_color[ids["Plain"]], [0.2, 0.4, 0.6]) and m.roughness[ids["Plain"]] == pytest.approx(0.3)
    assert np.allclose(m.diffuse_albedo[ids["Plain"]], np.array([0.2, 0.4, 0.6]) * 0.75)
    assert np.allclose(m.emission[ids["Glow"]], [4, 2, 0])
    tex_id = m.mapped("base_color")[ids["Tex"]]
    from vpl_gi.vpl_addon.materials.textures import lookup
    # an 8-bit sRGB image keeps its encoded values, which the map makes linear after its lookup (as Cycles does)
    tmap = m.maps[tex_id] if tex_id >= 0 else None
    assert tmap is not None and tmap.srgb and np.allclose(scene.textures[tmap.image], 0.5, atol=0.01)
    assert np.allclose(lookup(tmap, scene.textures, np.array([[0.5, 0.5]]), scalar=False),
                       ((0.5 + 0.055) / 1.055) ** 2.4, atol=0.01)
    assert m.glass[ids["Glassy"]] and m.ior[ids["Glassy"]] == pytest.approx(1.5)  # the Glass BSDF: thin glass
    assert np.allclose(m.base_color[ids["Toony"]], 0.8)  # an unsupported shader: grey diffuse, one warning
    assert [w for w in warnings if "'Toony'" in w and "Toon" in w] and not [w for w in warnings if "Glassy" in w]


def test_lights_in_blender_units(bpy):
    specs = [("POINT", {"energy": 100, "shadow_soft_size": 0.1}), ("SPOT", {"energy": 50, "spot_size": 1.0,
                                                                             "spot_blend": 0.2}),
             ("SUN", {"energy": 3, "angle": 0.1}), ("AREA", {"energy": 40, "shape": "RECTANGLE", "size": 2,
                                                            "size_y": 0.5})]
    for kind, props in specs:
        data = bpy.data.lights.new(kind, kind)
        data.color = (1, 0.5, 0.25)
        for k, v in props.items():
            setattr(data, k, v)
        obj = bpy.data.objects.new(kind, data)
        obj.location = (1, 2, 3)
        obj.rotation_euler = (math.pi, 0, 0)  # pointing up (+Z) instead of down
        bpy.context.scene.collection.objects.link(obj)
    scene, _ = extracted(bpy)
    lights = {l.name: l for l in scene.lights}
    assert np.allclose(lights["POINT"].power, [100, 50, 25]) and lights["POINT"].radius == pytest.approx(0.1)
    assert np.allclose(lights["SPOT"].direction, [0, 0, 1], atol=1e-6)
    assert lights["SPOT"].spot_size == pytest.approx(1.0) and lights["SPOT"].spot_blend == pytest.approx(0.2)
    assert np.allclose(lights["SUN"].strength, [3, 1.5, 0.75])
    assert np.allclose(lights["SUN"].direction, [0, 0, 1], atol=1e-6)
    area = lights["AREA"]
    assert area.area == pytest.approx(1.0) and np.allclose(area.normal, [0, 0, 1], atol=1e-6)
    assert np.allclose(area.center, [1, 2, 3])


def test_light_exposure_and_unnormalized_power(bpy):
    for name, normalize in (("Normal", True), ("Raw", False)):
        data = bpy.data.lights.new(name, "AREA")
        data.energy, data.size, data.exposure, data.normalize = 10, 2, 1.0, normalize
        bpy.context.scene.collection.objects.link(bpy.data.objects.new(name, data))
    scene, _ = extracted(bpy)
    lights = {l.name: l for l in scene.lights}
    assert np.allclose(lights["Normal"].power, 20)  # exposure 1 doubles
    assert np.allclose(lights["Raw"].radiance, 20 / np.pi)  # not divided by the 4 m^2 area


def test_camera_and_world(bpy):
    scene_bpy = bpy.context.scene
    cam = scene_bpy.camera.data
    cam.lens, cam.sensor_fit, cam.shift_x = 35, "VERTICAL", 0.1
    scene_bpy.render.resolution_x, scene_bpy.render.resolution_y = 400, 200
    scene_bpy.render.resolution_percentage = 50
    world = bpy.data.worlds.new("W")
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.5, 0.25, 1, 1)
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 2
    scene_bpy.world = world
    scene, _ = extracted(bpy)
    from vpl_gi.vpl_addon.core.camera import view_window
    assert (scene.camera.width, scene.camera.height) == (200, 100)
    assert np.allclose(scene.camera.window, view_window(200, 100, orthographic=False, lens=35, sensor_width=36,
                                                        sensor_height=cam.sensor_height, sensor_fit="VERTICAL",
                                                        shift_x=0.1))
    assert np.allclose(scene.world, [1, 0.5, 2])


def test_bounce_limit_follows_cycles_diffuse_and_total_limits(bpy):
    cycles = bpy.context.scene.cycles
    cycles.max_bounces, cycles.diffuse_bounces = 6, 3
    assert extracted(bpy)[0].max_bounces == 3
    cycles.max_bounces = 2
    assert extracted(bpy)[0].max_bounces == 2


def test_no_camera_is_a_clear_error(bpy):
    from vpl_gi.operators.scene.extract import ExtractionError
    bpy.context.scene.camera = None
    with pytest.raises(ExtractionError, match="no active camera"):
        extracted(bpy)
