"""The Bake Lightmaps panel and its operator with the real bpy module: the panel shows for the engine, the operator
bakes into image files or into the active Image Texture node's image as Cycles' bake does, refuses an object without
such an image before baking anything, and a bake stopped through its progress (ESC) raises and writes nothing."""
import numpy as np
import pytest

from lightmap_scenes import uv_cornell
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
    from vpl_gi.vpl_addon.core.exr import read_passes
    props = box.vpl_gi_lightmap
    props.objects, props.target, props.directory, props.bake_pass = "ALL", "IMAGE_FILES", str(tmp_path), "Diffuse"
    assert bpy.ops.vpl_gi.bake_lightmaps() == {"FINISHED"}
    meshes = sorted(obj.name for obj in box.objects if obj.type == "MESH")
    assert sorted(p.stem for p in tmp_path.glob("*.exr")) == meshes
    image = read_passes(str(tmp_path / "Floor.exr"))[0]["Diffuse"]
    assert image.shape == (16, 16, 4) and image[..., :3].mean() > 0.0


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
