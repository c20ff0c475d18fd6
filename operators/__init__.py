"""Everything that touches bpy: extraction, settings, the render engine, panels, Cycles references, the CLI.

``register`` first checks that the packages the engine needs load (``dependencies``): where one does not, it
registers ``ui.unavailable`` instead (the engine in the list, saying why in one line at registration, at F12 and in
the render panel). Where all load, it registers the engine and starts compiling its kernels on a background thread
(``vpl_addon.precompile``), which ``unregister`` stops and joins.
"""
from . import dependencies

_REGISTERED: list = []  # the modules registered, in order


def _modules() -> tuple:
    from .output import bake, lightmap_bake
    from .engine import render_engine
    from .ui import panels, properties
    return properties, render_engine, panels, bake, lightmap_bake


def register():
    problem = dependencies.problem()
    if problem is not None:
        from .ui import unavailable
        print(problem)
        unavailable.register(problem)
        _REGISTERED.append(unavailable)
        return
    from ..vpl_addon.precompile import KERNELS
    for module in _modules():
        module.register()
        _REGISTERED.append(module)
    KERNELS.start()


def unregister():
    if _REGISTERED and _REGISTERED[0].__name__.endswith(".unavailable"):
        _REGISTERED.pop().unregister()
        return
    from ..vpl_addon.precompile import KERNELS
    KERNELS.stop()
    while _REGISTERED:
        _REGISTERED.pop().unregister()
