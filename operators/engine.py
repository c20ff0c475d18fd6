"""The "VPL GI" RenderEngine: F12, ``blender -b ... -f N`` and the CLI all render through it.

Passes follow the view layer's pass toggles, as with Cycles (Combined always; Diffuse Direct / Indirect / Color,
Glossy Direct / Indirect / Color, Emission and Environment when enabled), so Blender writes them into multilayer EXRs
and the compositor sees them by name. *Film > Transparent* decides whether Combined shows the world, as in Cycles.
"""
from __future__ import annotations

import time

import bpy
import numpy as np

from ..vpl_addon.core import passes as P
from ..vpl_addon.core.memory import trim_heap
from ..vpl_addon.core.passes import BadOutput
from ..vpl_addon.render import Cancelled, render
from .extract import ExtractionError, extract
from .frame_state import FRAME_LOG, active_sequence

# (pass name, view layer toggle, channels, channel ids)
PASS_TOGGLES = (
    (P.DIFFUSE_DIRECT, "use_pass_diffuse_direct", 3, "RGB"),
    (P.DIFFUSE_INDIRECT, "use_pass_diffuse_indirect", 3, "RGB"),
    (P.DIFFUSE_COLOR, "use_pass_diffuse_color", 3, "RGB"),
    (P.EMIT, "use_pass_emit", 3, "RGB"),
    (P.GLOSSY_DIRECT, "use_pass_glossy_direct", 3, "RGB"),
    (P.GLOSSY_INDIRECT, "use_pass_glossy_indirect", 3, "RGB"),
    (P.GLOSSY_COLOR, "use_pass_glossy_color", 3, "RGB"),
    (P.ENVIRONMENT, "use_pass_environment", 3, "RGB"),
)

# Messages of the last render, for callers that cannot see the UI (the command line, tests).
LAST_REPORTS: list[tuple[str, str]] = []
LAST_STATS: dict = {}


def requested_passes(view_layer) -> tuple[str, ...]:
    return (P.COMBINED,) + tuple(name for name, toggle, _, _ in PASS_TOGGLES if getattr(view_layer, toggle, False))


class VPLGIRenderEngine(bpy.types.RenderEngine):
    bl_idname = "VPL_GI"
    bl_label = "VPL GI"
    bl_use_preview = False
    bl_use_postprocess = True

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
        LAST_REPORTS.clear()
        LAST_STATS.clear()
        scene = depsgraph.scene
        view_layer = depsgraph.view_layer
        t0 = time.perf_counter()
        try:
            built, warnings = extract(depsgraph)
        except ExtractionError as err:
            self._report("ERROR", str(err))
            return
        except Exception as err:  # a bug: one line in the UI and on the command line, never a traceback
            self._report("ERROR", _one_line(f"scene extraction failed ({type(err).__name__}: {err}); please report"))
            return
        t_extract = time.perf_counter() - t0
        for warning in warnings:
            self._report("WARNING", warning)
        passes = requested_passes(view_layer)
        settings = scene.vpl_gi.render_settings(passes)
        sequence, settings.placement_seed = active_sequence(scene, settings, self.is_animation)  # bake, blender -a

        def progress(fraction, text):
            self.update_progress(fraction)
            self.update_stats("VPL GI", f"{text} {fraction * 100:.0f}%")
            return not self.test_break()

        try:
            result = render(built, settings, progress, sequence=sequence)
        except Cancelled:
            self._report("INFO", "render cancelled")
            return
        except BadOutput as err:
            self._report("ERROR", _one_line(f"{err} (a bug; please report it)"))
            return
        except Exception as err:
            self._report("ERROR", _one_line(f"render failed ({type(err).__name__}: {err}); please report"))
            return
        for warning in result.warnings:
            self._report("WARNING", warning)
        if sequence is not None:
            FRAME_LOG.append({"frame": scene.frame_current, "light_paths": result.info.get("light_paths"),
                              "reused": bool(result.info.get("reused")), "bvh_builds": sequence.bvh_builds})
        LAST_STATS.update(seconds={"extract": t_extract, **result.seconds}, rays=result.rays, threads=result.threads,
                          width=built.camera.width, height=built.camera.height, samples=settings.samples,
                          method=settings.method, info=result.info)
        self._write(view_layer.name, result.passes)

    def _write(self, layer_name, images):
        """Hand the images to Blender. With a render border Blender's result is the border's size, cropped or not
        (without crop Blender puts it back into the full frame itself, as it does with Cycles' result), so the
        images, which are the border's pixels, fill it from (0, 0)."""
        height, width = images[P.COMBINED].shape[:2]
        for name in images:
            if name != P.COMBINED:
                self.add_pass(name, P.CHANNELS[name], "RGBA"[:P.CHANNELS[name]], layer=layer_name)
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

    def update_render_passes(self, scene=None, renderlayer=None):
        self.register_pass(scene, renderlayer, P.COMBINED, 4, "RGBA", "COLOR")
        for name, toggle, channels, ids in PASS_TOGGLES:
            if name in requested_passes(renderlayer):
                self.register_pass(scene, renderlayer, name, channels, ids, "COLOR")


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
