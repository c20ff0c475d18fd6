"""Settings of the VPL GI engine, stored on the scene as ``scene.vpl_gi``."""
from __future__ import annotations

import bpy

from ..vpl_addon.render import RenderSettings

_DEFAULTS = RenderSettings()


class VPLGISettings(bpy.types.PropertyGroup):
    samples: bpy.props.IntProperty(
        name="Samples", default=_DEFAULTS.samples, min=1, soft_max=1024,
        description="Camera samples per pixel: anti-aliasing and the number of shading points per pixel")
    light_samples: bpy.props.IntProperty(
        name="Light Samples", default=_DEFAULTS.light_samples, min=0, soft_max=64,
        description="Shadow rays toward the lights per camera sample for direct light (0 skips direct light)")
    seed: bpy.props.IntProperty(
        name="Seed", default=_DEFAULTS.seed, min=0,
        description="Seed of the random numbers: the same seed gives the same image")

    def render_settings(self, passes: tuple[str, ...]) -> RenderSettings:
        return RenderSettings(samples=self.samples, light_samples=self.light_samples, seed=self.seed, passes=passes)


def register():
    bpy.utils.register_class(VPLGISettings)
    bpy.types.Scene.vpl_gi = bpy.props.PointerProperty(type=VPLGISettings)


def unregister():
    del bpy.types.Scene.vpl_gi
    bpy.utils.unregister_class(VPLGISettings)
