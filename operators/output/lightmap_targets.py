"""Where baked lightmaps go: image files, the active Image Texture node's image (as Cycles' bake writes), or each
mesh's colour attribute (as Cycles' bake to Color Attributes writes). They are written after the whole bake
(``lightmap_bake``), so that a refused or stopped bake leaves every file, image and mesh as it was.

Files are written by Blender's own EXR writer: plain linear RGBA in 32-bit float (channels R, G, B, A, which game
engines and image tools read as the image), the output settings those of a scratch scene, so the user's scene's
output settings are not touched; each file is written under a temporary name beside it and renamed into place.
"""
from __future__ import annotations

import os

import bpy
import numpy as np

from ...vpl_addon.lightmap.lookup import lookup, per_vertex
from ..scene.extract import uv_layer

# the colour attribute made for a mesh that has none active; not "Lightmap", which UV maps are often called and
# whose names attributes share
ATTRIBUTE = "Baked Light"


def file_path(folder: str, name: str) -> str:
    """Where object ``name``'s map goes in ``folder``: ``<name>.exr``, path separators replaced."""
    return os.path.join(folder, name.replace(os.sep, "_").replace("/", "_") + ".exr")


def write_files(folder: str, images: dict[str, np.ndarray]) -> list[str]:
    """Each map of ``images`` (object name -> (size,size,4), row 0 at v = 1) as ``folder/<object>.exr``; their
    paths."""
    os.makedirs(folder, exist_ok=True)
    output = bpy.data.scenes.new(".VPL GI lightmap output")
    settings = output.render.image_settings
    settings.file_format, settings.color_mode, settings.color_depth, settings.exr_codec = \
        "OPEN_EXR", "RGBA", "32", "ZIP"
    try:
        paths = [file_path(folder, name) for name in images]
        for path, image in zip(paths, images.values()):
            _save(image, path, output)
    finally:
        bpy.data.scenes.remove(output)
    return paths


def _save(map_: np.ndarray, path: str, output) -> None:
    """``map_`` written to ``path`` with ``output``'s image settings, through a temporary name in its folder."""
    image = bpy.data.images.new(".VPL GI lightmap", map_.shape[1], map_.shape[0], alpha=True, float_buffer=True)
    partial = os.path.join(os.path.dirname(path), ".partial-" + os.path.basename(path))
    try:
        _set_pixels(image, map_)
        image.save_render(partial, scene=output)
        os.replace(partial, path)
    finally:
        bpy.data.images.remove(image)
        if os.path.exists(partial):
            os.unlink(partial)


def write_node_image(image, map_: np.ndarray) -> None:
    """``map_`` (size,size,4, row 0 at v = 1) into Blender ``image`` (scaled to its size first if it differs, as
    its pixels run from the bottom row)."""
    size = map_.shape[0]
    if tuple(image.size) != (size, size):
        image.scale(size, size)
    _set_pixels(image, map_)
    image.update()


def _set_pixels(image, map_: np.ndarray) -> None:
    """Blender ``image``'s pixels (bottom row first) from ``map_`` (H,W,4, row 0 at v = 1), as float32."""
    image.pixels.foreach_set(np.ascontiguousarray(map_[::-1], np.float32).ravel())


def write_color_attribute(obj, map_: np.ndarray, uv_map: str | None) -> str:
    """``map_`` read at each corner's point of UV map ``uv_map`` (None: the one rendering uses) into the mesh's
    active colour attribute, per corner or per vertex as its domain is (made as a corner attribute ``ATTRIBUTE``
    where the mesh has none); alpha 1, as Cycles' bake writes it. The attribute's name."""
    mesh = obj.data
    uv = np.empty(2 * len(mesh.loops), np.float32)
    uv_layer(mesh, uv_map).data.foreach_get("uv", uv)  # the map extraction baked in
    values = lookup(map_, uv.reshape(-1, 2))
    attribute = mesh.color_attributes.active_color
    if attribute is None:
        attribute = mesh.color_attributes.new(ATTRIBUTE, "FLOAT_COLOR", "CORNER")
        mesh.color_attributes.active_color = attribute
    if attribute.domain == "POINT":
        corner_vertex = np.empty(len(mesh.loops), np.int64)
        mesh.loops.foreach_get("vertex_index", corner_vertex)
        values = per_vertex(values, corner_vertex, len(mesh.vertices))
    values[:, 3] = 1.0
    attribute.data.foreach_set("color", np.ascontiguousarray(values, np.float32).ravel())
    mesh.update()
    return attribute.name
