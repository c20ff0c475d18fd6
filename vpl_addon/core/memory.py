"""The process's memory as the system sees it, and handing back what the engine freed.

A render allocates and frees gigabytes of numpy arrays, many too small for their own mapping, so glibc serves them
from its heap arenas (one per thread that allocated) and keeps them there when they are freed. In a long-lived
process that heap stays resident: Blender rendering the corridor with ``vbnl`` six times holds 3.0 GB afterwards
(0.4 GB before the first render) when the heap is kept, and 0.5 GB when it is handed back after each render.

While a render runs the opposite holds: what it frees it soon needs again, and every page glibc hands back to the
system faults in again, zeroed by the kernel, when the next block asks for it. ``render_heap`` keeps the heap for
the render's length and hands it back at its end.
"""
from __future__ import annotations

import ctypes
import os
import threading
from contextlib import contextmanager


def trim_heap() -> None:
    """Return the freed heap to the system where the C library can (glibc's ``malloc_trim``; elsewhere nothing)."""
    try:
        ctypes.CDLL(None).malloc_trim(0)
    except (AttributeError, OSError, TypeError):  # not glibc (no symbol, or no process handle on Windows)
        pass


def status_kb(key: str) -> int:
    """A size line of ``/proc/self/status`` in kB (``VmRSS``: resident now, ``VmHWM``: its peak); OSError
    where there is no such file or line."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(key + ":"):
                return int(line.split()[1])
    raise OSError(f"{key} not in /proc/self/status")


M_TRIM_THRESHOLD, M_TOP_PAD, M_MMAP_THRESHOLD = -1, -2, -3  # glibc's mallopt parameters
MMAP_THRESHOLD = 32 << 20  # glibc's largest dynamic mmap threshold on 64-bit systems
TRIM_THRESHOLD = 2 * MMAP_THRESHOLD  # what glibc's dynamic threshold sets beside it
TOP_PAD = 128 << 10  # glibc's default
# during a render (``render_heap``): arrays up to 64 MB from the heap, nothing handed back below 1 GB free, the heap
# grown 64 MB at a time
RENDER_HEAP = {M_MMAP_THRESHOLD: 64 << 20, M_TRIM_THRESHOLD: 1 << 30, M_TOP_PAD: 64 << 20}
AFTER_RENDERS = {M_MMAP_THRESHOLD: MMAP_THRESHOLD, M_TRIM_THRESHOLD: TRIM_THRESHOLD, M_TOP_PAD: TOP_PAD}

_renders = [0]  # renders inside ``render_heap`` now, under ``_renders_lock``
_renders_lock = threading.Lock()


def _mallopt(values: dict[int, int]) -> bool:
    """glibc's ``mallopt`` of each parameter; False where the C library is not glibc."""
    try:
        libc = ctypes.CDLL(None)
        return all(libc.mallopt(key, value) for key, value in values.items())
    except (AttributeError, OSError, TypeError):  # not glibc
        return False


@contextmanager
def render_heap():
    """The C library keeps what a render frees for the render's length (``RENDER_HEAP``): glibc's own thresholds
    (an mmap threshold that grows to at most 32 MB, a heap trimmed above twice that) map a block's larger arrays
    afresh and hand back the heap's top between blocks, so its pages fault in again and the kernel zeroes them (a
    256 x 256 vbnl render of the Cornell box: 395 K page faults, 1.6-1.9 s of its 9-10 CPU seconds in the kernel;
    with the heap kept 170 K, 0.8-1.1 s). When the last of the renders running at once ends, the thresholds go
    where glibc's dynamic ones end up for large arrays (``AFTER_RENDERS``, as ``heap_for_renders``) and the freed
    heap goes back to the system (``trim_heap``)."""
    with _renders_lock:
        _renders[0] += 1
        if _renders[0] == 1:
            _mallopt(RENDER_HEAP)
    try:
        yield
    finally:
        with _renders_lock:
            _renders[0] -= 1
            if _renders[0] == 0:
                _mallopt(AFTER_RENDERS)
                trim_heap()


def heap_for_renders() -> bool:
    """Undo a small fixed trim threshold (``MALLOC_TRIM_THRESHOLD_`` in the environment, which Dask's nanny sets to
    64 KiB for its workers): with it glibc maps every array of 128 KiB or more afresh and returns it on free, and the
    page faults make a bake of ``seq_moving_object`` (24 frames at 128 px, ir with 16,384 VPLs) take 58.5 s instead
    of 33 s. Setting the variable also stops glibc's dynamic thresholds, so this sets them where those end up for
    large arrays. Returns whether it changed anything (glibc only, and only when the variable is set)."""
    if "MALLOC_TRIM_THRESHOLD_" not in os.environ:
        return False
    return _mallopt(AFTER_RENDERS)
