"""Compiled kernels: the hot loops that numpy runs as many passes over temporary arrays, fused into one loop each by
numba's JIT.

Every kernel is ``kernel``-decorated: compiled without the GIL (``nogil``), so the render's blocks, which already
run on all cores (``render``), run their kernels concurrently; no kernel is ``parallel``, since numba's default
threading layer may not be entered from two Python threads at once. Kernels keep numpy's float semantics (no
fastmath): an image must not depend on whether a loop was compiled.

Machine code is cached on disk in the user's cache folder, ``$VPL_GI_CACHE/numba`` (by default under
``~/.cache/vpl_gi``), so only the first render after an install pays for compiling (about a second per kernel),
in a folder per module name (``bl_ext.user_default.vpl_gi.vpl_addon.core.tracer`` in Blender,
``vpl_gi.vpl_addon.core.tracer`` from the command line, ``vpl_addon.core.tracer`` in tests): a cached kernel
imports the module it was compiled in when it is loaded, so one compiled under another name, in another process,
would fail to load. numba's own cache settings (``NUMBA_CACHE_DIR``) are left to other users of numba. Tables that
kernels read and a process would integrate at its first render (the glossy lobes' albedo tables, 0.4 s) are kept
beside them (``kept_tables``).
"""
from __future__ import annotations

import hashlib
import os
import tempfile
import zipfile
from functools import lru_cache
from typing import Callable

import numba
import numpy as np
from numba.core import caching


def cache_root() -> str:
    """The user's cache folder of VPL GI: ``$VPL_GI_CACHE``, by default ~/.cache/vpl_gi."""
    return os.environ.get("VPL_GI_CACHE") or os.path.join(os.path.expanduser("~"), ".cache", "vpl_gi")


def cache_folder() -> str:
    """Where compiled kernels are kept: ``cache_root()/numba``."""
    return os.path.join(cache_root(), "numba")


@lru_cache(maxsize=None)
def _source_hash(path: str) -> str:
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()[:16]


def kept_tables(name: str, source: str, make: Callable[[], tuple[np.ndarray, ...]]) -> tuple[np.ndarray, ...]:
    """``make()``'s arrays, kept on disk in ``cache_root()/tables`` under ``name`` and the hash of the file ``source``
    (the module that makes them: a change to it makes them anew), so that tables a process takes half a second to
    integrate load in a millisecond in the next one (the first render of every Blender session, command-line render
    and farm worker). Written to a file of its own and renamed into place, so processes that make the same tables at
    once never read half a file; a file that cannot be read is made again. The arrays come back bit for bit."""
    path = os.path.join(cache_root(), "tables", f"{name}-{_source_hash(source)}.npz")
    try:
        with np.load(path) as kept:
            return tuple(kept[f"arr_{i}"] for i in range(len(kept.files)))
    except (OSError, ValueError, KeyError, zipfile.BadZipFile, EOFError):
        pass
    arrays = tuple(np.asarray(a) for a in make())
    try:
        os.makedirs(os.path.dirname(path), exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=os.path.dirname(path), suffix=".npz", delete=False) as f:
            np.savez(f, *arrays)
        os.replace(f.name, path)
    except OSError:  # a read-only cache folder: the tables are made in every process, as without a cache
        pass
    return arrays


class _Locator(caching.UserProvidedCacheLocator):
    """numba's locator of a user-given cache folder, with ours and the kernel's module name in place of
    ``NUMBA_CACHE_DIR``."""

    def __init__(self, py_func, py_file):
        super().__init__(py_func, py_file)
        self._cache_path = os.path.join(cache_folder(), py_func.__module__, self.get_suitable_cache_subpath(py_file))

    @classmethod
    def from_function(cls, py_func, py_file):
        return super(caching.UserProvidedCacheLocator, cls).from_function(py_func, py_file)  # any NUMBA_CACHE_DIR


class _Impl(caching.CompileResultCacheImpl):
    _locator_classes = [_Locator]


class _Cache(caching.FunctionCache):
    _impl_class = _Impl


def kernel(function):
    """``function`` compiled by numba: nopython, GIL released, cached in ``cache_folder()``."""
    dispatcher = numba.njit(nogil=True, error_model="numpy")(function)
    dispatcher._cache = _Cache(function)  # what cache=True does (Dispatcher.enable_caching), with our locator
    return dispatcher


def inline(function):
    """``function`` compiled into every kernel that calls it (numba's ``inline="always"``): a small helper of
    kernels. Called as a kernel of its own, it costs a call per use that LLVM does not remove (``sampling.basis``
    in ``cosine_hemisphere``'s loop: 8-12 % of its time); it is not cached apart, its callers are."""
    return numba.njit(nogil=True, error_model="numpy", inline="always")(function)
