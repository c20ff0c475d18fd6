"""Methods that place virtual lights: one module per paper, one interface.

``place(context, settings) -> (VirtualLights, info)`` where ``context`` carries the scene, tracer, lights,
bounce limit and random generator, and ``info`` is a dict of figures worth reporting (paths traced, shares...).
The gather consumes the lights the same way whatever placed them."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import bidir, ir

METHODS = {"ir": ir, "bidir": bidir}


@dataclass
class MethodContext:
    scene: object
    tracer: object
    lights: object  # LightSet
    rng: np.random.Generator
    max_bounces: int


@dataclass
class MethodSettings:
    vpls: int = 4096  # VPL budget: the number of lights the gather sees (bidir: kept after resampling)
    bidir: bidir.BidirSettings = field(default_factory=bidir.BidirSettings)


def place(name: str, context: MethodContext, settings: MethodSettings):
    if name not in METHODS:
        raise ValueError(f"unknown method {name!r}; choose one of {', '.join(METHODS)}")
    return METHODS[name].place(context, settings)
