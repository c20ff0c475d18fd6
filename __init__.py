"""VPL GI: indirect illumination with virtual point lights, measured against Cycles.

The only entry Blender calls. The engine lives in ``vpl_addon/`` (no bpy); everything that touches Blender is in
``operators/``.
"""


def register():
    from . import operators
    operators.register()


def unregister():
    from . import operators
    operators.unregister()
