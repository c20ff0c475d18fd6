"""Lightmaps: the light of every baked object's texels from one set of virtual lights, in the meanings of Cycles'
bake types. Above ``render`` (whose pass division it shares); nothing below imports it.

``bake.bake`` is the entry: a ``core.scene.Scene``, the names of the objects to bake and ``LightmapSettings`` in,
one (size, size, 4) image per object out (``LightmapResult``).
"""
from .bake import BAKE_PASSES, Cancelled, LightmapResult, LightmapSettings, bake

__all__ = ["BAKE_PASSES", "Cancelled", "LightmapResult", "LightmapSettings", "bake"]
