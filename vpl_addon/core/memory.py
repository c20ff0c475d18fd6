"""The process's memory as the system sees it, and handing back what the engine freed.

A render allocates and frees gigabytes of numpy arrays, many too small for their own mapping, so glibc serves them
from its heap arenas (one per thread that allocated) and keeps them there when they are freed. In a long-lived
process that heap stays resident: Blender rendering the corridor with ``vbnl`` six times holds 3.0 GB afterwards
(0.4 GB before the first render) when the heap is kept, and 0.5 GB when it is handed back after each render."""
from __future__ import annotations

import ctypes
import os


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


M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3  # glibc's mallopt parameters
MMAP_THRESHOLD = 32 << 20  # glibc's largest dynamic mmap threshold on 64-bit systems
TRIM_THRESHOLD = 2 * MMAP_THRESHOLD  # what glibc's dynamic threshold sets beside it


def heap_for_renders() -> bool:
    """Undo a small fixed trim threshold (``MALLOC_TRIM_THRESHOLD_`` in the environment, which Dask's nanny sets to
    64 KiB for its workers): with it glibc maps every array of 128 KiB or more afresh and returns it on free, and the
    page faults make a bake of ``seq_moving_object`` (24 frames at 128 px, ir with 16,384 VPLs) take 58.5 s instead
    of 33 s. Setting the variable also stops glibc's dynamic thresholds, so this sets them where those end up for
    large arrays. Returns whether it changed anything (glibc only, and only when the variable is set)."""
    if "MALLOC_TRIM_THRESHOLD_" not in os.environ:
        return False
    try:
        libc = ctypes.CDLL(None)
        mmap = libc.mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD)
        return bool(mmap and libc.mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD))
    except (AttributeError, OSError, TypeError):  # not glibc
        return False
