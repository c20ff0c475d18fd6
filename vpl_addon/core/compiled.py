"""Compiled kernels: the hot loops that numpy runs as many passes over temporary arrays, fused into one loop each by
numba's JIT (issue 26).

Every kernel is ``kernel``-decorated: compiled without the GIL (``nogil``), so the render's blocks, which already
run on all cores (``render``), run their kernels concurrently; no kernel is ``parallel``, since numba's default
threading layer may not be entered from two Python threads at once. Machine code is cached on disk, in the user's
cache folder (``$VPL_GI_CACHE/numba/<the engine's import name>``, by default under ``~/.cache/vpl_gi``) unless numba
was pointed elsewhere (``NUMBA_CACHE_DIR``) or imported before this module, so only the first render after an install
pays for compiling (about a second per kernel). A folder per import name (``bl_ext.user_default.vpl_gi.vpl_addon`` in
Blender, ``vpl_gi.vpl_addon`` from the command line, ``vpl_addon`` in tests): a cached kernel names the module it
came from, which must import in the process that loads it. Kernels keep numpy's float semantics (no fastmath): an image must not depend on
whether a loop was compiled.
"""
from __future__ import annotations

import os


def cache_folder() -> str:
    """Where compiled kernels are kept: ``$VPL_GI_CACHE/numba``, by default under ~/.cache/vpl_gi."""
    root = os.environ.get("VPL_GI_CACHE") or os.path.join(os.path.expanduser("~"), ".cache", "vpl_gi")
    return os.path.join(root, "numba")


os.environ.setdefault("NUMBA_CACHE_DIR", os.path.join(cache_folder(), __name__.rpartition(".core.")[0]))

import numba  # noqa: E402  (reads NUMBA_CACHE_DIR when first imported)


def kernel(function):
    """``function`` compiled by numba: nopython, GIL released, cached on disk."""
    return numba.njit(nogil=True, cache=True, error_model="numpy")(function)
