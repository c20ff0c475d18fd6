"""Settings of the VPL GI engine, stored on the scene as ``scene.vpl_gi``; defaults come from the engine's own
settings classes so Blender, the command line and the engine agree. The placement settings (the shared ones and
each method's) are made from their fields' ``methods.base.option`` metadata: a method's settings appear here, in the
panel and on the command line without a line of this module naming them."""

import bpy

from ...vpl_addon.core.denoise import CLEAN_GUIDES
from ...vpl_addon.gather.summing import GatherSettings
from ...vpl_addon.lightmap import BAKE_PASSES, LightmapSettings
from ...vpl_addon.methods import METHODS, NONE, PLACEMENT, MethodSettings
from ...vpl_addon.paths.data_passes import Mist
from ...vpl_addon.progressive import ViewportSettings
from ...vpl_addon.render import RenderSettings

_RENDER, _GATHER, _VIEW, _LIGHTMAP = RenderSettings(), GatherSettings(), ViewportSettings(), LightmapSettings()

MIST_FALLOFF = {"QUADRATIC": 2.0, "LINEAR": 1.0, "INVERSE_QUADRATIC": 0.5}  # the exponents Cycles gives them

METHOD_ITEMS = tuple((m.name, m.label, m.description) for m in METHODS.values()) + (
    (NONE, "None", "Direct light only: no indirect light is computed"),)


def _property(setting):
    """The Blender property of one ``methods.base.Exposed`` setting: its type, default, label, tooltip, range."""
    how = setting.option
    common = {"name": how.label, "description": how.description, "default": setting.default}
    if setting.kind is bool:
        return bpy.props.BoolProperty(**common)
    if how.items:
        return bpy.props.EnumProperty(items=how.items, **common)
    limits = {key: value for key, value in (("min", how.min), ("max", how.max), ("soft_max", how.soft_max),
                                            ("precision", how.precision)) if value is not None}
    if setting.kind is int:
        return bpy.props.IntProperty(**common, **{k: int(v) for k, v in limits.items()})
    return bpy.props.FloatProperty(**common, **limits)


FILTER_ITEMS = (
    ("BOX", "Box", "Every sample of a pixel weighs the same, within the pixel"),
    ("GAUSSIAN", "Gaussian", "Gaussian filter: samples weigh less away from the pixel's centre"),
    ("BLACKMAN_HARRIS", "Blackman-Harris", "Blackman-Harris filter: sharper than Gaussian (Cycles' default)"),
)

PREFILTER_ITEMS = (  # Cycles' Denoising Prefilter, in ``core.denoise.PREFILTERS``' order
    ("ACCURATE", "Accurate", "Denoise the albedo and normal guides first, then the image with them as clean ones: "
                             f"the most detail, three OpenImageDenoise runs (one from {CLEAN_GUIDES} samples on, "
                             "where the guides are clean already)"),
    ("FAST", "Fast", "One run that takes the guides as noisy: a seventh of Accurate's time at High quality, a "
                     "little softer"),
    ("NONE", "None", "One run that takes the guides as they are, as clean: fast, keeps the guides' own noise"),
)
QUALITY_ITEMS = (  # Cycles' Denoising Quality (OpenImageDenoise's), in ``core.denoise.QUALITIES``' order
    ("HIGH", "High", "OpenImageDenoise's largest network: the best picture, the slowest"),
    ("BALANCED", "Balanced", "A smaller network: about half High's time, nearly its picture"),
    ("FAST", "Fast", "The smallest network: for previews"),
)


def _cycles_setting(name: str, items=None, cycles: str | None = None) -> dict:
    """``get`` and ``set`` of a setting of ours that shows, and renders with, the scene's Cycles setting of the same
    name (or ``cycles``) until it is set here, so a scene made for Cycles keeps its light paths, pixel filter and
    denoiser; without Cycles, Cycles' default. What the user sets is kept as the settings' custom property ``name``.
    ``items``: an enum's."""
    def get(self):
        value = self.get(name)
        if value is not None:
            return value
        value = getattr(getattr(self.id_data, "cycles", None), cycles or name, None)
        if value is None:
            value = self.bl_rna.properties[name].default
        return [item[0] for item in items].index(value) if items else value

    def set(self, value):
        self[name] = value
    return {"get": get, "set": set}


class VPLGISettings(bpy.types.PropertyGroup):
    samples: bpy.props.IntProperty(
        name="Samples", default=_RENDER.samples, min=1, soft_max=1024,
        description="Camera samples per pixel: anti-aliasing and the number of shading points per pixel")
    light_samples: bpy.props.IntProperty(
        name="Light Samples", default=_RENDER.light_samples, min=0, soft_max=64,
        description="Shadow rays toward the lights per camera sample for direct light (0 skips direct light)")
    method: bpy.props.EnumProperty(
        name="Method", items=METHOD_ITEMS, default=_RENDER.method,
        description="How virtual point lights are placed for indirect light")
    indirect_samples: bpy.props.IntProperty(
        name="Indirect Samples", default=_RENDER.indirect_samples, min=1, soft_max=64,
        description="Camera samples per pixel that gather light from the VPLs (at most Samples)")
    clamp: bpy.props.FloatProperty(
        name="Clamp", default=_GATHER.clamp, min=0.0, soft_max=4.0,
        description="Limit the light of very close VPLs: the minimum distance as a multiple of the mean VPL "
                    "spacing (0 = no clamping, exact but spotty; higher = smoother, darker corners)")
    interleave: bpy.props.IntProperty(
        name="Interleave Tile", default=_GATHER.interleave, min=1, max=16,
        description="Pixels of each tile see disjoint subsets of the VPLs (1 = every pixel sees every VPL)")
    filter: bpy.props.BoolProperty(
        name="Filter", default=_GATHER.filter,
        description="Geometry-aware filter that removes the interleaving pattern. Not used when the render is "
                    "denoised: OpenImageDenoise does better on the unfiltered light")
    clamp_indirect: bpy.props.FloatProperty(
        name="Clamp Indirect", default=_GATHER.clamp_indirect, min=0.0, soft_max=100.0,
        description="As Cycles' Clamp Indirect: the largest value a sample of indirect light may take (0 = off). "
                    "Higher values are more accurate; lower ones remove the fireflies of caustics over metal at "
                    "the cost of their light")
    denoise: bpy.props.BoolProperty(
        name="Denoise", default=True,
        description="Denoise the finished image (Combined) with OpenImageDenoise, guided by the surfaces' albedo and "
                    "normal, as Cycles' render denoiser does; the light passes stay as rendered")
    denoising_prefilter: bpy.props.EnumProperty(
        name="Prefilter", items=PREFILTER_ITEMS, default=_RENDER.denoise_prefilter,
        **_cycles_setting("denoising_prefilter", PREFILTER_ITEMS),
        description="How the denoiser treats its albedo and normal guides (as Cycles' Denoise > Prefilter; until set "
                    "here, the scene's Cycles value)")
    denoising_quality: bpy.props.EnumProperty(
        name="Quality", items=QUALITY_ITEMS, default=_RENDER.denoise_quality,
        **_cycles_setting("denoising_quality", QUALITY_ITEMS),
        description="OpenImageDenoise's network: quality against time (as Cycles' Denoise > Quality; until set "
                    "here, the scene's Cycles value)")
    denoising_indirect_apart: bpy.props.BoolProperty(
        name="Indirect Light Apart", default=_RENDER.denoise_indirect_apart,
        description="Denoise the indirect light apart from the rest of the image, and add the two: closer to the "
                    "converged image than one pass over the whole (up to 12 % lower error on the example scenes, "
                    "none where all the light is indirect), for one denoiser run more. Off: the whole image in one "
                    "pass, as Cycles and a compositor Denoise node on Noisy Image do it")
    seed: bpy.props.IntProperty(
        name="Seed", default=_RENDER.seed, min=0,
        description="Seed of the random numbers: the same seed gives the same image")

    max_bounces: bpy.props.IntProperty(
        name="Total", default=12, min=0, max=1024, **_cycles_setting("max_bounces"),
        description="Most bounces a light path makes (as Cycles' Light Paths > Max Bounces > Total; until set "
                    "here, the scene's Cycles value)")
    diffuse_bounces: bpy.props.IntProperty(
        name="Diffuse", default=4, min=0, max=1024, **_cycles_setting("diffuse_bounces"),
        description="Most diffuse bounces a light path makes: 0 leaves only direct light (as Cycles' Light Paths > "
                    "Max Bounces > Diffuse; until set here, the scene's Cycles value)")
    pixel_filter_type: bpy.props.EnumProperty(
        name="Pixel Filter", items=FILTER_ITEMS, default="BLACKMAN_HARRIS",
        **_cycles_setting("pixel_filter_type", FILTER_ITEMS),
        description="How the samples of a pixel are spread and weighed (as Cycles' Film > Pixel Filter; until set "
                    "here, the scene's Cycles value)")
    filter_width: bpy.props.FloatProperty(
        name="Width", default=1.5, min=0.01, max=10.0, subtype="PIXEL", **_cycles_setting("filter_width"),
        description="Width of the pixel filter in pixels (as Cycles' Film > Pixel Filter > Width; until set here, "
                    "the scene's Cycles value)")
    viewport_samples: bpy.props.IntProperty(
        name="Viewport Samples", default=_VIEW.samples, min=1, soft_max=1024,
        description="Rendered shading in the 3D view: full-resolution passes (one camera and one light sample per "
                    "pixel each) averaged before the view stops refining")
    viewport_time_limit: bpy.props.FloatProperty(
        name="Time Limit", default=_VIEW.time_limit, min=0.0, soft_max=60.0, subtype="TIME_ABSOLUTE",
        description="Rendered shading: stop refining this many seconds after a change (0: the samples decide)")
    viewport_start_resolution: bpy.props.IntProperty(
        name="Start Resolution", default=_VIEW.start_resolution, min=8, soft_max=1024, subtype="PIXEL",
        description="Rendered shading: the first image after a change has this many pixels on its longer side, then "
                    "finer images follow up to the view's resolution (as Cycles' viewport Start Resolution)")
    viewport_denoise: bpy.props.BoolProperty(
        name="Denoise", default=_VIEW.denoise,
        description="Rendered shading: denoise the image with OpenImageDenoise after each pass")
    viewport_denoising_prefilter: bpy.props.EnumProperty(
        name="Prefilter", items=PREFILTER_ITEMS, default=_VIEW.denoise_prefilter,
        **_cycles_setting("viewport_denoising_prefilter", PREFILTER_ITEMS, "preview_denoising_prefilter"),
        description="Rendered shading: how the denoiser treats its albedo and normal guides (as Cycles' viewport "
                    "Denoise > Prefilter; until set here, the scene's Cycles value)")
    viewport_denoising_quality: bpy.props.EnumProperty(
        name="Quality", items=QUALITY_ITEMS, default=_VIEW.denoise_quality,
        **_cycles_setting("viewport_denoising_quality", QUALITY_ITEMS, "preview_denoising_quality"),
        description="Rendered shading: OpenImageDenoise's network (as Cycles' viewport Denoise > Quality; until set "
                    "here, the scene's Cycles value)")
    bake_directory: bpy.props.StringProperty(
        name="Bake Folder", default="//vpl_bake/", subtype="DIR_PATH",
        description="Folder of the baked sequence: frame_NNNN.exr per frame, and the state a bake resumes from")
    bake_overwrite: bpy.props.BoolProperty(
        name="Replace Other Bake", default=False,
        description="Replace a bake of other settings (or frames not from a bake) found in the folder")

    def render_settings(self, passes: tuple[str, ...]) -> RenderSettings:
        placement = MethodSettings()
        for setting in PLACEMENT:
            placement = setting.put(placement, getattr(self, setting.prop))
        world = self.id_data.world  # its Mist Pass and AO distance, as Cycles reads them
        mist = Mist() if world is None else Mist(world.mist_settings.start, world.mist_settings.depth,
                                                 MIST_FALLOFF[world.mist_settings.falloff])
        return RenderSettings(samples=self.samples, light_samples=self.light_samples, seed=self.seed, passes=passes,
                              mist=mist, denoise=self.denoise, denoise_prefilter=self.denoising_prefilter,
                              denoise_quality=self.denoising_quality,
                              denoise_indirect_apart=self.denoising_indirect_apart,
                              ao_distance=10.0 if world is None else world.light_settings.distance,
                              film_transparent=self.id_data.render.film_transparent,
                              threads=self.id_data.render.threads,  # Blender's: every core, a fixed number or -t
                              method=self.method, indirect_samples=self.indirect_samples, placement=placement,
                              gather=GatherSettings(interleave=self.interleave, clamp=self.clamp, filter=self.filter,
                                                    clamp_indirect=self.clamp_indirect))

    def viewport_settings(self) -> ViewportSettings:
        """The progressive render of the 3D view's Rendered shading (``vpl_addon.progressive``)."""
        return ViewportSettings(start_resolution=self.viewport_start_resolution, samples=self.viewport_samples,
                                time_limit=self.viewport_time_limit, denoise=self.viewport_denoise,
                                denoise_prefilter=self.viewport_denoising_prefilter,
                                denoise_quality=self.viewport_denoising_quality)


VPLGISettings.__annotations__.update({setting.prop: _property(setting) for setting in PLACEMENT})


class LightmapProperties(bpy.types.PropertyGroup):
    """The Lightmaps panel's settings (``scene.vpl_gi_lightmap``), defaults from ``lightmap.LightmapSettings``."""
    objects: bpy.props.EnumProperty(
        name="Objects", default="SELECTED", description="Which meshes are baked",
        items=(("SELECTED", "Selected", "The selected meshes"), ("ALL", "All", "Every mesh that renders")))
    uv_map: bpy.props.StringProperty(
        name="UV Map", default="", description="The UV map baked into (empty: each mesh's active render UV map)")
    sizing: bpy.props.EnumProperty(
        name="Resolution", default="SIZE", description="How each object's map size is chosen",
        items=(("SIZE", "Size", "One size for every object's map"),
               ("DENSITY", "Texel Density", "Each object's size from its surface area, so that a metre spans the "
                                            "same number of texels on every object")))
    size: bpy.props.IntProperty(name="Size", default=_LIGHTMAP.size, min=1, max=16384,
                                description="Texels per side of each object's map (an image node's own size "
                                            "is replaced)")
    texel_density: bpy.props.FloatProperty(
        name="Texels per Metre", default=32.0, min=0.01, soft_min=1.0, soft_max=1024.0,
        description="Texels a metre of surface spans; each object's size is the nearest power of two (at least 4)")
    bake_pass: bpy.props.EnumProperty(
        name="Pass", default=_LIGHTMAP.bake_pass, description="What is baked, in the meaning of Cycles' bake types",
        items=tuple((name, name, f"Cycles' bake of {name}") for name in BAKE_PASSES))
    samples: bpy.props.IntProperty(name="Samples", default=_LIGHTMAP.samples, min=1, soft_max=64,
                                   description="Sample points per texel")
    vpls: bpy.props.IntProperty(name="VPLs", default=_LIGHTMAP.placement.vpls, min=1, soft_max=1 << 16,
                                description="Virtual lights for all the baked objects at once")
    margin: bpy.props.IntProperty(name="Margin", default=_LIGHTMAP.margin, min=0, soft_max=64,
                                  description="Texels each island grows by (at least 2)")
    denoise: bpy.props.BoolProperty(name="Denoise", default=_LIGHTMAP.denoise,
                                    description="Denoise each map with OpenImageDenoise's lightmap filter")
    target: bpy.props.EnumProperty(
        name="Target", default="IMAGE_FILES", description="Where the maps go",
        items=(("IMAGE_FILES", "Image Files", "One <object name>.exr per object in the folder"),
               ("IMAGE_NODE", "Active Image Node", "The image of the active Image Texture node of each object's "
                                                   "active material, as Cycles' bake writes"),
               ("COLOR_ATTRIBUTE", "Color Attribute", "Each mesh's active colour attribute, read from the baked "
                                                      "map at its corners (a corner attribute \"Baked Light\" is made "
                                                      "where a mesh has none), as Cycles' bake to Color Attributes")))
    directory: bpy.props.StringProperty(name="Folder", default="//lightmaps/", subtype="DIR_PATH",
                                        description="Folder of the image files")


CLASSES = (VPLGISettings, LightmapProperties)


def register():
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.Scene.vpl_gi = bpy.props.PointerProperty(type=VPLGISettings)
    bpy.types.Scene.vpl_gi_lightmap = bpy.props.PointerProperty(type=LightmapProperties)


def unregister():
    del bpy.types.Scene.vpl_gi_lightmap
    del bpy.types.Scene.vpl_gi
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
