"""The compiled kernels (``core.compiled``): machine code cached in the user's cache folder, so a second process
loads it instead of compiling, whatever name the engine was imported under."""
import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

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
    env.update(VPL_GI_CACHE=str(cache), PYTHONPATH=os.pathsep.join([ROOT, str(cache.parent / "src")]))
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
