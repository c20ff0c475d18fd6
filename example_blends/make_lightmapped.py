"""Example scenes UV-mapped for lightmaps: each mesh unwrapped by Smart UV Project into a UV map of its own
(``LIGHTMAP_UV``), as a user prepares a scene for Cycles' bake or The Lightmapper, and saved beside the original
as ``<name>_uv.blend``.

    python example_blends/make_lightmapped.py [example_blends/cornell_area.blend ...]

``unwrap`` is what the lightmap tests and ``bench/lightmap.py`` call on a scene they opened themselves.
"""
from __future__ import annotations

import pathlib
import sys

LIGHTMAP_UV = "Lightmap"
ISLAND_MARGIN = 0.02  # Smart UV Project's margin between islands, in UV units (2.6 texels at 128)


def unwrap(bpy, uv_map: str = LIGHTMAP_UV) -> list[str]:
    """Every mesh of the open scene given a UV map ``uv_map`` by Smart UV Project (the active one, which
    rendering keeps reading its textures' maps by name); returns the meshes' names."""
    scene = bpy.context.scene
    meshes = [obj for obj in scene.objects if obj.type == "MESH"]
    for obj in meshes:
        layers = obj.data.uv_layers
        layer = layers.get(uv_map) or layers.new(name=uv_map)
        layers.active = layer
        bpy.ops.object.select_all(action="DESELECT")
        obj.select_set(True)
        bpy.context.view_layer.objects.active = obj
        bpy.ops.object.mode_set(mode="EDIT")
        bpy.ops.mesh.select_all(action="SELECT")
        bpy.ops.uv.smart_project(island_margin=ISLAND_MARGIN)
        bpy.ops.object.mode_set(mode="OBJECT")
    return [obj.name for obj in meshes]


def main(paths: list[str]) -> None:
    import bpy
    here = pathlib.Path(__file__).resolve().parent
    for path in [pathlib.Path(p) for p in paths] or [here / "cornell_area.blend"]:
        bpy.ops.wm.open_mainfile(filepath=str(path.resolve()))
        unwrap(bpy)
        out = path.with_name(f"{path.stem}_uv.blend")
        bpy.ops.wm.save_as_mainfile(filepath=str(out.resolve()))
        print(f"wrote {out}")


if __name__ == "__main__":
    main(sys.argv[1:])
