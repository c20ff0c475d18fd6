"""Everything that touches bpy: extraction, settings, the render engine, panels, Cycles references, the CLI."""
from .output import bake, lightmap_bake
from .engine import render_engine as engine
from .ui import panels, properties

MODULES = (properties, engine, panels, bake, lightmap_bake)


def register():
    for module in MODULES:
        module.register()


def unregister():
    for module in reversed(MODULES):
        module.unregister()
