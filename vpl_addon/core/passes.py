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

The data passes describe what the camera sees, not light (``paths.data_passes``, with Cycles' meanings): ``Depth``
(distance along the view axis, 1e10 where the pixel's first sample misses), ``Mist``, ``Normal``, ``Position``,
``Ambient Occlusion``, ``Object Index``, ``Material Index`` and the Cryptomatte passes ``CryptoObject00``,
``CryptoMaterial00``, ``CryptoAsset00``... (two id-coverage ranks per RGBA pass, ``core.cryptomatte``). Cycles'
Denoising Data: ``Denoising Albedo`` (Diffuse Color + Glossy Color + Emit, and the world where the camera sees
it unless the film is transparent: OIDN then keeps an emitter's or the sky's edges), ``Denoising Normal`` (Normal in
camera space: x right, y up, z forward) and, when the picture is denoised (``core.denoise``), ``Noisy Image``:
Combined before.
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
DEPTH = "Depth"
MIST = "Mist"
NORMAL = "Normal"
POSITION = "Position"
AO = "Ambient Occlusion"
OBJECT_INDEX = "Object Index"
MATERIAL_INDEX = "Material Index"
# Cycles' Denoising Data: the denoiser's guides, and Combined before denoising
DENOISING_ALBEDO = "Denoising Albedo"
DENOISING_NORMAL = "Denoising Normal"
NOISY_IMAGE = "Noisy Image"
# Cryptomatte: a kind's passes are its name and a two-digit number (CryptoObject00, CryptoObject01, ...)
CRYPTOMATTE = ("CryptoObject", "CryptoMaterial", "CryptoAsset")
CRYPTOMATTE_PASSES = 8  # Blender's 16 levels at most, two per pass

CHANNELS = {COMBINED: 4, DIFFUSE_DIRECT: 3, DIFFUSE_INDIRECT: 3, DIFFUSE_COLOR: 3, EMIT: 3,
            GLOSSY_DIRECT: 3, GLOSSY_INDIRECT: 3, GLOSSY_COLOR: 3, ENVIRONMENT: 3}
GLOSSY = (GLOSSY_DIRECT, GLOSSY_INDIRECT, GLOSSY_COLOR)
ALL = tuple(CHANNELS)  # the passes of light and colour
DATA = (DEPTH, MIST, NORMAL, POSITION, AO, OBJECT_INDEX, MATERIAL_INDEX)
DENOISING = (DENOISING_ALBEDO, DENOISING_NORMAL, NOISY_IMAGE)
CHANNELS.update({DEPTH: 1, MIST: 1, NORMAL: 3, POSITION: 3, AO: 3, OBJECT_INDEX: 1, MATERIAL_INDEX: 1,
                 DENOISING_ALBEDO: 3, DENOISING_NORMAL: 3, NOISY_IMAGE: 4})
CHANNELS.update({f"{kind}{number:02d}": 4 for kind in CRYPTOMATTE for number in range(CRYPTOMATTE_PASSES)})
# passes whose values may be negative (coordinates, and Cryptomatte ids, which are hashes read as floats)
SIGNED = {NORMAL, POSITION, DENOISING_NORMAL} | {name for name in CHANNELS if name.startswith(CRYPTOMATTE)}


def divide(light: np.ndarray, color: np.ndarray) -> np.ndarray:
    """Light over colour per channel, zero where the colour is (Cycles' pass division: a light pass is the light a
    pixel's samples reflect over the colour they reflect it with)."""
    return np.where(color > 0.0, light / np.where(color > 0.0, color, 1.0), 0.0)


def cryptomatte_passes(kind: str, levels: int) -> tuple[str, ...]:
    """The pass names that hold ``levels`` ranks of a Cryptomatte kind, as Blender names them."""
    return tuple(f"{kind}{number:02d}" for number in range(min(-(-levels // 2), CRYPTOMATTE_PASSES)))


class BadOutput(RuntimeError):
    """A pass holds non-finite or negative values: always a bug of the stage named in the message."""


def check(passes: dict[str, np.ndarray], stage: str) -> None:
    """Count non-finite and negative values (but in ``SIGNED`` passes) in every array and fail loudly, naming the
    array and the stage (e.g. ``method 'bidir', stage 'gather'``). Never zeroes anything: a bad value is a bug to fix,
    not to hide."""
    problems = []
    for name, image in passes.items():
        image = np.asarray(image)
        nonfinite = int((~np.isfinite(image)).sum())
        negative = 0 if name in SIGNED else int((image < 0).sum())
        if nonfinite or negative:
            problems.append(f"{name}: {nonfinite} non-finite, {negative} negative values")
    if problems:
        raise BadOutput(f"{stage}: {'; '.join(problems)}")
