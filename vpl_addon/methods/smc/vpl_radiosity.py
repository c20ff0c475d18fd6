"""The radiosity of a VPL from a path tracer with next-event estimation, seeded per VPL (Hedman, Karras, Lehtinen,
Sequential Monte Carlo Instant Radiosity, sec. 3.2.3: "16 samples from a path tracer with next event estimation
[...] we make sure that the path tracer generates similar paths for the same VPL throughout the lifetime of the
VPL [...] by initializing the pseudo-random number used by path tracer with a VPL-specific seed").

Each VPL y draws every random number of its paths from its own counter-based stream (a hash of its seed), in a fixed
layout per (sample, vertex), so re-estimating an unchanged VPL in an unchanged scene gives the same value and a moving
light changes it smoothly (a compiled kernel hashes, vertex by vertex, the numbers of the paths still alive). Paths
use the engine's one light sampler at every vertex (``lights.direct``, its diffuse part) and its one diffuse bounce
(``materials.surface``), fed the VPL's numbers through ``PresetNumbers``; they end at the scene's bounce limit (the
VPL is the first diffuse vertex) or by Russian roulette on the albedo. The result is the VPL's outgoing radiance
Lo(y) = albedo / pi * irradiance, per RGB channel.
"""
from __future__ import annotations

import numpy as np

from ...core.color import largest
from ...core.compiled import kernel
from ...core.sampling import mix64
from ...lights.direct import direct_light
from ...materials.surface import Surface, diffuse_bounce

NUMBERS_PER_VERTEX = 8  # light choice, two for a local light, two for the world, two for the bounce, roulette


class PresetNumbers:
    """A stand-in for ``np.random.Generator.random`` that hands out prepared columns in order, so a batched
    computation uses each row's own numbers."""

    def __init__(self, columns: list[np.ndarray]):
        self.columns = list(columns)

    def random(self, count) -> np.ndarray:
        column = self.columns.pop(0)
        if len(column) != count:
            raise ValueError(f"asked for {count} numbers, prepared {len(column)}")
        return column


# the hash's odd multipliers: of the VPL's seed, of the stream, the offset, of the position in the row
_GOLDEN, _SEED_MIX = np.uint64(0x9E3779B97F4A7C15), np.uint64(0xC2B2AE3D27D4EB4F)
_OFFSET, _COUNTER = np.uint64(0x632BE59BD9B4E019), np.uint64(0xD1B54A32D192ED03)


@kernel
def _vertex_numbers(seeds, vpl, sample, depth, vertices, seed):
    """(len(vpl), NUMBERS_PER_VERTEX): the numbers of vertex ``depth`` of path sample[i] of the VPL vpl[i]."""
    out = np.empty((len(vpl), NUMBERS_PER_VERTEX))
    salt = np.uint64(seed & 0xFFFFFFFF) * _SEED_MIX + _OFFSET
    for i in range(len(vpl)):
        key = mix64(np.uint64(seeds[vpl[i]]) * _GOLDEN + salt)
        first = (sample[i] * vertices + depth) * NUMBERS_PER_VERTEX
        for j in range(NUMBERS_PER_VERTEX):
            bits = mix64(key + np.uint64(first + j) * _COUNTER)
            out[i, j] = np.float64(bits >> np.uint64(11)) * (1.0 / 9007199254740992.0)
    return out


def vertex_numbers(seeds: np.ndarray, vpl: np.ndarray, sample: np.ndarray, depth: int, vertices: int,
                   seed: int = 0) -> np.ndarray:
    """The row of ``vpl_numbers`` for (vpl[i], sample[i], depth), computed for these rows only."""
    return _vertex_numbers(np.asarray(seeds, np.int64), np.asarray(vpl, np.int64), np.asarray(sample, np.int64),
                           int(depth), int(vertices), int(seed))


def vpl_numbers(seeds: np.ndarray, samples: int, vertices: int, seed: int = 0) -> np.ndarray:
    """(N, samples, vertices, NUMBERS_PER_VERTEX) uniform numbers in [0, 1); row i depends on ``seeds[i]`` (and
    ``seed``) alone: a counter-based generator, the SplitMix64 hash of (seed, VPL seed, position in the row)."""
    n = len(seeds)
    vpl, sample = np.repeat(np.arange(n), samples), np.tile(np.arange(samples), n)
    return np.stack([vertex_numbers(seeds, vpl, sample, d, vertices, seed) for d in range(vertices)], axis=1).reshape(
        n, samples, vertices, NUMBERS_PER_VERTEX)


def estimate_radiosity(scene, tracer, lights, surface: Surface, seeds: np.ndarray, samples: int,
                       max_bounces: int, seed: int = 0) -> np.ndarray:
    """(N,3) outgoing radiance of the diffuse points ``surface`` (the VPLs), ``samples`` paths each, paths of at
    most ``max_bounces`` diffuse vertices counting the VPL."""
    n = len(surface)
    if n == 0 or len(lights) == 0 or max_bounces < 1 or samples < 1:
        return np.zeros((n, 3))
    owner = np.repeat(np.arange(n), samples)
    sample = np.tile(np.arange(samples), n)
    current = surface.take(owner)
    throughput = np.ones((len(owner), 3))
    total = np.zeros((len(owner), 3))
    rows = np.arange(len(owner))  # the paths still alive, index into owner
    for depth in range(max_bounces):
        u = vertex_numbers(seeds, owner[rows], sample[rows], depth, max_bounces, seed)  # (k, NUMBERS_PER_VERTEX)
        choice = [u[:, 0]] if lights.local else []
        direct = direct_light(current, lights, tracer, 1, PresetNumbers(choice),
                              numbers=tuple(u[:, i:i + 1] for i in (1, 2, 3, 4)))[0]
        weight = throughput[rows] if depth == 0 else throughput[rows] * current.albedo
        total[rows] += weight * direct
        if depth == max_bounces - 1:
            break
        throughput[rows] = weight
        if depth >= 1:  # Russian roulette on the albedo the path just met
            survive = np.clip(largest(current.albedo), 0.0, 1.0)
            keep = u[:, 7] < survive
            throughput[rows[keep]] /= survive[keep, None]
            rows, current, u = rows[keep], current.take(np.nonzero(keep)[0]), u[keep]
        if len(rows) == 0:
            break
        hit, source, _, _ = diffuse_bounce(scene, tracer, current, PresetNumbers([u[:, 5], u[:, 6]]))
        rows, current = rows[source], hit
        if len(rows) == 0:
            break
    estimate = np.zeros((n, 3))
    np.add.at(estimate, owner, total)
    return estimate / samples * surface.albedo
