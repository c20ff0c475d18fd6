"""The C library's heap in processes that others start: a Dask worker's small trim threshold undone
(``core.memory.heap_for_renders``)."""
import subprocess
import sys

from conftest import ROOT


HEAP_PROBE = """
import resource, sys
import numpy as np
sys.path.insert(0, {root!r})
from vpl_addon.core.memory import heap_for_renders


def faults():
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    for _ in range(200):
        np.ones(1 << 17)  # 1 MiB, touched, then freed
    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before


print(faults(), heap_for_renders(), faults())
"""


def test_a_dask_workers_trim_threshold_is_undone_so_freed_arrays_are_reused():
    """Dask's nanny starts its workers with MALLOC_TRIM_THRESHOLD_=65536: glibc then maps every array afresh and
    each of its pages faults in again (a farm worker rendered 1.8x slower than a process). ``heap_for_renders``
    (called by every farm chunk) sets the thresholds back where glibc's own would be; without the variable it does
    nothing."""
    probe = HEAP_PROBE.format(root=str(ROOT))
    env = {"MALLOC_TRIM_THRESHOLD_": "65536", "PATH": "/usr/bin:/bin"}
    throttled, changed, after = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True,
                                               check=True).stdout.split()
    assert changed == "True"
    assert int(throttled) > 200 * 200 and int(after) < 1000  # 256 pages a MiB, each faulting, until undone
    _, changed, _ = subprocess.run([sys.executable, "-c", probe], env={"PATH": "/usr/bin:/bin"}, capture_output=True,
                                   text=True, check=True).stdout.split()
    assert changed == "False"
