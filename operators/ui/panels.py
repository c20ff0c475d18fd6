"""Panels of the VPL GI engine: its settings, light paths, film, performance and the passes it can write, and
Blender's own panels of the Light, Material and World tabs adopted for it."""
from __future__ import annotations

import bpy

from ...vpl_addon.methods import METHODS, NONE, PATH_REUSE
from ...vpl_addon.precompile import KERNELS
from ..engine.render_engine import CRYPTOMATTE_TOGGLES, DENOISING_TOGGLE, VPLGIRenderEngine

# Blender's own panels of the Light, Material and World tabs that show for this engine too: EEVEE's, whose polls read
# their own COMPAT_ENGINES for external engines to join (Cycles' read one set shared by every Cycles panel)
ADOPTED = (
    "DATA_PT_EEVEE_light",  # type, colour, power, size (the node editor's copy shares its engines)
    "DATA_PT_spot",  # its Beam Shape: spot angle and blend
    "EEVEE_MATERIAL_PT_context_material",  # material slots
    "EEVEE_MATERIAL_PT_surface",
    "EEVEE_WORLD_PT_surface",
)


# the summing gather's settings, which apply to the methods whose lights it sums
SUMMED_GATHER = ("indirect_samples", "clamp", "interleave")


def indirect_settings(method: str) -> list[str]:
    """The settings the render panel shows under Indirect for ``method`` (a name of ``METHODS``, or none): the VPL
    budget, the method's own settings, path reuse where it keeps light paths, the summing gather's where it sums its
    lights, the filter, and Clamp Indirect where there is indirect light."""
    chosen = METHODS.get(method)
    if chosen is None:
        return ["vpls", "filter"]
    return ["vpls", *(setting.prop for setting in chosen.options()),
            *(PATH_REUSE if chosen.reuses_light_paths else ()), *(SUMMED_GATHER if chosen.sums_lights else ()),
            "filter", "clamp_indirect"]


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
        if not KERNELS.ready:
            layout.label(text=KERNELS.status(), icon="TIME")
        col = layout.column()
        col.prop(settings, "samples")
        col.prop(settings, "light_samples")
        col.prop(settings, "seed")
        col = layout.column(heading="Indirect")
        col.prop(settings, "method")
        sub = col.column()
        sub.active = settings.method != NONE
        for name in indirect_settings(settings.method):
            sub.prop(settings, name)
        layout.prop(settings, "denoise")
        sub = layout.column()
        sub.active = settings.denoise
        sub.prop(settings, "denoising_prefilter")
        sub.prop(settings, "denoising_quality")
        sub.prop(settings, "denoising_indirect_apart")


class RENDER_PT_vpl_gi_viewport(_VPLGIPanel, bpy.types.Panel):
    """The 3D view's Rendered shading, as Cycles' Sampling > Viewport."""
    bl_label = "Viewport"
    bl_context = "render"

    SETTINGS = ("viewport_samples", "viewport_time_limit", "viewport_start_resolution", "viewport_denoise")
    DENOISING = ("viewport_denoising_prefilter", "viewport_denoising_quality")

    def draw(self, context):
        self.layout.use_property_split = True
        settings = context.scene.vpl_gi
        column = self.layout.column()
        for name in self.SETTINGS:
            column.prop(settings, name)
        sub = self.layout.column()
        sub.active = settings.viewport_denoise
        for name in self.DENOISING:
            sub.prop(settings, name)


class VIEWLAYER_PT_vpl_gi_passes(_VPLGIPanel, bpy.types.Panel):
    """The passes the engine writes, grouped as Cycles' own pass panels group them."""
    bl_label = "Passes"
    bl_context = "view_layer"
    GROUPS = (  # (heading, toggles)
        ("Data", ("use_pass_z", "use_pass_mist", "use_pass_position", "use_pass_normal")),
        ("Indexes", ("use_pass_object_index", "use_pass_material_index")),
        ("Diffuse", ("use_pass_diffuse_direct", "use_pass_diffuse_indirect", "use_pass_diffuse_color")),
        ("Glossy", ("use_pass_glossy_direct", "use_pass_glossy_indirect", "use_pass_glossy_color")),
        ("Light", ("use_pass_emit", "use_pass_environment", "use_pass_ambient_occlusion")),
        ("Cryptomatte", tuple(CRYPTOMATTE_TOGGLES.values()) + ("pass_cryptomatte_depth",)),
    )

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        labels = context.view_layer.bl_rna.properties
        for heading, toggles in self.GROUPS:
            col = layout.column(heading=heading, align=True)
            for toggle in toggles:
                col.prop(context.view_layer, toggle, text=labels[toggle].name.removeprefix(f"{heading} "))
            if heading == "Data" and getattr(context.view_layer, "cycles", None) is not None:
                col.prop(context.view_layer.cycles, DENOISING_TOGGLE, text="Denoising Data")


class DATA_PT_vpl_gi_area_spread(_VPLGIPanel, bpy.types.Panel):
    """The area light's spread, which the engine renders as Cycles does (EEVEE's Beam Shape is the spot's alone)."""
    bl_label = "Beam Shape"
    bl_context = "data"
    bl_parent_id = "DATA_PT_EEVEE_light"

    @classmethod
    def poll(cls, context):
        return context.light is not None and context.light.type == "AREA" and super().poll(context)

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.prop(context.light, "spread")


class RENDER_PT_vpl_gi_light_paths(_VPLGIPanel, bpy.types.Panel):
    bl_label = "Light Paths"
    bl_context = "render"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        settings = context.scene.vpl_gi
        col = layout.column(heading="Max Bounces", align=True)
        col.prop(settings, "max_bounces")
        col.prop(settings, "diffuse_bounces")


class RENDER_PT_vpl_gi_film(_VPLGIPanel, bpy.types.Panel):
    bl_label = "Film"
    bl_context = "render"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        settings = context.scene.vpl_gi
        layout.prop(context.scene.render, "film_transparent")
        col = layout.column()
        col.prop(settings, "pixel_filter_type")
        sub = col.column()
        sub.active = settings.pixel_filter_type != "BOX"  # Box is one pixel wide whatever the width (core.camera)
        sub.prop(settings, "filter_width")


class RENDER_PT_vpl_gi_performance(_VPLGIPanel, bpy.types.Panel):
    """Blender's own thread settings, which the engine follows as Cycles does (Performance > Threads)."""
    bl_label = "Performance"
    bl_context = "render"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        render = context.scene.render
        col = layout.column()
        col.prop(render, "threads_mode")
        sub = col.column(align=True)
        sub.enabled = render.threads_mode == "FIXED"
        sub.prop(render, "threads")


# the Bake Lightmaps panel's settings by group: what is baked, how well, where it goes
LIGHTMAP_GROUPS = (
    ("Bake", ("objects", "uv_map", "bake_pass")),
    ("Quality", ("sizing", "size", "samples", "vpls", "margin", "denoise")),
    ("Output", ("target",)),
)


class RENDER_PT_vpl_gi_lightmaps(_VPLGIPanel, bpy.types.Panel):
    """Lightmaps of the chosen meshes from one set of virtual lights (``output.lightmap_bake``)."""
    bl_label = "Bake Lightmaps"
    bl_context = "render"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        props = context.scene.vpl_gi_lightmap
        self.layout.use_property_split = True
        for heading, names in LIGHTMAP_GROUPS:
            group = self.layout.column(heading=heading)
            for name in names:
                group.prop(props, "texel_density" if name == "size" and props.sizing == "DENSITY" else name)
        if props.target == "IMAGE_FILES":
            group.prop(props, "directory")
        self.layout.operator("vpl_gi.bake_lightmaps", icon="RENDER_STILL")


CLASSES = (RENDER_PT_vpl_gi, RENDER_PT_vpl_gi_viewport, RENDER_PT_vpl_gi_light_paths,
           RENDER_PT_vpl_gi_film, RENDER_PT_vpl_gi_performance, RENDER_PT_vpl_gi_lightmaps,
           VIEWLAYER_PT_vpl_gi_passes, DATA_PT_vpl_gi_area_spread)


def adopted_panels() -> list[type]:
    """The registered panels named in ``ADOPTED``."""
    return [getattr(bpy.types, name) for name in ADOPTED if hasattr(bpy.types, name)]


def register():
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    for panel in adopted_panels():
        panel.COMPAT_ENGINES.add(VPLGIRenderEngine.bl_idname)


def unregister():
    for panel in adopted_panels():
        panel.COMPAT_ENGINES.discard(VPLGIRenderEngine.bl_idname)
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
