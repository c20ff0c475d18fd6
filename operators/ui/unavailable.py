"""What registers when a required package does not load (``operators.dependencies``): the VPL GI engine that
renders nothing and says why, and a render-properties panel with that line, so the user sees the package and the
fix where the settings would be instead of an add-on that failed to enable."""
from __future__ import annotations

import bpy

MESSAGE = [""]  # the line of ``dependencies.problem()``, set by ``register``


class VPLGIUnavailableEngine(bpy.types.RenderEngine):
    bl_idname = "VPL_GI"
    bl_label = "VPL GI"

    def render(self, depsgraph):
        self.report({"ERROR"}, MESSAGE[0])
        self.error_set(MESSAGE[0])


class RENDER_PT_vpl_gi_unavailable(bpy.types.Panel):
    bl_label = "VPL GI"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "render"
    COMPAT_ENGINES = {VPLGIUnavailableEngine.bl_idname}

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES

    def draw(self, context):
        column = self.layout.column()
        column.alert = True
        for i, line in enumerate(_wrapped(MESSAGE[0])):
            column.label(text=line, icon="ERROR" if i == 0 else "BLANK1")


def _wrapped(text: str, width: int = 60) -> list[str]:
    """``text`` in lines of about ``width`` characters, split at spaces (a panel label does not wrap)."""
    lines, line = [], ""
    for word in text.split():
        if line and len(line) + 1 + len(word) > width:
            lines.append(line)
            line = word
        else:
            line = f"{line} {word}" if line else word
    return lines + [line] if line else lines


CLASSES = (VPLGIUnavailableEngine, RENDER_PT_vpl_gi_unavailable)


def register(message: str):
    MESSAGE[0] = message
    for cls in CLASSES:
        bpy.utils.register_class(cls)


def unregister():
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
