"""Lightmaps baked from Blender (``vpl_addon.lightmap``): the objects chosen and checked, the scene extracted with
their UV map, the maps written as image files or into the active Image Texture node's image (as Cycles' bake
writes them), and the operator of the render properties' Lightmaps panel, with progress and ESC.

The checks come before anything is baked, one message each naming the object (``LightmapError``), so that a bad
object leaves every file and image as it was. The command line's ``lightmap`` (``cli.lightmap``) uses the same.
"""
from __future__ import annotations

import os
import threading

import bpy
import numpy as np

from ...vpl_addon.core.camera import Camera, view_window
from ...vpl_addon.lightmap import Cancelled, LightmapSettings, bake
from ...vpl_addon.methods import MethodSettings
from ..scene.extract import ACTIVE_UV, ExtractionError, camera_of, extract


class LightmapError(Exception):
    """The bake cannot start; the message names the object or setting at fault."""


def baked_objects(scene, listed: list[str] | None, uv_map: str | None) -> list[str]:
    """The names of the objects to bake: ``listed``, or every mesh that renders; each checked to be a mesh with
    UV map ``uv_map`` (any UV map, without one)."""
    if listed is None:
        listed = [obj.name for obj in scene.objects if obj.type == "MESH" and not obj.hide_render]
        if not listed:
            raise LightmapError(f"scene {scene.name!r} has no mesh to bake")
    for name in listed:
        obj = scene.objects.get(name)
        if obj is None:
            raise LightmapError(f"no object {name!r} in scene {scene.name!r}")
        if obj.type != "MESH":
            raise LightmapError(f"object {name!r} is a {obj.type.lower()}, not a mesh: only meshes are baked")
        layers = obj.data.uv_layers
        if uv_map and uv_map not in layers:
            raise LightmapError(f"object {name!r} has no UV map {uv_map!r} (it has: "
                                f"{', '.join(layer.name for layer in layers) or 'none'})")
        if not len(layers):
            raise LightmapError(f"object {name!r} has no UV map: unwrap it (e.g. Smart UV Project) before baking")
    return list(listed)


def extracted(scene, names: list[str], uv_map: str | None):
    """(the engine's Scene with the bake UV map, extraction's warnings) of ``scene``; its camera, which methods
    that place by the view read, or a placeholder where it has none."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    try:
        camera = camera_of(scene, depsgraph) if scene.camera is not None and scene.camera.type == "CAMERA" else \
            Camera(np.eye(4), 1, 1, view_window(1, 1, orthographic=True, ortho_scale=1.0), orthographic=True)
        built, warnings = extract(depsgraph, camera=camera, bake_uv=uv_map or ACTIVE_UV)
    except ExtractionError as err:
        raise LightmapError(str(err)) from None
    hidden = [name for name in names if name not in built.object_names]
    if hidden:
        raise LightmapError(f"object {hidden[0]!r} has no faces that render (hidden from render, or empty)")
    return built, warnings


def file_path(folder: str, name: str) -> str:
    """Where object ``name``'s map goes in ``folder``: ``<name>.exr``, path separators replaced."""
    return os.path.join(folder, name.replace(os.sep, "_").replace("/", "_") + ".exr")


def write_files(folder: str, result, bake_pass: str) -> list[str]:
    """Each map of ``result`` (``LightmapResult``) as ``folder/<object>.exr`` (made atomically); their paths."""
    try:  # OpenEXR is the command line's (requirements.txt), not a bundled wheel: the add-on registers without it
        from ...vpl_addon.core.exr import write_passes
    except ImportError as err:
        raise LightmapError(f"writing image files needs the OpenEXR package ({err}); bake into the active Image "
                            f"Texture node's image instead") from None
    os.makedirs(folder, exist_ok=True)
    paths = []
    for name, image in result.images.items():
        paths.append(file_path(folder, name))
        write_passes(paths[-1], {bake_pass: image})
    return paths


def node_image(obj):
    """The image of the active Image Texture node of ``obj``'s active material, where Cycles' bake writes; a
    ``LightmapError`` naming the object without one."""
    material = obj.active_material
    node = None if material is None or material.node_tree is None else material.node_tree.nodes.active
    if node is None or node.bl_idname != "ShaderNodeTexImage" or node.image is None:
        raise LightmapError(f"object {obj.name!r}: its active material has no active Image Texture node with an "
                            f"image to bake into")
    return node.image


def write_node_image(image, map_: np.ndarray) -> None:
    """``map_`` (size,size,4, row 0 at v = 1) into Blender ``image`` (scaled to its size first if it differs, as
    its pixels run from the bottom row)."""
    size = map_.shape[0]
    if tuple(image.size) != (size, size):
        image.scale(size, size)
    image.pixels.foreach_set(np.ascontiguousarray(map_[::-1], np.float32).ravel())
    image.update()


def lightmap_settings(props) -> LightmapSettings:
    """The engine's settings from the panel's (``ui.properties.LightmapProperties``)."""
    return LightmapSettings(size=props.size, samples=props.samples, bake_pass=props.bake_pass,
                            placement=MethodSettings(vpls=props.vpls), margin=props.margin, denoise=props.denoise)


class VPLGI_OT_bake_lightmaps(bpy.types.Operator):
    """Bake the light of the chosen meshes into their UV maps from one set of virtual lights, in the meaning of
    Cycles' bake type, to image files or the active Image Texture node's image"""
    bl_idname = "vpl_gi.bake_lightmaps"
    bl_label = "Bake Lightmaps"
    bl_options = {"REGISTER"}

    _thread = _timer = None

    @classmethod
    def poll(cls, context):
        return context.scene is not None and context.scene.render.engine == "VPL_GI"

    def _prepare(self, context):
        """(engine scene, object names, settings, targets): everything read from Blender before baking."""
        scene, props = context.scene, context.scene.vpl_gi_lightmap
        listed = [obj.name for obj in context.selected_objects] if props.objects == "SELECTED" else None
        if listed == []:
            raise LightmapError("no object is selected")
        names = baked_objects(scene, listed, props.uv_map or None)
        targets = {name: node_image(scene.objects[name]) for name in names} if props.target == "IMAGE_NODE" else None
        if props.target == "IMAGE_FILES" and not bpy.path.abspath(props.directory):
            raise LightmapError("set the lightmap folder first")
        built, warnings = extracted(scene, names, props.uv_map or None)
        for warning in warnings:
            self.report({"WARNING"}, warning)
        return built, names, lightmap_settings(props), targets

    def _store(self, context, result, targets) -> None:
        props = context.scene.vpl_gi_lightmap
        for warning in result.warnings:
            self.report({"WARNING"}, warning)
        if targets is None:
            paths = write_files(bpy.path.abspath(props.directory), result, props.bake_pass)
            self.report({"INFO"}, f"baked {len(paths)} lightmaps to {os.path.dirname(paths[0])}")
            return
        for name, image in targets.items():
            write_node_image(image, result.images[name])
        self.report({"INFO"}, f"baked {len(targets)} lightmaps into their images")

    def execute(self, context):  # scripts and background mode: blocking
        try:
            built, names, settings, targets = self._prepare(context)
            self._store(context, bake(built, names, settings), targets)
        except (LightmapError, OSError, ValueError) as err:
            self.report({"ERROR"}, str(err))
            return {"CANCELLED"}
        return {"FINISHED"}

    def invoke(self, context, event):  # the UI: the bake on a thread, progress on the cursor, ESC stops it
        try:
            built, names, settings, self._targets = self._prepare(context)
        except (LightmapError, ValueError) as err:
            self.report({"ERROR"}, str(err))
            return {"CANCELLED"}
        self._stop, self._done, self._outcome = threading.Event(), [0.0, "starting"], {}

        def progress(fraction, text):
            self._done[:] = [fraction, text]
            return not self._stop.is_set()

        def run():
            try:
                self._outcome["result"] = bake(built, names, settings, progress)
            except Exception as err:  # handed to the main thread, which reports it
                self._outcome["error"] = err
        self._thread = threading.Thread(target=run, daemon=True)
        self._thread.start()
        wm = context.window_manager
        wm.progress_begin(0, 100)
        self._timer = wm.event_timer_add(0.1, window=context.window)
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        if event.type == "ESC":
            self._stop.set()
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        if self._thread.is_alive():
            fraction, text = self._done
            context.window_manager.progress_update(int(fraction * 100))
            context.workspace.status_text_set(f"VPL GI lightmaps: {text} ({fraction * 100:.0f} %), ESC to stop")
            return {"RUNNING_MODAL"}
        self._finish(context)
        error = self._outcome.get("error")
        if isinstance(error, Cancelled):
            self.report({"WARNING"}, "lightmap bake stopped: nothing was written")
            return {"CANCELLED"}
        if error is not None:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        try:
            self._store(context, self._outcome["result"], self._targets)
        except (LightmapError, OSError) as err:
            self.report({"ERROR"}, str(err))
            return {"CANCELLED"}
        return {"FINISHED"}

    def _finish(self, context):
        wm = context.window_manager
        wm.event_timer_remove(self._timer)
        wm.progress_end()
        context.workspace.status_text_set(None)


register, unregister = bpy.utils.register_classes_factory((VPLGI_OT_bake_lightmaps,))
