"""Everything that touches bpy: extraction, settings, the render engine, panels, Cycles references, the CLI."""
from . import bake, engine, panels, properties

MODULES = (properties, engine, panels, bake)


def register():
    for module in MODULES:
        module.register()


def unregister():
    for module in reversed(MODULES):
        module.unregister()
