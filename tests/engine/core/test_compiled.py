"""The compiled kernels (``core.compiled``): machine code cached in the user's cache folder, so a second process
loads it instead of compiling, whatever name the engine was imported under; and compiled ahead of the first render
on a thread that stops when told (``precompile``)."""
import os
import subprocess
import sys
import threading

from conftest import ROOT

MODULE = """
from vpl_addon.core.compiled import kernel


@kernel
def twice(x):
    return 2.0 * x
"""

GROUP_SUM = """
import numpy as np
import importlib
if {name!r}.startswith("vpl_gi."):
    from vpl_addon.__main__ import extension_package
    extension_package()
sampling = importlib.import_module({name!r} + ".core.sampling")
assert sampling.group_sum(np.array([0, 0, 1]), np.ones((3, 2)), 2).tolist() == [[2.0, 2.0], [1.0, 1.0]]
"""


def run(code, cache):
    env = {key: value for key, value in os.environ.items() if key != "NUMBA_CACHE_DIR"}
    env.update(VPL_GI_CACHE=str(cache), PYTHONPATH=os.pathsep.join([str(ROOT), str(cache.parent / "src")]))
    subprocess.run([sys.executable, "-c", code], env=env, check=True, timeout=300, cwd=str(cache.parent))


def test_kernels_are_cached_in_the_users_cache_folder(tmp_path):
    (tmp_path / "src").mkdir()
    (tmp_path / "src" / "doubling.py").write_text(MODULE)
    run("import doubling; assert doubling.twice(1.5) == 3.0", tmp_path / "cache")
    cached = [name for _, _, files in os.walk(tmp_path / "cache" / "numba" / "doubling") for name in files]
    assert any(name.startswith("doubling.twice") and name.endswith(".nbc") for name in cached), cached


def test_each_import_name_keeps_its_own_kernels(tmp_path):
    """The command line and Blender import the engine as ``vpl_gi.vpl_addon`` (``bl_ext...``), the tests as
    ``vpl_addon``, and the tests load both in one process: each copy's kernels go to their own folder, so a later
    process with one name alone loads them (a cached kernel imports the module it was compiled in)."""
    (tmp_path / "src").mkdir()
    run(GROUP_SUM.format(name="vpl_gi.vpl_addon") + GROUP_SUM.format(name="vpl_addon"), tmp_path / "cache")
    folders = sorted(os.listdir(tmp_path / "cache" / "numba"))
    assert folders == ["vpl_addon.core.sampling", "vpl_gi.vpl_addon.core.sampling"]
    run(GROUP_SUM.format(name="vpl_addon"), tmp_path / "cache")
    run(GROUP_SUM.format(name="vpl_gi.vpl_addon"), tmp_path / "cache")


HELPED = """
from vpl_addon.core.compiled import inline, kernel


@inline
def half(x):
    return 0.5 * x


@kernel
def quarter(x):
    return half(half(x))
"""


def test_a_kernel_keeps_its_inlined_helpers_in_its_cache(tmp_path):
    """An ``inline`` helper is compiled into the kernel that calls it: the kernel is cached with it, and a second
    process loads that kernel and gives the same value."""
    (tmp_path / "src").mkdir()
    (tmp_path / "src" / "helped.py").write_text(HELPED)
    for _ in range(2):
        run("import helped; assert helped.quarter(3.0) == 0.75", tmp_path / "cache")
    cached = [name for _, _, files in os.walk(tmp_path / "cache" / "numba" / "helped") for name in files]
    assert any(name.startswith("helped.quarter") and name.endswith(".nbc") for name in cached), cached
    assert not any(name.startswith("helped.half") for name in cached), cached


def test_tables_are_kept_on_disk_bit_for_bit_and_made_again_when_the_code_or_the_file_changes(tmp_path, monkeypatch):
    """``kept_tables``: the first call makes the arrays and keeps them, the next one (another process's) reads them
    back to the bit without making them; another source file's hash makes them anew, and so does a damaged file.
    The glossy lobe's albedo tables come back from the disk equal to the integrated ones."""
    import numpy as np
    from vpl_addon.core import compiled
    from vpl_addon.materials import microfacet as M
    monkeypatch.setenv("VPL_GI_CACHE", str(tmp_path / "cache"))
    made = []

    def make():
        made.append(1)
        return np.random.default_rng(3).random((4, 5)), np.float64(np.pi)

    source = tmp_path / "module.py"
    source.write_text("one")
    first = compiled.kept_tables("t", str(source), make)
    second = compiled.kept_tables("t", str(source), make)
    assert len(made) == 1 and second[0].tobytes() == first[0].tobytes() and float(second[1]) == np.pi
    (kept,) = (tmp_path / "cache" / "tables").iterdir()
    kept.write_bytes(kept.read_bytes()[:100])  # a file cut short
    assert compiled.kept_tables("t", str(source), make)[0].tobytes() == first[0].tobytes() and len(made) == 2
    other = tmp_path / "other.py"
    other.write_text("two")
    compiled.kept_tables("t", str(other), make)
    assert len(made) == 3
    M._metal_tables.cache_clear()
    M._metal_tables()  # made and kept
    M._metal_tables.cache_clear()
    for disk, integrated in zip(M._metal_tables(), M._integrated_metal_tables()):
        assert disk.tobytes() == integrated.tobytes()
    assert any(p.name.startswith("metal-") for p in (tmp_path / "cache" / "tables").iterdir())


def test_precompile_readies_every_method_on_its_thread_and_a_stop_joins_it():
    from vpl_addon.methods import METHODS
    from vpl_addon.precompile import Precompile
    kernels = Precompile()
    kernels.start()
    assert "vpl_gi kernels" in [t.name for t in threading.enumerate()]
    assert kernels.status().startswith("Compiling kernels")
    kernels.stop()
    assert "vpl_gi kernels" not in [t.name for t in threading.enumerate()] and not kernels.ready
    kernels.start()
    for name in METHODS:
        assert kernels.wait(name, timeout=900), name
    assert kernels.ready and kernels.error is None and kernels.status().startswith("Kernels ready"), kernels.status()
    assert kernels.wait("none", timeout=0)  # no method: nothing to wait for
    kernels.stop()
    assert "vpl_gi kernels" not in [t.name for t in threading.enumerate()]
