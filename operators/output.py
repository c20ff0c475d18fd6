"""Writing a frame to a multilayer EXR through Blender's own render pipeline, atomically and without
overwriting anything the user has unless asked to."""
from __future__ import annotations

import os
import tempfile

import bpy


class OutputExists(FileExistsError):
    pass


def check_target(path: str, overwrite: bool) -> str:
    path = os.path.abspath(path)
    if os.path.exists(path) and not overwrite:
        raise OutputExists(f"{path} exists; pass --overwrite to replace it")
    os.makedirs(os.path.dirname(path), exist_ok=True)
    return path


def configure_multilayer_exr(scene) -> None:
    settings = scene.render.image_settings
    if hasattr(settings, "media_type"):
        settings.media_type = "MULTI_LAYER_IMAGE"
    settings.file_format = "OPEN_EXR_MULTILAYER"
    settings.color_depth = "32"
    settings.exr_codec = "ZIP"
    scene.render.use_file_extension = False


def render_to(scene, path: str) -> None:
    """Render the current frame of ``scene`` with its engine and let Blender write ``path`` atomically."""
    configure_multilayer_exr(scene)
    folder = os.path.dirname(path)
    fd, tmp = tempfile.mkstemp(prefix=".partial-", suffix=".exr", dir=folder)
    os.close(fd)
    try:
        scene.render.filepath = tmp
        bpy.ops.render.render(write_still=True, scene=scene.name)
        if os.path.getsize(tmp) == 0:
            raise RuntimeError("Blender wrote no image")
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
