"""Render passes named and defined as Cycles defines them, and the guard that keeps bad numbers out of them.

``Diffuse Direct`` / ``Diffuse Indirect``: light reflected by a white diffuse surface at the primary hit (NOT
multiplied by albedo), per pixel the albedo-weighted mean over its samples (Cycles divides these passes by
``Diffuse Color``: at a pixel on the edge of a wall and the background, or a wall and a metal floor, they hold the
wall's light); ``Diffuse Color``: the albedo; ``Emit``: emitted radiance; ``Combined``: RGBA with alpha the
geometry coverage of a transparent film. ``(Diffuse Direct + Diffuse Indirect) * Diffuse Color + Emit`` is the
diffuse part of ``Combined``. ``Glossy Direct`` / ``Glossy Indirect``: light reflected by the glossy (metallic GGX)
lobe at the primary hit divided by ``Glossy Color``, the lobe's directional albedo as Cycles estimates it, so
``(Glossy Direct + Glossy Indirect) * Glossy Color`` is the glossy part of ``Combined``. ``Environment``: the
world's radiance that camera rays which miss every surface see, times the share of the pixel's samples that miss
(Cycles' background pass, written whether the film is transparent or not). ``Combined`` holds it too, with alpha 1,
unless *Film > Transparent* is on: then its background is 0 and alpha the coverage, as in Cycles. So ``Combined`` is
the sum of the diffuse, glossy and emission parts, plus ``Environment`` when the film is not transparent.
"""
from __future__ import annotations

import numpy as np

COMBINED = "Combined"
DIFFUSE_DIRECT = "Diffuse Direct"
DIFFUSE_INDIRECT = "Diffuse Indirect"
DIFFUSE_COLOR = "Diffuse Color"
EMIT = "Emit"
GLOSSY_DIRECT = "Glossy Direct"
GLOSSY_INDIRECT = "Glossy Indirect"
GLOSSY_COLOR = "Glossy Color"
ENVIRONMENT = "Environment"

CHANNELS = {COMBINED: 4, DIFFUSE_DIRECT: 3, DIFFUSE_INDIRECT: 3, DIFFUSE_COLOR: 3, EMIT: 3,
            GLOSSY_DIRECT: 3, GLOSSY_INDIRECT: 3, GLOSSY_COLOR: 3, ENVIRONMENT: 3}
GLOSSY = (GLOSSY_DIRECT, GLOSSY_INDIRECT, GLOSSY_COLOR)
ALL = tuple(CHANNELS)


class BadOutput(RuntimeError):
    """A pass holds non-finite or negative values: always a bug of the stage named in the message."""


def check(passes: dict[str, np.ndarray], stage: str) -> None:
    """Count non-finite and negative values in every array and fail loudly, naming the array and the stage
    (e.g. ``method 'bidir', stage 'gather'``). Never zeroes anything: a bad value is a bug to fix, not to hide."""
    problems = []
    for name, image in passes.items():
        image = np.asarray(image)
        nonfinite = int((~np.isfinite(image)).sum())
        negative = int((image < 0).sum())
        if nonfinite or negative:
            problems.append(f"{name}: {nonfinite} non-finite, {negative} negative values")
    if problems:
        raise BadOutput(f"{stage}: {'; '.join(problems)}")
