"""Render-properties panels of the VPL GI engine: its settings and the passes it can write."""
from __future__ import annotations

import bpy

from .engine import PASS_TOGGLES, VPLGIRenderEngine


class _VPLGIPanel:
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    COMPAT_ENGINES = {VPLGIRenderEngine.bl_idname}

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES


class RENDER_PT_vpl_gi(_VPLGIPanel, bpy.types.Panel):
    bl_label = "VPL GI"
    bl_context = "render"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        settings = context.scene.vpl_gi
        col = layout.column()
        col.prop(settings, "samples")
        col.prop(settings, "light_samples")
        col.prop(settings, "seed")
        col = layout.column(heading="Indirect")
        col.prop(settings, "method")
        sub = col.column()
        sub.active = settings.method != "none"
        sub.prop(settings, "vpls")
        if settings.method == "vbnl":
            sub.prop(settings, "vbnl_samples")
            sub.prop(settings, "photons")
            sub.prop(settings, "elimination")
            sub.prop(settings, "path_extension")
        if settings.method in ("ir", "bidir", "vbnl"):
            sub.prop(settings, "path_reuse")
            sub.prop(settings, "path_threshold")
        if settings.method != "vbnl":
            if settings.method == "smc":
                sub.prop(settings, "smc_replacements")
                sub.prop(settings, "smc_warmup")
            sub.prop(settings, "indirect_samples")
            sub.prop(settings, "clamp")
            sub.prop(settings, "interleave")
        sub.prop(settings, "filter")


class VIEWLAYER_PT_vpl_gi_passes(_VPLGIPanel, bpy.types.Panel):
    bl_label = "Passes"
    bl_context = "view_layer"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        for heading in ("Diffuse", "Glossy", "Other"):  # as Cycles' own pass panel groups them
            col = layout.column(heading=heading, align=True)
            for name, toggle, _, _ in PASS_TOGGLES:
                kind = name.split(" ")[0] if name.split(" ")[0] in ("Diffuse", "Glossy") else "Other"
                if kind == heading:
                    col.prop(context.view_layer, toggle, text=name.replace(f"{heading} ", ""))


CLASSES = (RENDER_PT_vpl_gi, VIEWLAYER_PT_vpl_gi_passes)


register, unregister = bpy.utils.register_classes_factory(CLASSES)
