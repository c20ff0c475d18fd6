"""The Bake Lightmaps panel and its operator with the real bpy module: the panel shows for the engine, the operator
bakes into image files (Blender's EXR writer, the values kept exactly), into the active Image Texture node's image
or into the colour attribute as Cycles' bake does, refuses an object without such an image, or two objects of one
mesh for a colour attribute, before baking anything, and a bake stopped through its progress (ESC) raises and
writes nothing."""
import numpy as np
import pytest

from lightmap_scenes import read_map, uv_cornell
from test_panels import _shown

pytestmark = pytest.mark.blender


@pytest.fixture
def box(ext, tmp_path):
    import bpy
    uv_cornell(bpy, tmp_path / "cornell_uv.blend")
    scene = bpy.context.scene
    scene.render.engine = "VPL_GI"
    props = scene.vpl_gi_lightmap
    props.size, props.vpls, props.uv_map = 16, 512, "Lightmap"
    return scene


def _select(bpy, *names):
    bpy.ops.object.select_all(action="DESELECT")
    for name in names:
        bpy.data.objects[name].select_set(True)


def test_the_panel_shows_in_the_render_tab_for_the_engine(box):
    import bpy
    assert "RENDER_PT_vpl_gi_lightmaps" in _shown(bpy, "render")
    box.render.engine = "CYCLES"
    assert "RENDER_PT_vpl_gi_lightmaps" not in _shown(bpy, "render")


def test_the_operator_bakes_the_selected_objects_into_their_image_nodes(box):
    import bpy
    image = bpy.data.images.new("floor light", 8, 8, float_buffer=True)
    material = bpy.data.materials.new("Floor paint")
    material.use_nodes = True
    node = material.node_tree.nodes.new("ShaderNodeTexImage")
    node.image = image
    material.node_tree.nodes.active = node
    floor = bpy.data.objects["Floor"]
    floor.data.materials.clear()
    floor.data.materials.append(material)
    _select(bpy, "Floor")
    box.vpl_gi_lightmap.target = "IMAGE_NODE"
    assert bpy.ops.vpl_gi.bake_lightmaps() == {"FINISHED"}
    pixels = np.array(image.pixels[:]).reshape(16, 16, 4)  # the image takes the bake's size
    assert np.isfinite(pixels).all() and (pixels >= 0).all() and pixels[..., :3].mean() > 0.0
    assert pixels[..., 3].max() == 1.0


def test_an_object_without_an_image_node_is_refused_before_anything_is_baked(box, tmp_path):
    import bpy
    _select(bpy, "Floor", "BackWall")
    box.vpl_gi_lightmap.target = "IMAGE_NODE"
    with pytest.raises(RuntimeError, match="no active Image Texture node"):
        bpy.ops.vpl_gi.bake_lightmaps()


def test_the_operator_writes_one_file_per_mesh(box, tmp_path):
    import bpy
    props = box.vpl_gi_lightmap
    props.objects, props.target, props.directory, props.bake_pass = "ALL", "IMAGE_FILES", str(tmp_path), "Diffuse"
    assert bpy.ops.vpl_gi.bake_lightmaps() == {"FINISHED"}
    meshes = sorted(obj.name for obj in box.objects if obj.type == "MESH")
    assert sorted(p.stem for p in tmp_path.glob("*.exr")) == meshes
    image = read_map(tmp_path / "Floor.exr")
    assert image.shape == (16, 16, 4) and image[..., :3].mean() > 0.0
    assert not list(tmp_path.glob(".partial-*"))


def test_files_hold_the_maps_exactly_and_leave_the_scene_as_it_was(box, tmp_path):
    """Blender's EXR writer through a scratch scene: 32-bit values above 1 and fractional alpha read back to the
    bit, the user's scene's output format untouched, no scratch scene or image left behind."""
    import bpy
    from vpl_gi.operators.output.lightmap_targets import write_files
    maps = {"A": np.random.default_rng(0).uniform(0.0, 40.0, (6, 5, 4)).astype(np.float32)}
    maps["A"][..., 3] = np.linspace(0.0, 1.0, 30).reshape(6, 5)
    box.render.image_settings.file_format = "PNG"
    scenes, images = len(bpy.data.scenes), len(bpy.data.images)
    assert write_files(str(tmp_path), maps) == [str(tmp_path / "A.exr")]
    assert np.array_equal(read_map(tmp_path / "A.exr"), maps["A"])
    assert box.render.image_settings.file_format == "PNG"
    assert (len(bpy.data.scenes), len(bpy.data.images)) == (scenes, images)


def _baked_corners(bpy, name, tmp_path):
    """The Floor's corners' UVs, and its map baked into an image file by the same settings."""
    props = bpy.context.scene.vpl_gi_lightmap
    props.target, props.directory = "IMAGE_FILES", str(tmp_path)
    assert bpy.ops.vpl_gi.bake_lightmaps() == {"FINISHED"}
    mesh = bpy.data.objects[name].data
    uv = np.empty(2 * len(mesh.loops), np.float32)
    mesh.uv_layers["Lightmap"].data.foreach_get("uv", uv)
    return uv.reshape(-1, 2), read_map(tmp_path / f"{name}.exr")


def _colors(attribute):
    values = np.empty(4 * len(attribute.data), np.float32)
    attribute.data.foreach_get("color", values)
    return values.reshape(-1, 4)


def test_a_colour_attribute_holds_the_baked_map_at_each_corner(box, tmp_path):
    """No colour attribute on the floor: one is made, per corner, holding the map (the same bake written to a file)
    read bilinearly at each corner's UV, alpha 1."""
    import bpy
    from vpl_gi.vpl_addon.lightmap.lookup import lookup
    _select(bpy, "Floor")
    uv, map_ = _baked_corners(bpy, "Floor", tmp_path)
    mesh = bpy.data.objects["Floor"].data
    assert len(mesh.color_attributes) == 0
    box.vpl_gi_lightmap.target = "COLOR_ATTRIBUTE"
    assert bpy.ops.vpl_gi.bake_lightmaps() == {"FINISHED"}
    attribute = mesh.color_attributes.active_color
    assert (attribute.name, attribute.domain, attribute.data_type) == ("Baked Light", "CORNER", "FLOAT_COLOR")
    colors = _colors(attribute)
    assert np.allclose(colors[:, :3], lookup(map_, uv)[:, :3], rtol=1e-5, atol=1e-6)
    assert colors[:, :3].mean() > 0.0 and (colors[:, 3] == 1.0).all()


def test_a_per_vertex_colour_attribute_holds_the_mean_of_its_corners(box, tmp_path):
    import bpy
    from vpl_gi.vpl_addon.lightmap.lookup import lookup, per_vertex
    _select(bpy, "TallBox")
    uv, map_ = _baked_corners(bpy, "TallBox", tmp_path)
    mesh = bpy.data.objects["TallBox"].data
    mesh.color_attributes.active_color = mesh.color_attributes.new("Paint", "FLOAT_COLOR", "POINT")
    box.vpl_gi_lightmap.target = "COLOR_ATTRIBUTE"
    assert bpy.ops.vpl_gi.bake_lightmaps() == {"FINISHED"}
    assert [a.name for a in mesh.color_attributes] == ["Paint"]
    corner_vertex = np.array([loop.vertex_index for loop in mesh.loops])
    want = per_vertex(lookup(map_, uv), corner_vertex, len(mesh.vertices))
    assert np.allclose(_colors(mesh.color_attributes["Paint"])[:, :3], want[:, :3], rtol=1e-5, atol=1e-6)


def test_two_objects_of_one_mesh_are_refused_a_colour_attribute(box):
    import bpy
    twin = bpy.data.objects["Floor"].copy()  # a linked duplicate: the same mesh
    box.collection.objects.link(twin)
    _select(bpy, "Floor", twin.name)
    box.vpl_gi_lightmap.target = "COLOR_ATTRIBUTE"
    with pytest.raises(RuntimeError, match=f"objects 'Floor' and '{twin.name}' share mesh"):
        bpy.ops.vpl_gi.bake_lightmaps()
    assert len(bpy.data.objects["Floor"].data.color_attributes) == 0


def test_a_bake_stopped_by_its_progress_raises_and_reports_how_far_it_got(box):
    """The operator's ESC: its thread's progress returns False, the bake raises ``Cancelled`` after the object
    under way, and the operator then writes nothing."""
    from vpl_gi.operators.output.lightmap_bake import extracted, lightmap_settings
    from vpl_gi.vpl_addon.lightmap import Cancelled, bake
    names = ["Floor", "Ceiling", "BackWall"]
    built, _ = extracted(box, names, "Lightmap")
    heard = []

    def progress(fraction, text):
        heard.append((fraction, text))
        return False
    with pytest.raises(Cancelled):
        bake(built, names, lightmap_settings(box.vpl_gi_lightmap), progress)
    assert heard == [(1 / 3, "Floor")]


def test_the_texel_density_replaces_the_size_when_chosen(box):
    from vpl_gi.operators.output.lightmap_bake import lightmap_settings
    props = box.vpl_gi_lightmap
    props.texel_density = 12.5
    assert lightmap_settings(props).texel_density is None and lightmap_settings(props).size == 16
    props.sizing = "DENSITY"
    assert lightmap_settings(props).texel_density == 12.5
