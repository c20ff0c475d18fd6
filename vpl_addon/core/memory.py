"""The process's memory as the system sees it, and handing back what the engine freed.

A render allocates and frees gigabytes of numpy arrays, many too small for their own mapping, so glibc serves them
from its heap arenas (one per thread that allocated) and keeps them there when they are freed. In a long-lived
process that heap stays resident: Blender rendering the corridor with ``vbnl`` six times held 3.0 GB afterwards
(0.4 GB before the first render), and 0.5 GB when the heap was handed back after each render."""
from __future__ import annotations

import ctypes


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
