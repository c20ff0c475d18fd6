"""Lightmaps baked from Blender (``vpl_addon.lightmap``): the objects chosen and checked, the scene extracted with
their UV map, the maps written to their target (``lightmap_targets``: image files, the active Image Texture node's
image or the colour attribute, as Cycles' bake writes them), and the operator of the render properties' Lightmaps
panel, with progress and ESC.

The checks come before anything is baked, one message each naming the object (``LightmapError``), so that a bad
object leaves every file, image and mesh as it was. The command line's ``lightmap`` (``cli.lightmap``) uses the same.
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
from .lightmap_targets import write_color_attribute, write_files, write_node_image


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


def node_image(obj):
    """The image of the active Image Texture node of ``obj``'s active material, where Cycles' bake writes; a
    ``LightmapError`` naming the object without one."""
    material = obj.active_material
    node = None if material is None or material.node_tree is None else material.node_tree.nodes.active
    if node is None or node.bl_idname != "ShaderNodeTexImage" or node.image is None:
        raise LightmapError(f"object {obj.name!r}: its active material has no active Image Texture node with an "
                            f"image to bake into")
    return node.image


def target_writer(scene, props, names: list[str]):
    """A function that writes a bake's maps (object name -> image) into the panel's target and returns what it
    wrote into, for the report; the target read and checked now, before the bake, and kept as it was then."""
    uv_map = props.uv_map or None
    if props.target == "IMAGE_NODE":
        images = {name: node_image(scene.objects[name]) for name in names}

        def write(maps):
            for name, map_ in maps.items():
                write_node_image(images[name], map_)
            return "their images"
    elif props.target == "COLOR_ATTRIBUTE":
        objects = {name: scene.objects[name] for name in names}
        _one_object_a_mesh(objects)

        def write(maps):
            written = {write_color_attribute(objects[name], map_, uv_map) for name, map_ in maps.items()}
            return f"colour attribute {', '.join(sorted(written))}"
    else:
        folder = bpy.path.abspath(props.directory)
        if not folder:
            raise LightmapError("set the lightmap folder first")

        def write(maps):
            return os.path.dirname(write_files(folder, maps)[0])
    return write


def _one_object_a_mesh(objects: dict) -> None:
    """A ``LightmapError`` naming two of ``objects`` that share a mesh, whose one colour attribute cannot hold the
    light of both."""
    seen = {}
    for name, obj in objects.items():
        other = seen.setdefault(obj.data.name, name)
        if other != name:
            raise LightmapError(f"objects {other!r} and {name!r} share mesh {obj.data.name!r}, whose colour "
                                f"attribute holds one light: make them single user, or bake one of them")


def lightmap_settings(props) -> LightmapSettings:
    """The engine's settings from the panel's (``ui.properties.LightmapProperties``)."""
    return LightmapSettings(size=props.size, texel_density=props.texel_density if props.sizing == "DENSITY" else None,
                            samples=props.samples, bake_pass=props.bake_pass,
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
        """(engine scene, object names, settings, the target's writer): everything read from Blender before
        baking."""
        scene, props = context.scene, context.scene.vpl_gi_lightmap
        listed = [obj.name for obj in context.selected_objects] if props.objects == "SELECTED" else None
        if listed == []:
            raise LightmapError("no object is selected")
        names = baked_objects(scene, listed, props.uv_map or None)
        write = target_writer(scene, props, names)
        built, warnings = extracted(scene, names, props.uv_map or None)
        for warning in warnings:
            self.report({"WARNING"}, warning)
        return built, names, lightmap_settings(props), write

    def _store(self, result, write) -> None:
        for warning in result.warnings:
            self.report({"WARNING"}, warning)
        self.report({"INFO"}, f"baked {len(result.images)} lightmaps into {write(result.images)}")

    def execute(self, context):  # scripts and background mode: blocking
        try:
            built, names, settings, write = self._prepare(context)
            self._store(bake(built, names, settings), write)
        except (LightmapError, OSError, ValueError) as err:
            self.report({"ERROR"}, str(err))
            return {"CANCELLED"}
        return {"FINISHED"}

    def invoke(self, context, event):  # the UI: the bake on a thread, progress on the cursor, ESC stops it
        try:
            built, names, settings, self._write = self._prepare(context)
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
            self._store(self._outcome["result"], self._write)
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
