"""The C library's heap: a Dask worker's small trim threshold undone (``core.memory.heap_for_renders``), and the
heap kept while a render runs (``core.memory.render_heap``)."""
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


RENDER_PROBE = """
import resource, sys
import numpy as np
sys.path.insert(0, {root!r})
from vpl_addon.core.memory import render_heap

np.core.multiarray._set_madvise_hugepage(False)  # 4 KiB pages, so that faults count pages


def faults():
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    for _ in range(20):
        np.ones(6 << 20)  # 48 MiB, touched, then freed: past glibc's largest dynamic mmap threshold
    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before


plain = faults()
with render_heap():
    with render_heap():  # a second render at once (the viewport's beside F12's)
        kept = faults()
    inner_ended = faults()
print(plain, kept, inner_ended, faults())
"""


def test_a_render_keeps_the_heap_it_frees_until_the_last_render_ends():
    """Inside ``render_heap`` an array freed and made again comes from the heap, its pages already there: a 48 MiB
    array made twenty times faults its 12,288 pages in once instead of twenty times. The heap stays kept while any
    render runs, and once the last one ends such arrays are mapped afresh as before."""
    plain, kept, inner_ended, after = (int(n) for n in subprocess.run(
        [sys.executable, "-c", RENDER_PROBE.format(root=str(ROOT))], env={"PATH": "/usr/bin:/bin"},
        capture_output=True, text=True, check=True).stdout.split())
    pages = 12_288
    assert plain > 19 * pages and after > 19 * pages
    assert kept < 3 * pages and inner_ended < pages
