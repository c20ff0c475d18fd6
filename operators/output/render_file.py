"""Writing a frame to a multilayer EXR through Blender's own render pipeline, atomically and without
overwriting anything the user has unless asked to, and leaving the scene's output settings as they were."""
from __future__ import annotations

import contextlib
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


def _image_settings_of(settings) -> dict:
    """The values of an ``ImageFormatSettings``' own settings that can be set, the media type and the file format
    first (setting the format resets the depth, codec and colour space to the format's own), and the colour space
    of a linear format such as EXR (another format's is its own, set with the format)."""
    values = {}
    for prop in sorted(settings.bl_rna.properties, key=lambda p: p.identifier not in ("media_type", "file_format")):
        if prop.is_readonly or prop.type in {"POINTER", "COLLECTION"}:
            continue
        value = getattr(settings, prop.identifier)
        values[prop.identifier] = value[:] if getattr(prop, "is_array", False) else value
    if getattr(settings, "has_linear_colorspace", False):
        values["linear_colorspace_settings.name"] = settings.linear_colorspace_settings.name
    return values


@contextlib.contextmanager
def kept_output_settings(scene):
    """Inside the block the output path, file extension and image format of ``scene`` may change; after it, also
    after an error, they are the user's again."""
    render = scene.render
    kept = {"filepath": render.filepath, "use_file_extension": render.use_file_extension}
    image = _image_settings_of(render.image_settings)
    try:
        yield
    finally:
        for name, value in kept.items():
            setattr(render, name, value)
        settings = render.image_settings
        for name, value in image.items():
            if name == "linear_colorspace_settings.name":
                settings.linear_colorspace_settings.name = value
            else:
                setattr(settings, name, value)


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
    killed render never replaces what was there. The scene's output path and format are the user's again after."""
    folder = os.path.dirname(path)
    remove_stale_partials(folder)
    fd, tmp = tempfile.mkstemp(prefix=f".partial-{os.getpid()}-", suffix=".exr", dir=folder)
    os.close(fd)
    try:
        failure = None
        with kept_output_settings(scene):
            configure_multilayer_exr(scene)
            scene.render.filepath = tmp
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
