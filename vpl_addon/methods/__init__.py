"""Methods that place virtual lights: one subpackage per paper holding the modules only it uses, one interface.
May import every layer below (a method's sequence hooks use ``sequence``), never another method, ``render``
or Blender's side.

``place(context, settings) -> (VirtualLights, info)`` where ``context`` carries the scene, tracer, lights,
bounce limit and random generator, and ``info`` is a dict of figures worth reporting (paths traced, shares...).
Lights that are summed (VPLs) go to the one interleaved ``gather``; a method whose lights are sampled instead
(``vbnl``'s photon lights) brings its own ``gather(surface, lights, context, settings, rng)`` and
``gather_samples(settings, camera_samples)``, the sample pairs per pixel."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from . import bidir, ir, smc, vbnl

METHODS = {"ir": ir, "bidir": bidir, "vbnl": vbnl, "smc": smc}


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


@dataclass
class MethodSettings:
    vpls: int = 4096  # VPL budget: the number of lights the gather sees (bidir: kept after resampling)
    bidir: bidir.BidirSettings = field(default_factory=bidir.BidirSettings)
    vbnl: vbnl.VBNLSettings = field(default_factory=vbnl.VBNLSettings)
    smc: smc.SMCSettings = field(default_factory=smc.SMCSettings)
    # in a sequence, keep ir's and bidir's light paths between frames and re-trace only those that moved objects
    # cut or moved lights carry (Moreau et al.)
    path_reuse: bool = True
    # T of eq. 2 (Moreau et al. sec. 3.3): a moved segment whose new end reflects within T of its old energy keeps
    # the rest of its path (the paper's 0.1 %); 0 re-traces every moved segment
    path_threshold: float = 1e-3


def place(name: str, context: MethodContext, settings: MethodSettings):
    if name not in METHODS:
        raise ValueError(f"unknown method {name!r}; choose one of {', '.join(METHODS)}")
    return METHODS[name].place(context, settings)
