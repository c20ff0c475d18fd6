"""Scenes for the lightmap tests, made with the real bpy module: the Cornell box UV-mapped by Smart UV Project
(``example_blends/make_lightmapped.py``), and a floor with a UV map and no light; and a baked file read back."""
from conftest import EXAMPLES


def uv_cornell(bpy, path) -> str:
    """``example_blends/cornell_area.blend`` with a Smart UV Project map "Lightmap" on each mesh, saved at
    ``path``."""
    from example_blends.make_lightmapped import unwrap
    bpy.ops.wm.open_mainfile(filepath=str(EXAMPLES / "cornell_area.blend"))
    unwrap(bpy)
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    return str(path)


def dark_floor(bpy, path) -> str:
    """A UV-mapped floor and nothing to light it, saved at ``path``."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    mesh = bpy.data.meshes.new("Floor")
    mesh.from_pydata([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], [], [(0, 1, 2, 3)])
    mesh.uv_layers.new(name="UVMap")
    bpy.context.scene.collection.objects.link(bpy.data.objects.new("Floor", mesh))
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    return str(path)


def read_map(path):
    """The (H,W,4) image of lightmap file ``path``, checked to be a plain RGBA image (channels R, G, B, A with no
    layer or pass prefix, as game engines read it)."""
    from vpl_addon.core.exr import read_passes
    passes, _ = read_passes(str(path))
    assert list(passes) == ["Combined"], list(passes)  # read_passes names a plain RGBA image Combined
    return passes["Combined"]
