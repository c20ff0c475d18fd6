"""The extension as Blender users get it: built and validated by Blender's own tool (shipped in the bpy wheel),
installed into a throw-away user repository, enabled, and rendering a scene through the installed copy."""
import importlib.util
import os
import pathlib
import subprocess
import sys
import textwrap

import pytest

from conftest import EXAMPLES, ROOT

pytestmark = pytest.mark.blender

INSTALL_AND_RENDER = textwrap.dedent("""
    import sys, bpy
    zip_path, blend, out = sys.argv[1:4]
    bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default", enable_on_install=True)
    engine = sys.modules["bl_ext.user_default.vpl_gi.operators.engine"]
    print("ENGINE_FILE", engine.__file__)
    bpy.ops.wm.open_mainfile(filepath=blend)
    scene = bpy.context.scene
    scene.render.engine = "VPL_GI"
    scene.vpl_gi.samples = 2
    scene.vpl_gi.light_samples = 1
    scene.render.resolution_percentage = 25
    scene.view_layers[0].use_pass_diffuse_direct = True
    scene.render.image_settings.media_type = "MULTI_LAYER_IMAGE"
    scene.render.image_settings.file_format = "OPEN_EXR_MULTILAYER"
    scene.render.filepath = out
    scene.render.use_file_extension = False
    bpy.ops.render.render(write_still=True)
""")


def blender_ext_tool() -> pathlib.Path:
    spec = importlib.util.find_spec("bpy")
    base = pathlib.Path(list(spec.submodule_search_locations)[0])
    return next(base.glob("*/scripts/addons_core/bl_pkg/cli/blender_ext.py"))


def run(*args, env=None):
    proc = subprocess.run([sys.executable, *map(str, args)], capture_output=True, text=True, timeout=600,
                          env={**os.environ, **(env or {})})
    assert proc.returncode == 0, proc.stdout + proc.stderr
    return proc.stdout


def test_extension_builds_validates_installs_and_renders(tmp_path):
    from vpl_addon.core.exr import read_passes
    tool = blender_ext_tool()
    missing = [w for w in ("wheels",) if not (ROOT / w).is_dir()]
    assert not missing, "run `make wheels` first: the extension bundles the embreex and scipy wheels"
    dist = tmp_path / "dist"
    dist.mkdir()
    run(tool, "build", "--source-dir", ROOT, "--output-dir", dist)
    (zip_path,) = dist.glob("vpl_gi-*.zip")
    assert "Success" in run(tool, "validate", zip_path)
    user = tmp_path / "user"
    out = tmp_path / "render.exr"
    stdout = run("-c", INSTALL_AND_RENDER, zip_path, EXAMPLES / "cornell_area.blend", out,
                 env={"BLENDER_USER_EXTENSIONS": str(user / "extensions"), "BLENDER_USER_CONFIG": str(user / "config")})
    engine_file = next(l.split(" ", 1)[1] for l in stdout.splitlines() if l.startswith("ENGINE_FILE"))
    assert engine_file.startswith(str(user)), "the render must run the installed copy, not the checkout"
    assert list(user.glob("extensions/.local/lib/python3.11/site-packages/embreex/rtcore_scene*.so")), \
        "the bundled embreex wheel was not installed"
    assert list(user.glob("extensions/.local/lib/python3.11/site-packages/scipy/spatial/_ckdtree*.so")), \
        "the bundled scipy wheel was not installed"
    passes, _ = read_passes(str(out))
    assert passes["Diffuse Direct"].shape == (64, 64, 3) and passes["Diffuse Direct"].mean() > 0.05
