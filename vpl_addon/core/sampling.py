"""Warps from uniform random numbers to the distributions the engine samples, vectorized over rows.

Every function takes arrays of uniform numbers in [0,1) and returns samples together with what is needed for the
estimator (a pdf or a frame); they are used by the light sampler, the camera and every method.
"""
from __future__ import annotations

import functools

import numpy as np

from .compiled import inline, kernel


def normalize(v: np.ndarray) -> np.ndarray:
    """Unit vectors along the last axis; zero vectors stay zero instead of becoming NaN."""
    length = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(length > 0.0, length, 1.0)


def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("...i,...i->...", a, b)


def group_sum(index: np.ndarray, values: np.ndarray, count: int) -> np.ndarray:
    """(count, C) sums of the rows of ``values`` (N, C) by their group ``index`` (N,) in [0, count), in float64."""
    out = np.zeros((count, values.shape[1]))
    _add_rows(np.asarray(index, np.int64), np.asarray(values, np.float64), out)
    return out


@kernel
def _add_rows(index, values, out):
    """out[index[i]] += values[i], in the order of i (np.bincount's sums, all channels in one pass)."""
    for i in range(len(index)):
        for c in range(values.shape[1]):
            out[index[i], c] += values[i, c]


def power_heuristic(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Veach's power heuristic: the MIS weight a^2 / (a^2 + b^2) of a sample drawn with pdf a against a strategy
    of pdf b; 0 where both are 0, 1 where a is NaN (a light that cannot say its pdf: nothing to weigh against)."""
    a2, b2 = a * a, b * b
    return np.where(np.isnan(a), 1.0, a2 / np.where(a2 + b2 > 0.0, a2 + b2, 1.0))


def orthonormal_basis(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Tangent vectors (t, b) completing unit normals n to a right-handed frame (Duff et al. 2017)."""
    sign = np.where(n[..., 2] >= 0.0, 1.0, -1.0)
    a = -1.0 / (sign + n[..., 2])
    b = n[..., 0] * n[..., 1] * a
    t = np.stack([1.0 + sign * n[..., 0] ** 2 * a, sign * b, -sign * n[..., 0]], axis=-1)
    s = np.stack([b, sign + n[..., 1] ** 2 * a, -n[..., 1]], axis=-1)
    return t, s


@inline
def basis(n0, n1, n2):
    """``orthonormal_basis`` of one unit normal (n0, n1, n2), in a kernel: (t0, t1, t2, b0, b1, b2)."""
    sign = 1.0 if n2 >= 0.0 else -1.0
    a = -1.0 / (sign + n2)
    b = n0 * n1 * a
    return 1.0 + sign * (n0 * n0) * a, sign * b, -sign * n0, b, sign + (n1 * n1) * a, -n1


def to_world(local: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Rotate directions given in a frame whose z axis is n into world space."""
    t, s = orthonormal_basis(n)
    return local[..., :1] * t + local[..., 1:2] * s + local[..., 2:3] * n


def cosine_hemisphere(u1: np.ndarray, u2: np.ndarray, n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Directions with pdf cos(theta)/pi about the unit normals n (K,3) (Malley's method), from numbers u1, u2 (K,);
    returns (directions, cos theta). ``to_world``'s frame, in one compiled loop."""
    u1, u2 = np.asarray(u1, np.float64), np.asarray(u2, np.float64)
    dirs, cos = np.empty((len(u1), 3)), np.empty(len(u1))
    _cosine_hemisphere(u1, u2, np.asarray(n, np.float64), dirs, cos)
    return dirs, cos


@kernel
def _cosine_hemisphere(u1, u2, n, dirs, cos):
    for i in range(len(u1)):
        r, phi, z = np.sqrt(u1[i]), 2.0 * np.pi * u2[i], np.sqrt(max(0.0, 1.0 - u1[i]))
        x, y = r * np.cos(phi), r * np.sin(phi)
        n0, n1, n2 = n[i, 0], n[i, 1], n[i, 2]
        t0, t1, t2, b0, b1, b2 = basis(n0, n1, n2)
        dirs[i, 0] = x * t0 + y * b0 + z * n0
        dirs[i, 1] = x * t1 + y * b1 + z * n1
        dirs[i, 2] = x * t2 + y * b2 + z * n2
        cos[i] = z


def uniform_sphere(u1: np.ndarray, u2: np.ndarray) -> np.ndarray:
    """Directions uniform over the unit sphere (pdf 1 / (4 pi))."""
    z = 1.0 - 2.0 * u1
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    phi = 2.0 * np.pi * u2
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=-1)


def uniform_cone(u1: np.ndarray, u2: np.ndarray, axis: np.ndarray, cos_max: np.ndarray) -> np.ndarray:
    """Directions uniform in solid angle within the cone of half-angle acos(cos_max) about axis.

    The pdf is 1 / (2 pi (1 - cos_max)).
    """
    cos_t = 1.0 - u1 * (1.0 - cos_max)
    sin_t = np.sqrt(np.maximum(0.0, 1.0 - cos_t * cos_t))
    phi = 2.0 * np.pi * u2
    local = np.stack([sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t], axis=-1)
    return to_world(local, axis)


def concentric_disk(u1: np.ndarray, u2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Uniform points on the unit disk by Shirley and Chiu's concentric map (keeps stratification)."""
    a = 2.0 * u1 - 1.0
    b = 2.0 * u2 - 1.0
    first = np.abs(a) > np.abs(b)
    r = np.where(first, a, b)
    with np.errstate(divide="ignore", invalid="ignore"):
        phi = np.where(first, (np.pi / 4.0) * (b / a), np.pi / 2.0 - (np.pi / 4.0) * (a / b))
    phi = np.nan_to_num(phi)
    return r * np.cos(phi), r * np.sin(phi)


def triangle_barycentrics(u1: np.ndarray, u2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Uniform barycentrics (b1, b2) on a triangle (square-root parametrisation)."""
    su = np.sqrt(u1)
    return su * (1.0 - u2), su * u2


def interpolated(corners: np.ndarray, bary: np.ndarray) -> np.ndarray:
    """(K,C) the per-corner values (K,3,C) at barycentric coordinates (K,3), in float64."""
    return np.einsum("kj,kjc->kc", bary, corners.astype(np.float64))


def sample_cdf(cdf: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Indices drawn from a discrete distribution given by its normalised, non-decreasing CDF."""
    return np.minimum(np.searchsorted(cdf, u, side="right"), len(cdf) - 1)


@functools.cache
def _sobol_net(count: int) -> tuple[np.ndarray, np.ndarray]:
    """The first ``count`` points of ``_sobol_point`` as 32-bit integers (read only)."""
    x, y = np.empty(count, np.uint64), np.empty(count, np.uint64)
    _sobol_points(np.arange(count, dtype=np.uint64), x, y)
    x, y = x.astype(np.uint32), y.astype(np.uint32)
    x.flags.writeable = y.flags.writeable = False
    return x, y


@inline
def _sobol_point(index):
    """The first two dimensions of Sobol's sequence at ``index`` as 32-bit integers: van der Corput (bit reversal)
    and the Pascal-matrix dimension. Any 2^m consecutive-from-zero points form a (0, m, 2)-net."""
    x, y = np.uint64(0), np.uint64(0)
    v = np.uint64(1 << 31)
    for bit in range(32):
        if index >> np.uint64(bit) == 0:
            break
        if (index >> np.uint64(bit)) & np.uint64(1):
            x |= np.uint64(1 << (31 - bit))
            y ^= v
        v ^= v >> np.uint64(1)
    return x, y


@kernel
def _sobol_points(index, x, y):
    """x[i], y[i] = ``_sobol_point(index[i])``."""
    for i in range(len(index)):
        x[i], y[i] = _sobol_point(index[i])


def stratified_2d(count: int, per_cell: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """``per_cell`` 2D points for each of ``count`` cells (pixels), shape (count, per_cell).

    A power of two gives the first points of the 2D Sobol sequence, randomised per pixel by a random digital
    shift (XOR): a (0, m, 2)-net, so every elementary box of area 1 / per_cell (8x8, 4x16, 64x1, ...) holds one
    point, which keeps anti-aliasing error low on edges of every direction (Cycles' samplers are of this kind).
    Any leading 2^j points of a pixel are a net too. Otherwise the points are independent uniform ones.
    """
    if per_cell & (per_cell - 1):
        return rng.random((count, per_cell)), rng.random((count, per_cell))
    return _shifted(_sobol_net(per_cell), count, per_cell, rng)


def stratified_4d(count: int, per_cell: int, rng: np.random.Generator) -> tuple[np.ndarray, ...]:
    """(x, y, u, v), each (count, per_cell): ``stratified_2d``'s points in four dimensions, the first four of Sobol's
    sequence (Joe and Kuo's directions, scipy's ``qmc.Sobol``) shifted per cell, so that the pairs (x, y) and (u, v)
    are each a net and together a 4D net: a pixel's filter positions and lens points (depth of field) are stratified
    jointly, as by Cycles' tabulated Sobol sampler. Two independent 2D nets at the same sample index, by contrast,
    repeat one point set under two shifts (a lens point then follows from its filter position). Otherwise the
    points are independent uniform ones."""
    if per_cell & (per_cell - 1):
        return tuple(rng.random((count, per_cell)) for _ in range(4))
    return _shifted(_sobol_net_4d(per_cell), count, per_cell, rng)


def _shifted(net, count: int, per_cell: int, rng: np.random.Generator) -> tuple[np.ndarray, ...]:
    """Each dimension of ``net`` (its 32-bit integer points) as (count, per_cell) numbers in [0, 1): the net
    XOR-shifted by a random 32-bit number per cell and dimension (a random digital shift keeps it a net), the bits
    below 32 filled at random."""
    shift = rng.integers(0, 1 << 32, (count, len(net)), dtype=np.uint64).astype(np.uint32)
    scale = 1.0 / 4294967296.0
    jitter = rng.random((count, per_cell, len(net)))  # fills the bits below 32
    return tuple((net[d] ^ shift[:, d:d + 1]) * scale + jitter[..., d] * scale for d in range(len(net)))


@functools.cache
def _sobol_net_4d(count: int) -> np.ndarray:
    """(4, count) the first ``count`` (a power of two) points of the 4D Sobol sequence as 32-bit integers (read
    only), in scipy's Gray-code order: any leading 2^j of them are the first 2^j points of the sequence."""
    from scipy.stats import qmc
    points = qmc.Sobol(d=4, scramble=False, bits=32).random_base2(count.bit_length() - 1)
    net = np.ascontiguousarray((points * 4294967296.0).astype(np.uint32).T)
    net.flags.writeable = False
    return net


def pixel_nets(pixel: np.ndarray, per_row: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(u, v), each (R, per_row): 2D numbers for R rows (sample points) of the pixels ``pixel`` (R,). The rows of a
    pixel share one scrambled Sobol net (``stratified_2d``) of the next power of two at or above the most numbers a
    pixel asks for, dealt to them in random order: a pixel's numbers cover the square evenly, while a row's numbers,
    and the numbers of two nets drawn for the same rows, stay independent of each other (Cycles pads its dimensions
    in pairs the same way). A pixel with fewer rows takes a random part of its net."""
    return _dealt(_ranks(pixel), per_row, rng)


def _ranks(pixel: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """(group, rank, groups): each row's pixel numbered 0, 1, ... and its place among that pixel's rows."""
    order = None if np.all(pixel[1:] >= pixel[:-1]) else np.argsort(pixel, kind="stable")
    ordered = pixel if order is None else pixel[order]
    first = np.flatnonzero(np.r_[True, ordered[1:] != ordered[:-1]]) if len(pixel) else np.zeros(0, np.int64)
    sizes = np.diff(np.r_[first, len(pixel)])
    group = np.repeat(np.arange(len(first)), sizes)
    rank = np.arange(len(pixel)) - np.repeat(first, sizes)
    if order is not None:
        group[order], rank[order] = group.copy(), rank.copy()
    return group, rank, len(first)


def _dealt(ranks: tuple[np.ndarray, np.ndarray, int], per_row: int, rng: np.random.Generator):
    """``pixel_nets`` of rows numbered by ``_ranks``."""
    group, rank, groups = ranks
    if len(rank) == 0:
        return np.zeros((0, per_row)), np.zeros((0, per_row))
    count = 1 << int(rank.max() * per_row + per_row - 1).bit_length()
    u, v = stratified_2d(groups, count, rng)
    deal = rng.permuted(np.broadcast_to(np.arange(count), u.shape), axis=1)
    dealt = deal[group[:, None], rank[:, None] * per_row + np.arange(per_row)]
    return u[group[:, None], dealt], v[group[:, None], dealt]


class LatinHypercube:
    """A stand-in for ``np.random.Generator.random`` whose every call of n numbers puts one in each of n equal
    strata (in random order): Latin hypercube sampling across the rows of a batch. Light paths drawn with it
    cover the lights' positions and directions evenly, which steadies the total energy of a VPL set (Keller's
    Instant Radiosity used quasi-random numbers for the same reason)."""

    def __init__(self, rng: np.random.Generator):
        self.rng = rng

    def random(self, count) -> np.ndarray:
        if np.ndim(count):
            return self.rng.random(count)
        return (self.rng.permutation(count) + self.rng.random(count)) / max(count, 1)


class PathNumbers:
    """Uniform numbers of camera paths keyed by what they are for, not by when they are drawn: the numbers of a
    path's vertex (its ``branch`` at ``depth``, where a path may branch into a diffuse and a metallic vertex) for a
    ``stream`` of its sampling decisions depend on the block's key, the path's pixel and its slot among that pixel's
    paths, and nothing else.

    A generator's numbers depend on every draw before them: one path more or fewer at a vertex (a Russian roulette
    decision that a 0.1 % change of a light's intensity flips) gives every later vertex of the block other numbers,
    and a render of a slightly changed scene a new draw of its noise (a frame of a sequence). Keyed
    numbers keep the noise of every other path where it was, as Cycles' do (a pixel's numbers are a hash of the
    pixel, the sample and the dimension).

    Stratification is ``pixel_nets``': each (pixel, branch, depth, stream, pair of dimensions) has a 2D Sobol net of
    as many points as the pixel has paths (the next power of two), digitally shifted by a hash, and a path takes the
    point of its slot under a hashed permutation (different for every pair, so a path's pairs stay independent)."""

    def __init__(self, pixel: np.ndarray, rng: np.random.Generator):
        _, self.slot, _ = _ranks(pixel)
        self.pixel = np.asarray(pixel, np.int64)
        self.mask = (1 << int(self.slot.max(initial=0)).bit_length()) - 1
        self.key = int(rng.integers(1 << 63))

    def numbers(self, count: int, owner: np.ndarray, branch: np.ndarray, depth: int, stream: int) -> np.ndarray:
        """(count, R) numbers for the vertices ``branch`` (R,) of the paths ``owner`` (R,) at ``depth``."""
        out = np.empty((count + (count & 1), len(owner)))
        _keyed_nets(np.uint64(self.key), self.pixel, self.slot, np.uint64(self.mask), owner,
                    np.broadcast_to(np.asarray(branch, np.int64), np.shape(owner)), depth, stream, out)
        return out[:count]

    def independent(self, count: int, owner: np.ndarray, branch: np.ndarray, depth: int, stream: int) -> np.ndarray:
        """(count, R) numbers keyed as ``numbers``', each independent of the others (no nets: a third of the
        cost, for draws a net would not help, such as the levels of a tree descended one number a level)."""
        out = np.empty((count + (count & 1), len(owner)))
        _keyed_independent(np.uint64(self.key), self.pixel, self.slot, owner,
                           np.broadcast_to(np.asarray(branch, np.int64), np.shape(owner)), depth, stream, out)
        return out[:count]

    def generator(self, depth: int) -> np.random.Generator:
        """A generator for the draws at ``depth`` that are not keyed: its numbers do not depend on other depths'."""
        return np.random.default_rng([self.key, depth])


@inline
def mix64(z):
    """A 64-bit integer hash, bijective (the finaliser of Steele et al.'s SplitMix64); compiled into the kernels that
    call it."""
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


@inline
def _permuted(x, mask, h):
    """x in [0, mask] moved by a bijection of [0, mask] chosen by the hash h: odd multiplications, additions and
    xor-shifts, each invertible modulo a power of two."""
    for r in range(3):
        x = (x * ((h >> np.uint64(20 * r)) | np.uint64(1)) + (h >> np.uint64(20 * r + 7))) & mask
        x = x ^ (x >> np.uint64(1 + r))
    return x


@inline
def _vertex_key(key, pixel, branch, depth, stream):
    """The hash of a (pixel, branch, depth, stream) under the block's key."""
    vertex = mix64(np.uint64(branch) * np.uint64(0x9E3779B97F4A7C15) + np.uint64(depth * 4096 + stream))
    return mix64(key ^ mix64(np.uint64(pixel) * np.uint64(0xD6E8FEB86659FD93) ^ vertex))


@kernel
def _keyed_independent(key, pixel, slot, owner, branch, depth, stream, out):
    """``PathNumbers.independent`` into ``out`` (2 x pairs, R): two 32-bit numbers from each hash."""
    scale = 1.0 / 4294967296.0
    for i in range(len(owner)):
        o = owner[i]
        row = _vertex_key(key, pixel[o], branch[i], depth, stream)
        row ^= np.uint64(slot[o]) * np.uint64(0xA0761D6478BD642F)
        for pair in range(out.shape[0] // 2):
            z = mix64(row + np.uint64(pair + 1) * np.uint64(0xE7037ED1A0B428DB))
            out[2 * pair, i] = (z >> np.uint64(32)) * scale
            out[2 * pair + 1, i] = (z & np.uint64(0xFFFFFFFF)) * scale


@kernel
def _keyed_nets(key, pixel, slot, mask, owner, branch, depth, stream, out):
    """``PathNumbers.numbers`` into ``out`` (2 x pairs, R)."""
    scale = 1.0 / 4294967296.0
    low = np.uint64(0xFFFFFFFF)
    for i in range(len(owner)):
        o = owner[i]
        row = _vertex_key(key, pixel[o], branch[i], depth, stream)
        for pair in range(out.shape[0] // 2):
            h = mix64(row + np.uint64(pair) * np.uint64(0xD1B54A32D192ED03))
            x, y = _sobol_point(_permuted(np.uint64(slot[o]), mask, h))
            shift = mix64(h ^ np.uint64(0x632BE59BD9B4E019))
            jitter = mix64(shift + np.uint64(slot[o]) + np.uint64(1))
            out[2 * pair, i] = ((x ^ (shift & low)) + (jitter & low) * scale) * scale
            out[2 * pair + 1, i] = ((y ^ (shift >> np.uint64(32))) + (jitter >> np.uint64(32)) * scale) * scale
