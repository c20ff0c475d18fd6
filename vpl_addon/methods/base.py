"""The method contract, written as code: what every way of placing virtual lights provides (``Method``), what it is
handed (``MethodContext``), and how its settings describe themselves (``option``) so that the Blender properties,
the render panel, the command line's flags and the bench's methods are made from them.

A method is one folder ``methods/<name>/`` whose package defines ``METHOD = Method(...)``, plus one line naming it
in ``methods/__init__.py``'s ``REGISTERED``: nothing else names a method. As in Mitsuba 3, where an integrator is a
plugin behind one interface and one registration line (``include/mitsuba/render/integrator.h``), and pbrt-v2's
``igi.cpp``, a technique is a *place* pass and a *gather* pass:

* ``place(context, settings) -> (VirtualLights, info)``: the lights of one frame, and a dict of figures worth
  reporting (paths traced, shares...). ``settings`` is the whole ``MethodSettings``; a method reads its own part
  under its name (``settings.vbnl``) and the shared VPL budget ``settings.vpls``.
* Lights that are summed (VPLs) go to the one interleaved gather (``gather.summing``); a method whose lights are
  sampled instead brings ``gather(surface, lights, context, settings, rng, glossy=None, pixel=None)`` and
  ``gather_samples(settings, camera_samples) -> int``, the sample pairs a pixel takes. The gather returns two (K,3)
  parts: the light the point's own samples find, which the frame's filter may smooth when the picture is not
  denoised, and the light of paths continued past it (over metal: a caustic's rare bright samples), left as
  sampled, so that no filter spreads one such sample over a square of pixels.
* A method that keeps a state from frame to frame of a sequence provides ``start(context, settings) -> state`` (a
  cold start, warm-up included, so a chunk of frames can begin on another machine) and ``advance(state, context,
  settings, motion) -> (VirtualLights, info)``; without them a sequence reuses the previous frame's lights when
  nothing they depend on changed (``sequence.state``).

The flags say what the sequence machinery and the Blender side may rely on: ``view_independent`` (lights that do not
depend on the camera), ``stable_lights`` (a light keeps its slot from frame to frame), ``uses_still`` (candidates
drawn from the sequence's still scene), ``reuses_light_paths`` (the path reuse options of Moreau et al. apply).
"""
from __future__ import annotations

import dataclasses
from dataclasses import MISSING, dataclass, field
from typing import Any, Callable

import numpy as np

from ..paths.camera_points import CameraPoints


@dataclass
class MethodContext:
    scene: object
    tracer: object
    lights: object  # LightSet
    rng: np.random.Generator
    max_bounces: int
    # what a method draws from the camera's view (vbnl's candidates and their catchment): the pixels' numbers, the
    # same in every frame of a sequence (``rng`` is the frame's), so a view that did not change places its lights
    # where it did and a sequence's lights do not flicker; None: ``rng``
    camera_rng: np.random.Generator | None = None
    # in a sequence: the frame without the objects that move in it, as (scene, tracer), or None
    # (``SequenceState.still``); asked for by a method that finds what it draws from the view in it (vbnl)
    still: Callable[[], tuple | None] | None = None
    # the points the view sees, (count, rng) -> ``CameraPoints``: None, the camera's pixels' (``seen``); a lightmap
    # bake gives its texels' sample points, so that a method placing by the view places by what is baked
    view_points: Callable[[int, np.random.Generator], CameraPoints] | None = None

    def seen(self, count: int, rng: np.random.Generator) -> CameraPoints:
        """``count`` points the view sees, drawn uniformly over it (bidir's camera points x_1, smc's X)."""
        if self.view_points is not None:
            return self.view_points(count, rng)
        return CameraPoints.sample(self.scene, self.tracer, count, rng)


@dataclass(frozen=True)
class Option:
    """How one setting shows itself to a user: its label and tooltip, the name of its Blender property and command
    line flag (``prop``; ``--photons`` for ``photons``, ``--no-path-reuse`` for a setting on by default), its range
    and, for a choice, the items (identifier, label, description)."""
    label: str
    description: str
    prop: str = ""
    min: float | None = None
    max: float | None = None
    soft_max: float | None = None
    precision: int | None = None
    items: tuple[tuple[str, str, str], ...] = ()


def option(default: Any = MISSING, *, default_factory: Callable[[], Any] | Any = MISSING, **how) -> Any:
    """A settings dataclass field that users see: ``how`` are ``Option``'s fields. Fields made with plain
    ``dataclasses.field`` stay the engine's own (tuned by measurement, not shown)."""
    return field(default=default, default_factory=default_factory, metadata={"option": Option(**how)})


@dataclass(frozen=True)
class Exposed:
    """One user-facing setting inside a tree of settings dataclasses: where it lives (attribute names from the
    root), how it shows (``option``), its type (bool, int, float or str) and default."""
    path: tuple[str, ...]
    option: Option
    kind: type
    default: Any

    @property
    def prop(self) -> str:
        return self.option.prop or "_".join(self.path)

    def get(self, settings) -> Any:
        for name in self.path:
            settings = getattr(settings, name)
        return settings

    def put(self, settings, value):
        """``settings`` with this one value replaced (the dataclasses above it copied, the rest shared)."""
        head, *rest = self.path
        inner = value if not rest else Exposed(tuple(rest), self.option, self.kind, self.default).put(
            getattr(settings, head), value)
        return dataclasses.replace(settings, **{head: inner})


KINDS = {"bool": bool, "int": int, "float": float, "str": str}


def exposed(settings_type: type, path: tuple[str, ...] = ()) -> list[Exposed]:
    """Every ``option`` field of ``settings_type`` and of the settings dataclasses nested in it, in field order."""
    found = []
    defaults = settings_type()
    for f in dataclasses.fields(settings_type):
        value = getattr(defaults, f.name)
        if "option" in f.metadata:
            kind = KINDS[f.type] if isinstance(f.type, str) else f.type
            found.append(Exposed(path + (f.name,), f.metadata["option"], kind, value))
        elif dataclasses.is_dataclass(value):
            found += exposed(type(value), path + (f.name,))
    return found


@dataclass(frozen=True)
class Method:
    """One way of placing virtual lights, as the engine, a sequence, the Blender side and the bench use it."""
    name: str  # the identifier: the setting's value, the folder's name, ``--method NAME``
    label: str  # as the render panel shows it
    description: str  # the paper, and what the method is good at (the panel's tooltip)
    place: Callable  # (context, settings) -> (VirtualLights, info)
    settings: type | None = None  # its settings dataclass, a field of ``MethodSettings`` under ``name``
    start: Callable | None = None  # (context, settings) -> state, with ``advance``: a sequence method
    advance: Callable | None = None  # (state, context, settings, motion) -> (VirtualLights, info)
    gather: Callable | None = None  # the method's own gather of sampled lights; None: the summing gather
    gather_samples: Callable | None = None  # (settings, camera_samples) -> sample pairs per pixel, with ``gather``
    # (settings, camera_samples) -> the settings a frame of that many camera samples in all places with (vbnl's
    # automatic light paths made a number); None: the settings as they are
    frame_settings: Callable | None = None
    view_independent: bool = False  # lights that ignore the camera: a frame where only it moved reuses them
    stable_lights: bool = False  # a light keeps its slot (and so its interleaving subset) from frame to frame
    uses_still: bool = False  # draws from the view in the sequence's still scene (a bake finds what moves first)
    reuses_light_paths: bool = False  # its light paths are kept across frames (``MethodSettings.path_reuse``)
    budget: str = "vpls"  # what the bench sweeps: "vpls" (the VPL budget) or "samples" (camera samples)

    def __post_init__(self):
        if (self.start is None) != (self.advance is None):
            raise TypeError(f"method {self.name!r}: a sequence method provides both start and advance")
        if (self.gather is None) != (self.gather_samples is None):
            raise TypeError(f"method {self.name!r}: a sampled gather comes with gather_samples")
        if self.budget not in ("vpls", "samples"):
            raise TypeError(f"method {self.name!r}: budget is 'vpls' or 'samples', not {self.budget!r}")

    @property
    def sequential(self) -> bool:
        return self.start is not None

    @property
    def sums_lights(self) -> bool:
        """Its lights go to the summing gather (``gather.summing``), whose settings then apply."""
        return self.gather is None

    def options(self) -> list[Exposed]:
        """The settings users see, with paths from ``MethodSettings`` (``("vbnl", "photons")``)."""
        return [] if self.settings is None else exposed(self.settings, (self.name,))
