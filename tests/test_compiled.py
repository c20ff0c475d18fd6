"""The compiled kernels (``core.compiled``): machine code cached in the user's cache folder, so a second process
loads it instead of compiling."""
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


def test_kernels_are_cached_in_the_users_cache_folder(tmp_path):
    (tmp_path / "src").mkdir()
    (tmp_path / "src" / "doubling.py").write_text(MODULE)
    env = {key: value for key, value in os.environ.items() if key != "NUMBA_CACHE_DIR"}
    env.update(VPL_GI_CACHE=str(tmp_path / "cache"), PYTHONPATH=os.pathsep.join([ROOT, str(tmp_path / "src")]))
    subprocess.run([sys.executable, "-c", "import doubling; assert doubling.twice(1.5) == 3.0"], env=env, check=True,
                   timeout=300)
    cached = [name for _, _, files in os.walk(tmp_path / "cache" / "numba") for name in files]
    assert any(name.startswith("doubling.twice") and name.endswith(".nbc") for name in cached), cached
