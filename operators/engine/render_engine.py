"""The "VPL GI" RenderEngine: F12, ``blender -b ... -f N`` and the CLI all render through it, and the 3D view's
Rendered shading (``view_update`` / ``view_draw``, a thin layer over ``viewport.Viewport``).

Passes follow the view layer's pass toggles, as with Cycles (Combined always; Diffuse Direct / Indirect / Color,
Glossy Direct / Indirect / Color, Emission, Environment, Ambient Occlusion, Depth, Mist, Normal, Position, Object and
Material Index and Cryptomatte when enabled), so Blender writes them into multilayer EXRs (Cryptomatte with its
manifests) and the compositor sees them by name; a pass switched on that the engine does not write is named in one
warning. *Film > Transparent* decides whether Combined shows the world, as in Cycles.
"""
from __future__ import annotations

import time

import bpy
import numpy as np

from ...vpl_addon.core import cryptomatte
from ...vpl_addon.core import passes as P
from ...vpl_addon.core.memory import trim_heap
from ...vpl_addon.core.passes import BadOutput
from ...vpl_addon.precompile import KERNELS
from ...vpl_addon.render import Cancelled, render
from ..scene.extract import ExtractionError, depth_of_field, extract
from .frame_state import FRAME_LOG, active_sequence
from .viewport import ImageTexture, Viewport, view_camera

# (pass name, view layer toggle, channels, channel ids): the passes of light, then the data passes
LIGHT_PASSES = (
    (P.DIFFUSE_DIRECT, "use_pass_diffuse_direct", 3, "RGB"),
    (P.DIFFUSE_INDIRECT, "use_pass_diffuse_indirect", 3, "RGB"),
    (P.DIFFUSE_COLOR, "use_pass_diffuse_color", 3, "RGB"),
    (P.EMIT, "use_pass_emit", 3, "RGB"),
    (P.GLOSSY_DIRECT, "use_pass_glossy_direct", 3, "RGB"),
    (P.GLOSSY_INDIRECT, "use_pass_glossy_indirect", 3, "RGB"),
    (P.GLOSSY_COLOR, "use_pass_glossy_color", 3, "RGB"),
    (P.ENVIRONMENT, "use_pass_environment", 3, "RGB"),
)
DATA_PASSES = (
    (P.AO, "use_pass_ambient_occlusion", 3, "RGB"),
    (P.DEPTH, "use_pass_z", 1, "Z"),
    (P.MIST, "use_pass_mist", 1, "Z"),
    (P.POSITION, "use_pass_position", 3, "XYZ"),
    (P.NORMAL, "use_pass_normal", 3, "XYZ"),
    (P.OBJECT_INDEX, "use_pass_object_index", 1, "X"),
    (P.MATERIAL_INDEX, "use_pass_material_index", 1, "X"),
)
PASS_TOGGLES = LIGHT_PASSES + DATA_PASSES
# Cryptomatte kind -> its view layer toggle; the number of passes follows the view layer's Levels
DENOISING_TOGGLE = "denoising_store_passes"  # view_layer.cycles: Denoising Albedo / Normal, Noisy Image
CRYPTOMATTE_TOGGLES = {"CryptoObject": "use_pass_cryptomatte_object", "CryptoMaterial": "use_pass_cryptomatte_material",
                       "CryptoAsset": "use_pass_cryptomatte_asset"}

# Messages of the last render, for callers that cannot see the UI (the command line, tests).
LAST_REPORTS: list[tuple[str, str]] = []
LAST_STATS: dict = {}


def requested_passes(view_layer, scene) -> tuple[str, ...]:
    names = [name for name, toggle, _, _ in PASS_TOGGLES if getattr(view_layer, toggle, False)]
    for kind, toggle in CRYPTOMATTE_TOGGLES.items():
        if getattr(view_layer, toggle, False):
            names += P.cryptomatte_passes(kind, view_layer.pass_cryptomatte_depth)
    if getattr(getattr(view_layer, "cycles", None), DENOISING_TOGGLE, False):  # Cycles' Denoising Data
        names += [P.DENOISING_ALBEDO, P.DENOISING_NORMAL] + [P.NOISY_IMAGE] * scene.vpl_gi.denoise  # Combined before
    return (P.COMBINED,) + tuple(names)


def channel_ids(name: str) -> str:
    """Blender's channel names of a pass: ``RGBA`` of Combined and Cryptomatte, ``XYZ``... of the data passes."""
    if name in (P.DENOISING_ALBEDO, P.DENOISING_NORMAL):
        return "RGB" if name == P.DENOISING_ALBEDO else "XYZ"
    return next((ids for pass_name, _, _, ids in PASS_TOGGLES if pass_name == name), "RGBA")


def unwritten_passes(view_layer) -> list[str]:
    """What the user switched on for this view layer that the engine does not write, by its UI name: Blender's
    other pass toggles, Cycles' (its volume, shadow catcher, denoising and debug passes), shader AOVs and light
    groups."""
    ours = {toggle for _, toggle, _, _ in PASS_TOGGLES} | set(CRYPTOMATTE_TOGGLES.values()) | \
        {"use_pass_combined", "use_pass_cryptomatte_accurate", DENOISING_TOGGLE}  # Combined always; Accurate is no pass
    toggles = [(view_layer, prop) for prop in view_layer.bl_rna.properties if prop.identifier.startswith("use_pass_")]
    cycles = getattr(view_layer, "cycles", None)  # None when Cycles is disabled
    if cycles is not None:  # its passes; its other booleans (5.2's denoising_pass_follow_reflections) are settings
        toggles += [(cycles, prop) for prop in cycles.bl_rna.properties
                    if prop.identifier.startswith(("use_pass_", "pass_"))]
    names = [prop.name for settings, prop in toggles if prop.type == "BOOLEAN" and prop.identifier not in ours
             and getattr(settings, prop.identifier)]
    names += [f"AOV {aov.name!r}" for aov in getattr(view_layer, "aovs", ())]
    names += [f"light group {group.name!r}" for group in getattr(view_layer, "lightgroups", ())]
    return names


class VPLGIRenderEngine(bpy.types.RenderEngine):
    bl_idname = "VPL_GI"
    bl_label = "VPL GI"
    bl_use_preview = False  # material previews: Blender's own (a render at our F12 settings takes seconds)
    bl_use_postprocess = True
    bl_use_eevee_viewport = True  # Material Preview shading: EEVEE, as with Cycles

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)  # Blender makes the RenderEngine's own data here
        self._viewport = None  # the 3D view's progressive render, made by its first view_update
        self._texture = None

    def __del__(self):
        if getattr(self, "_viewport", None) is not None:  # its worker threads end with it
            self._viewport.close()

    @staticmethod
    def _view(context, depsgraph):
        """The 3D view's camera; looking through the scene's camera, with its depth of field (none if that cannot be
        read: extraction names it)."""
        region, scene, lens = context.region, depsgraph.scene, None
        if context.region_data.view_perspective == "CAMERA" and scene.camera is not None:
            try:
                lens = depth_of_field(scene.camera.evaluated_get(depsgraph), depsgraph)
            except ExtractionError:
                lens = None
        return view_camera(context.region_data.view_matrix, context.region_data.window_matrix, region.width,
                           region.height, scene.vpl_gi, lens)

    def view_update(self, context, depsgraph):
        if self._viewport is None:
            self._viewport, self._texture = Viewport(), ImageTexture()
        self._viewport.update(depsgraph, self._view(context, depsgraph))

    def view_draw(self, context, depsgraph):
        import gpu
        view = self._viewport
        if view is None:
            return
        view.look(self._view(context, depsgraph))
        self.update_stats("VPL GI", view.status)
        if view.frame is not None:
            gpu.state.blend_set("ALPHA_PREMULT")
            self.bind_display_space_shader(depsgraph.scene)
            self._texture.draw(view.frame, context.region.width, context.region.height)
            self.unbind_display_space_shader()
            gpu.state.blend_set("NONE")
        if view.busy:  # drawn again soon: the next image, or the status
            self.tag_redraw()

    def _report(self, level: str, message: str):
        LAST_REPORTS.append((level, message))
        self.report({level}, message)
        if level == "ERROR":
            self.error_set(message)

    def render(self, depsgraph):
        try:
            self._render(depsgraph)
        finally:  # what the render freed goes back to the system, not into Blender's idle footprint
            trim_heap()

    def _render(self, depsgraph):
        """One frame: the scene extracted, its settings read, rendered, and the passes handed to Blender; every
        failure is one report, never a traceback."""
        LAST_REPORTS.clear()
        LAST_STATS.clear()
        scene, view_layer = depsgraph.scene, depsgraph.view_layer
        t0 = time.perf_counter()
        built = self._extracted(depsgraph)
        if built is None:
            return
        t_extract = time.perf_counter() - t0
        passes = requested_passes(view_layer, scene)
        unwritten = unwritten_passes(view_layer)
        if unwritten:
            self._report("WARNING", f"view layer {view_layer.name!r}: VPL GI does not write these passes: "
                                    f"{', '.join(unwritten)}")
        settings = scene.vpl_gi.render_settings(passes)
        sequence, settings.placement_seed = active_sequence(scene, settings, self.is_animation)  # bake, blender -a
        t_wait = time.perf_counter()
        if not self._kernels_ready(settings.method):
            return
        t_wait = time.perf_counter() - t_wait
        bands = []
        with KERNELS.rendering():
            result = self._rendered(built, settings, sequence, view_layer.name, bands)
        if result is None:
            return
        if sequence is not None:
            FRAME_LOG.append({"frame": scene.frame_current, "light_paths": result.info.get("light_paths"),
                              "reused": bool(result.info.get("reused")), "bvh_builds": sequence.bvh_builds,
                              "animated": sequence.animated})
        LAST_STATS.update(seconds={"extract": t_extract, "kernels": t_wait, **result.seconds}, rays=result.rays,
                          threads=result.threads, width=built.camera.width, height=built.camera.height,
                          samples=settings.samples, method=settings.method, info=result.info, bands_shown=len(bands))
        self._write(view_layer.name, result.passes, _cryptomatte_metadata(view_layer.name, passes, built))

    def _kernels_ready(self, method: str) -> bool:
        """Wait, saying so, while the background thread compiles ``method``'s kernels (the first render after an
        install); False after ESC."""
        while not KERNELS.wait(method, timeout=0.25):
            self.update_stats("VPL GI", f"Waiting: {KERNELS.status()}")
            if self.test_break():
                self._report("INFO", "render cancelled")
                return False
        return True

    def _extracted(self, depsgraph):
        """The engine's scene of ``depsgraph`` (its warnings reported), or None after reporting why not."""
        def told(text):
            self.update_stats("VPL GI", text)
            return not self.test_break()

        try:
            built, warnings = extract(depsgraph, told)
        except ExtractionError as err:
            self._report("ERROR", str(err))
            return None
        except Cancelled:
            self._report("INFO", "render cancelled")
            return None
        except Exception as err:  # a bug: one line in the UI and on the command line, never a traceback
            self._report("ERROR", _one_line(f"scene extraction failed ({type(err).__name__}: {err}); please report"))
            return None
        for warning in warnings:
            self._report("WARNING", warning)
        return built

    def _rendered(self, built, settings, sequence, layer_name: str, bands: list[int]):
        """The engine's render of ``built`` with its progress, ESC and finished bands shown as they come (each
        band's row count appended to ``bands``), its warnings reported; None after reporting why not."""
        def progress(fraction, text):
            self.update_progress(fraction)
            self.update_stats("VPL GI", f"{text} {fraction * 100:.0f}%")
            return not self.test_break()

        def shown(row, band):
            """A band of finished rows on screen at once, as Cycles shows its tiles (Blender's rows go up)."""
            rows, width = band.shape[:2]
            tile = self.begin_result(0, built.camera.pixel_region[3] - row - rows, width, rows, layer=layer_name)
            tile.layers[0].passes.find_by_name(P.COMBINED, "").rect.foreach_set(
                np.ascontiguousarray(band[::-1]).reshape(-1))
            self.end_result(tile)
            bands.append(rows)

        try:
            result = render(built, settings, progress, sequence=sequence, shown=shown)
        except Cancelled:
            self._report("INFO", "render cancelled")
            return None
        except BadOutput as err:
            self._report("ERROR", _one_line(f"{err} (a bug; please report it)"))
            return None
        except Exception as err:
            self._report("ERROR", _one_line(f"render failed ({type(err).__name__}: {err}); please report"))
            return None
        for warning in result.warnings:
            self._report("WARNING", warning)
        return result

    def _write(self, layer_name, images, metadata):
        """Hand the images to Blender. With a render border Blender's result is the border's size, cropped or not
        (without crop Blender puts it back into the full frame itself, as it does with Cycles' result), so the
        images, which are the border's pixels, fill it from (0, 0)."""
        height, width = images[P.COMBINED].shape[:2]
        for name in images:
            if name != P.COMBINED:
                self.add_pass(name, P.CHANNELS[name], channel_ids(name), layer=layer_name)
        out = self.begin_result(0, 0, width, height, layer=layer_name)
        if (out.resolution_x, out.resolution_y) != (width, height):  # never a silent misfit: name the setting
            self.end_result(out, cancel=True)
            self._report("ERROR", f"the render result is {out.resolution_x}x{out.resolution_y} pixels but the "
                                  f"engine rendered {width}x{height} (resolution and render border settings); "
                                  f"please report")
            return
        layer = out.layers[0]
        for name, image in images.items():
            render_pass = layer.passes.find_by_name(name, "")
            if render_pass is None:
                continue
            # engine images have row 0 at the top, Blender's buffers at the bottom
            render_pass.rect.foreach_set(np.ascontiguousarray(image[::-1]).reshape(-1))
        self.end_result(out)
        whole = self.get_result()  # the file's header takes the whole result's stamp data, not a tile's
        for key, value in metadata.items():
            whole.stamp_data_add_field(key, value)

    def update_render_passes(self, scene=None, renderlayer=None):
        self.register_pass(scene, renderlayer, P.COMBINED, 4, "RGBA", "COLOR")
        for name in requested_passes(renderlayer, scene)[1:]:
            ids = channel_ids(name)
            kind = "COLOR" if ids.startswith("RGB") else "VECTOR" if len(ids) == 3 else "VALUE"
            self.register_pass(scene, renderlayer, name, P.CHANNELS[name], ids, kind)


def _cryptomatte_metadata(layer_name: str, passes, scene) -> dict[str, str]:
    """The manifests of the Cryptomatte kinds among ``passes`` (``core.cryptomatte``), for the file's header."""
    names = {"CryptoObject": scene.object_names, "CryptoMaterial": scene.materials.listed_names,
             "CryptoAsset": scene.asset_names}
    metadata = {}
    for kind, listed in names.items():
        if any(name.startswith(kind) for name in passes):
            metadata.update(cryptomatte.header(f"{layer_name}.{kind}", listed))
    return metadata


def _one_line(message: str) -> str:
    return " ".join(message.split())


def get_panels():
    """Cycles/Eevee panels that also make sense for this engine (output, format, color management...); the light's
    panel is EEVEE's (``panels.ADOPTED``), not this one that shows its type alone. A node editor's copy of a panel
    (``NODE_``) shares its engines, so it is left out with it."""
    exclude = {"VIEWLAYER_PT_filter", "VIEWLAYER_PT_layer_passes", "DATA_PT_light"}
    return [p for p in bpy.types.Panel.__subclasses__()
            if "BLENDER_RENDER" in getattr(p, "COMPAT_ENGINES", set())
            and p.__name__.removeprefix("NODE_") not in exclude]


def register():
    bpy.utils.register_class(VPLGIRenderEngine)
    for panel in get_panels():
        panel.COMPAT_ENGINES.add("VPL_GI")


def unregister():
    for panel in get_panels():
        panel.COMPAT_ENGINES.discard("VPL_GI")
    bpy.utils.unregister_class(VPLGIRenderEngine)
