"""Writing a frame to a multilayer EXR through Blender's own render pipeline, atomically and without
overwriting anything the user has unless asked to."""
from __future__ import annotations

import glob
import os
import tempfile
from typing import Callable

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


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def remove_stale_partials(folder: str) -> None:
    """Delete partial files of renders whose process died (killed, power cut): ``.partial-<pid>-*.exr``."""
    for stale in glob.glob(os.path.join(glob.escape(folder), ".partial-*-*.exr")):
        pid = os.path.basename(stale).split("-")[1]
        if pid.isdigit() and int(pid) != os.getpid() and not _alive(int(pid)):
            try:
                os.unlink(stale)
            except OSError:
                pass


def render_to(scene, path: str, verify: Callable[[], None] | None = None) -> None:
    """Render the current frame of ``scene`` with its engine and let Blender write ``path`` atomically: the image
    appears under its name only when complete and when ``verify()`` (called before) does not raise, so a failed or
    killed render never replaces what was there."""
    configure_multilayer_exr(scene)
    folder = os.path.dirname(path)
    remove_stale_partials(folder)
    fd, tmp = tempfile.mkstemp(prefix=f".partial-{os.getpid()}-", suffix=".exr", dir=folder)
    os.close(fd)
    try:
        scene.render.filepath = tmp
        failure = None
        try:
            bpy.ops.render.render(write_still=True, scene=scene.name)
        except RuntimeError as err:  # an engine error report arrives as "Error: <report>"
            failure = err
        if verify is not None:
            verify()
        if failure is not None:
            raise failure
        if os.path.getsize(tmp) == 0:
            raise RuntimeError("Blender wrote no image")
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
