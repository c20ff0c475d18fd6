"""What VPL GI does not render (issue 22): light portals, volumes, hair, point clouds, light linking, shadow catchers,
holdouts, motion blur and Cycles' ray visibility are left out or approximated with exactly one warning
that names the object, material or setting (``operators/scene/unsupported.py``); a portal gives no light and a fog box
hides nothing."""
import numpy as np
import pytest

from conftest import add_mesh, add_sun, camera_and_black_world, shader_material, surface_material
from test_extract import CUBE_F, CUBE_V, bpy, extracted  # noqa: F401 (bpy: the fixture)

pytestmark = pytest.mark.blender


def _link(bpy, obj):
    bpy.context.scene.collection.objects.link(obj)
    return obj


def _lamp(bpy, name, kind="AREA"):
    return _link(bpy, bpy.data.objects.new(name, bpy.data.lights.new(name, kind)))


def _cube(bpy, name, *materials, location=(0, 0, 0)):
    cube = add_mesh(bpy, name, CUBE_V, CUBE_F, location=location)
    for material in materials:
        cube.data.materials.append(material)
    return cube


def _volume_material(bpy, name, surface):
    """A material with a Principled Volume, and its Principled BSDF as the Surface when ``surface``."""
    material = bpy.data.materials.new(name)
    nodes, links = material.node_tree.nodes, material.node_tree.links
    links.new(nodes.new("ShaderNodeVolumePrincipled").outputs[0], nodes["Material Output"].inputs["Volume"])
    if not surface:
        nodes.remove(nodes["Principled BSDF"])
    return material


def _layer_collection(bpy, name):
    """The view layer's entry of a new collection holding a cube."""
    collection = bpy.data.collections.new(name)
    bpy.context.scene.collection.children.link(collection)
    collection.objects.link(bpy.data.objects.new(f"{name} cube", bpy.data.meshes.new(name)))
    return bpy.context.view_layer.layer_collection.children[name]


# each builds one feature into the scene and returns (the warning's feature, a name it must give)
def portal(bpy):
    _lamp(bpy, "Window").data.cycles.is_portal = True
    return "portal", "area light 'Window'"


def volume_only(bpy):
    _cube(bpy, "FogBox", _volume_material(bpy, "Fog", surface=False))
    return "volume", "material 'Fog' on object 'FogBox'"


def volume_and_surface(bpy):
    _cube(bpy, "Jelly", _volume_material(bpy, "Tinted", surface=True))
    return "volume", "material 'Tinted'"


def world_volume(bpy):
    world = bpy.data.worlds.new("Misty")
    nodes, links = world.node_tree.nodes, world.node_tree.links
    links.new(nodes.new("ShaderNodeVolumeScatter").outputs[0], nodes["World Output"].inputs["Volume"])
    bpy.context.scene.world = world
    return "volume", "world 'Misty'"


def volume_object(bpy):
    _link(bpy, bpy.data.objects.new("Smoke", bpy.data.volumes.new("Smoke")))
    return "volume", "object 'Smoke'"


def hair_curves(bpy):
    curves = bpy.data.hair_curves.new("Fur")
    curves.add_curves([3, 3])
    _link(bpy, bpy.data.objects.new("Fur", curves))
    return "hair", "object 'Fur'"


def hair_particles(bpy):
    head = _cube(bpy, "Head")
    head.modifiers.new("Strands", "PARTICLE_SYSTEM")
    head.particle_systems[0].settings.type = "HAIR"
    return "hair", "particle system 'Strands' on object 'Head'"


def point_cloud(bpy):
    _link(bpy, bpy.data.objects.new("Dust", bpy.data.pointclouds.new("Dust")))
    return "point cloud", "object 'Dust'"


def light_linking(bpy):
    _lamp(bpy, "Key", "POINT").light_linking.receiver_collection = bpy.data.collections.new("Lit")
    return "light linking", "light 'Key' (receivers 'Lit')"


def shadow_linking(bpy):
    glow = shader_material(bpy, "Glow", "ShaderNodeEmission", {"Strength": 5.0})
    _cube(bpy, "Neon", glow).light_linking.blocker_collection = bpy.data.collections.new("Blockers")
    return "light linking", "object 'Neon' (blockers 'Blockers')"


def shadow_catcher(bpy):
    _cube(bpy, "Ground").is_shadow_catcher = True
    return "shadow catcher", "object 'Ground'"


def holdout_object(bpy):
    _cube(bpy, "Mask").is_holdout = True
    return "holdout", "object 'Mask'"


def holdout_collection(bpy):
    _layer_collection(bpy, "Matte").holdout = True
    return "holdout", "collection 'Matte' (Holdout in view layer"


def holdout_shader(bpy):
    _cube(bpy, "Cutout", surface_material(bpy, "Hole", lambda nodes, links: nodes.new("ShaderNodeHoldout").outputs[0]))
    return "holdout", "material 'Hole'"


def motion_blur(bpy):
    bpy.context.scene.render.use_motion_blur = True
    return "motion blur", "(Render > Motion Blur)"


def ray_visibility(bpy):
    _cube(bpy, "Ghost").visible_camera = False
    return "ray visibility", "object 'Ghost' (camera off)"


def indirect_only(bpy):
    _layer_collection(bpy, "Bounce").indirect_only = True
    return "ray visibility", "collection 'Bounce' (Indirect Only in view layer"


FEATURES = (portal, volume_only, volume_and_surface, world_volume, volume_object, hair_curves, hair_particles,
            point_cloud, light_linking, shadow_linking, shadow_catcher, holdout_object, holdout_collection,
            holdout_shader, motion_blur, ray_visibility, indirect_only)


@pytest.mark.parametrize("feature", FEATURES, ids=[f.__name__ for f in FEATURES])
def test_each_unsupported_feature_gives_one_warning_naming_it(bpy, feature):
    name, what = feature(bpy)
    _, warnings = extracted(bpy)
    assert len(warnings) == 1 and warnings[0].startswith(f"{name}: ") and what in warnings[0], warnings


def test_many_objects_with_a_feature_give_one_warning_naming_each_once(bpy):
    source = bpy.data.collections.new("Rocks")
    source.objects.link(bpy.data.objects.new("Rock", bpy.data.meshes.new("Rock")))
    source.objects[0].data.from_pydata(CUBE_V, [], CUBE_F)
    for obj in (source.objects[0], _cube(bpy, "Ground")):
        obj.is_shadow_catcher = True
    for i in range(3):  # three instances of one catcher
        empty = _link(bpy, bpy.data.objects.new(f"Rocks{i}", None))
        empty.instance_type, empty.instance_collection = "COLLECTION", source
    _, warnings = extracted(bpy)
    assert len(warnings) == 1 and warnings[0].startswith("shadow catcher: "), warnings
    assert sorted(warnings[0].split(": ")[-1].split(", ")) == ["object 'Ground'", "object 'Rock'"]


def test_a_volume_only_material_leaves_out_its_faces_and_a_surface_beside_a_volume_stays(bpy):
    paint, fog = bpy.data.materials.new("Paint"), _volume_material(bpy, "Fog", surface=False)
    box = _cube(bpy, "Box", paint, fog)
    box.data.polygons[0].material_index = 1  # one face of fog, five painted
    _cube(bpy, "Jelly", _volume_material(bpy, "Tinted", surface=True), location=(5, 0, 0))
    scene, _ = extracted(bpy)
    names = [scene.materials.names[i] for i in scene.material]
    assert names.count("Paint") == 10 and names.count("Tinted") == 12 and "Fog" not in names


def test_light_linking_of_an_object_that_does_not_glow_changes_nothing_and_says_nothing(bpy):
    _cube(bpy, "Plain").light_linking.receiver_collection = bpy.data.collections.new("Lit")  # Cycles ignores it too
    assert extracted(bpy)[1] == []


def test_a_holdout_shader_renders_black(bpy):
    holdout_shader(bpy)
    scene, _ = extracted(bpy)
    hole = scene.materials.names.index("Hole")
    assert np.all(scene.materials.base_color[hole] == 0) and scene.materials.specular[hole] == 0


def _render(bpy, tmp_path):
    """Combined of the current scene rendered by the engine at 16 x 16 pixels, 4 samples, direct light only, and
    its reports."""
    from vpl_gi.operators.engine import render_engine as engine
    from vpl_gi.operators.output.render_file import render_to
    from vpl_gi.vpl_addon.core.exr import read_passes
    scene = bpy.context.scene
    scene.render.engine = engine.VPLGIRenderEngine.bl_idname
    scene.render.resolution_x = scene.render.resolution_y = 16
    scene.vpl_gi.samples, scene.vpl_gi.method = 4, "none"
    path = tmp_path / f"{len(list(tmp_path.iterdir()))}.exr"
    render_to(scene, str(path))
    return read_passes(str(path))[0]["Combined"], list(engine.LAST_REPORTS)


def _floor_seen_from_above(bpy):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    add_mesh(bpy, "Floor", [(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)], [(0, 1, 2, 3)])
    camera_and_black_world(bpy, scene, (0, 0, 6))
    return scene


def test_a_scene_lit_only_by_a_portal_is_black_with_the_portals_warning(ext, tmp_path):
    import bpy
    _floor_seen_from_above(bpy)
    window = _lamp(bpy, "Window")
    window.location, window.data.energy, window.data.size = (0, 0, 2), 1000.0, 2.0
    window.data.cycles.is_portal = True
    combined, reports = _render(bpy, tmp_path)
    portal, no_lights = reports  # the second is the renderer's: the scene has no lights
    assert portal[0] == "WARNING" and portal[1].startswith("portal: ") and "'Window'" in portal[1]
    assert "Window" not in no_lights[1] and "no lights" in no_lights[1] and np.all(combined[..., :3] == 0)


def test_a_fog_box_hides_nothing_behind_it(ext, tmp_path):
    import bpy
    scene = _floor_seen_from_above(bpy)
    add_sun(bpy, scene, (0.3, 0.2, 0.0), energy=3.0)
    fog_box = _cube(bpy, "FogBox", _volume_material(bpy, "Fog", surface=False), location=(0, 0, 2))
    fog_box.scale = (0.5, 0.5, 0.5)
    with_fog, reports = _render(bpy, tmp_path)
    fog_box.hide_render = True
    without, no_reports = _render(bpy, tmp_path)
    assert len(reports) == 1 and reports[0][1].startswith("volume: ") and "'FogBox'" in reports[0][1]
    assert no_reports == [] and with_fog[..., :3].max() > 0 and np.array_equal(with_fog, without)


def test_a_lights_default_node_tree_gives_no_warning_and_a_changed_one_does(bpy):
    """Blender 5.2 gives every light the default tree (a white Emission of Strength 1) and ``use_nodes`` True."""
    camera_and_black_world(bpy, bpy.context.scene, (0, 0, 5))
    _cube(bpy, "Floor")
    lamp = _lamp(bpy, "Lamp", "POINT")
    lamp.location = (0, 0, 3)
    lamp.data.use_nodes = True
    assert lamp.data.node_tree is not None
    _, warnings = extracted(bpy)
    assert not warnings, warnings
    emission = next(n for n in lamp.data.node_tree.nodes if n.type == "EMISSION")
    emission.inputs["Strength"].default_value = 2.0
    _, warnings = extracted(bpy)
    assert warnings == ["light 'Lamp': light nodes are not supported; using colour and power alone"], warnings
