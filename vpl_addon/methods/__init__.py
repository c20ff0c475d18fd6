"""Methods that place virtual lights: one subpackage per paper holding the modules only it uses, behind the one
contract of ``base.Method``. May import every layer below (a method's sequence hooks use ``sequence``), never
another method, ``render`` or Blender's side.

``REGISTERED`` is the one list of methods, in the order users see them: a new method is its folder plus one line
there. ``METHODS`` maps each name to its ``Method``; ``MethodSettings`` holds the settings every method shares (the
VPL budget, path reuse) and one field per method with settings of its own, under the method's name.
"""
from __future__ import annotations

import importlib
from dataclasses import field, make_dataclass

from .base import Method, MethodContext, exposed, option

REGISTERED = (
    "vbnl",
    "bidir",
    "ir",
    "smc",
)

NONE = "none"  # the setting's value for no indirect light: no method runs


def _load(names) -> dict[str, Method]:
    methods = {}
    for name in names:
        method = importlib.import_module(f".{name}", __package__).METHOD
        if method.name != name:
            raise TypeError(f"methods/{name}/ defines the method {method.name!r}: a method is named after its folder")
        methods[name] = method
    return methods


METHODS: dict[str, Method] = _load(REGISTERED)

SHARED = [
    ("vpls", int, option(4096, label="VPLs", min=1, soft_max=1 << 20,
                         description="Virtual lights the gather uses: more is smoother (and slower for the summing "
                                     "methods); bidir's are those kept after resampling")),
    # in a sequence, keep the light paths between frames and re-trace only those that moved objects cut or moved
    # lights carry (Moreau et al.)
    ("path_reuse", bool, option(True, label="Path Reuse",
                                description="In animations, keep light paths between frames and re-trace only "
                                            "those that moving objects cut or lights move")),
    # T of eq. 2 (Moreau et al. sec. 3.3): a moved segment whose new end reflects within T of its old energy keeps
    # the rest of its path (the paper's 0.1 %); 0 re-traces every moved segment
    ("path_threshold", float, option(1e-3, label="Path Threshold", min=0.0, max=1.0, precision=4,
                                     description="Path reuse: a moved light path keeps the rest of its vertices when "
                                                 "the energy reflected at its new end changes less than this "
                                                 "fraction (Moreau et al. eq. 2); 0 re-traces every moved segment")),
]
PATH_REUSE = ("path_reuse", "path_threshold")  # the shared settings of the methods that reuse light paths

MethodSettings = make_dataclass(
    "MethodSettings",
    SHARED + [(m.name, m.settings, field(default_factory=m.settings)) for m in METHODS.values() if m.settings])
MethodSettings.__module__ = __name__  # where pickle finds it
MethodSettings.__doc__ = "What placing lights takes: the shared settings, and each method's own under its name."

# every placement setting users see, the shared ones first: what the Blender properties, the panel and the command
# line's flags are made from
PLACEMENT = exposed(MethodSettings)


def place(name: str, context: MethodContext, settings):
    if name not in METHODS:
        raise ValueError(f"unknown method {name!r}; choose one of {', '.join(METHODS)}")
    return METHODS[name].place(context, settings)
