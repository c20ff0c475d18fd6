"""Cryptomatte (Friedman and Jones, "Fully Automatic ID Mattes with Support for Motion Blur and Transparency",
Psyop 2015; the specification Cycles follows): each pixel lists the ids of the names its samples see with the share
of its samples (coverage) each has, largest first, as (id, coverage) pairs, two per RGBA pass.

An id is the 32-bit MurmurHash3 (x86, seed 0) of the name's UTF-8 bytes, stored as the float with those bits, its
exponent kept off 0 and 255 so that it is never a denormal, an infinity or a NaN ("uint32_to_float32"). The file
carries a manifest per kind, name -> hash in hex, under ``cryptomatte/<key>/`` with ``key`` the first seven hex digits
of the hash of the kind's layer name (``ViewLayer.CryptoObject``).
"""
from __future__ import annotations

import functools
import json

import numpy as np

MASK = 0xFFFFFFFF


def _rotated(x: int, bits: int) -> int:
    return ((x << bits) | (x >> (32 - bits))) & MASK


def _scrambled(k: int) -> int:
    return (_rotated(k * 0xCC9E2D51 & MASK, 15) * 0x1B873593) & MASK


def murmur3_32(data: bytes, seed: int = 0) -> int:
    """MurmurHash3_x86_32 of ``data``."""
    h = seed
    body = len(data) - len(data) % 4
    for start in range(0, body, 4):
        h = (_rotated(h ^ _scrambled(int.from_bytes(data[start:start + 4], "little")), 13) * 5 + 0xE6546B64) & MASK
    if body < len(data):
        h ^= _scrambled(int.from_bytes(data[body:], "little"))
    h ^= len(data)
    for shift, factor in ((16, 0x85EBCA6B), (13, 0xC2B2AE35)):
        h = ((h ^ (h >> shift)) * factor) & MASK
    return h ^ (h >> 16)


@functools.lru_cache(maxsize=65536)
def name_hash(name: str) -> int:
    """The name's hash, computed once: every block of every frame asks again for the same names."""
    return murmur3_32(name.encode("utf-8"))


def ids(names: list[str]) -> np.ndarray:
    """(N,) float32 Cryptomatte ids of ``names``."""
    bits = np.array([name_hash(n) for n in names], np.uint32).reshape(-1)
    exponent = np.clip((bits >> 23) & 0xFF, 1, 254)
    return ((bits & 0x807FFFFF) | (exponent << 23)).astype(np.uint32).view(np.float32)


def header(layer_pass: str, names: list[str]) -> dict[str, str]:
    """The metadata of one kind's passes (``layer_pass``: e.g. ``ViewLayer.CryptoObject``) naming ``names``."""
    key = f"cryptomatte/{name_hash(layer_pass):08x}"[:len("cryptomatte/") + 7]
    manifest = {name: f"{name_hash(name):08x}" for name in dict.fromkeys(names)}
    return {f"{key}/name": layer_pass, f"{key}/hash": "MurmurHash3_32", f"{key}/conversion": "uint32_to_float32",
            f"{key}/manifest": json.dumps(manifest, separators=(",", ":"))}


def ranked(pixel: np.ndarray, item: np.ndarray, weight: float, pixels: int, levels: int,
           id_of: np.ndarray) -> np.ndarray:
    """(pixels, 2 x levels) (id, coverage) pairs, largest coverage first, from samples that each see ``item`` (an
    index into ``id_of``) in ``pixel`` with coverage ``weight``; ranks a pixel lacks are (0, 0)."""
    out = np.zeros((pixels, 2 * levels), np.float64)
    if len(pixel) == 0 or levels < 1:
        return out
    key = np.asarray(pixel, np.int64) * len(id_of) + item
    unique, count = np.unique(key, return_counts=True)
    at, which = unique // len(id_of), unique % len(id_of)
    order = np.lexsort((which, -count, at))  # by pixel, then coverage falling (ties by index, so deterministic)
    at, which, count = at[order], which[order], count[order]
    rank = np.arange(len(at)) - np.searchsorted(at, at)
    keep = rank < levels
    out[at[keep], 2 * rank[keep]] = id_of[which[keep]]
    out[at[keep], 2 * rank[keep] + 1] = count[keep] * weight
    return out
