"""The extension as Blender users get it: one zip per platform built (--split-platforms) and validated by Blender's
own tool (shipped in the bpy wheel), each with only its platform's wheels; the Linux one installed into a throw-away
user repository, enabled, and rendering a scene through the installed copy."""
import importlib.util
import os
import pathlib
import re
import subprocess
import sys
import textwrap
import tomllib
import zipfile

import pytest

from conftest import EXAMPLES, ROOT

pytestmark = pytest.mark.blender

# The platforms the extension ships for, and the wheel platform tags (the last field of a wheel's file name, its
# dot-separated parts) that belong in each platform's zip.
PLATFORM_WHEEL_TAGS = {
    "linux-x64": r"manylinux(_\d+_\d+|\d+)_x86_64",
    "windows-x64": r"win_amd64",
    "macos-arm64": r"macosx_\d+_\d+_arm64",
    "macos-x64": r"macosx_\d+_\d+_x86_64",
}
# the compiled wheels come once per Python the supported Blenders bundle; pyoidn (its own libraries, loaded by cffi)
# and pycparser (pure Python, "any" platform) once
COMPILED = ["cffi", "embreex", "llvmlite", "numba", "scipy"]
PYTHON_TAGS = ["cp311", "cp313"]
BUNDLED = sorted([(name, tag) for name in COMPILED for tag in PYTHON_TAGS] + [("pycparser", "py3"), ("pyoidn", "py3")])

INSTALL_AND_RENDER = textwrap.dedent("""
    import sys, bpy
    zip_path, blend, out = sys.argv[1:4]
    bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default", enable_on_install=True)
    engine = sys.modules["bl_ext.user_default.vpl_gi.operators.engine.render_engine"]
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
    scene.vpl_gi.denoise = True
    bpy.ops.render.render(write_still=True)
    print("REPORTS", engine.LAST_REPORTS)
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


def test_the_manifest_bundles_the_wheels_the_makefile_pins():
    """``make wheels`` fetches what the Makefile pins; the manifest must name exactly those files."""
    manifest = tomllib.loads((ROOT / "blender_manifest.toml").read_text())
    pinned = subprocess.run(["make", "-s", "--no-print-directory", "print-wheels"], cwd=ROOT, capture_output=True,
                            text=True, check=True).stdout.split()
    assert [w.removeprefix("./") for w in manifest["wheels"]] == pinned


def test_extension_builds_validates_installs_and_renders(tmp_path):
    from vpl_addon.core.exr import read_passes
    tool = blender_ext_tool()
    manifest = tomllib.loads((ROOT / "blender_manifest.toml").read_text())
    assert sorted(manifest["platforms"]) == sorted(PLATFORM_WHEEL_TAGS)
    missing = [w for w in manifest["wheels"] if not (ROOT / w).is_file()]
    assert not missing, f"run `make wheels` first: the extension bundles its wheels; missing {missing}"
    dist = tmp_path / "dist"
    dist.mkdir()
    run(tool, "build", "--split-platforms", "--source-dir", ROOT, "--output-dir", dist)
    zips = {platform: dist / f"vpl_gi-{manifest['version']}-{platform.replace('-', '_')}.zip"
            for platform in manifest["platforms"]}
    assert sorted(dist.iterdir()) == sorted(zips.values())
    for platform, zip_path in zips.items():
        assert "Success" in run(tool, "validate", zip_path)
        with zipfile.ZipFile(zip_path) as archive:
            names = archive.namelist()
            generated = tomllib.loads(archive.read("blender_manifest.toml").decode())["build"]["generated"]
        assert not [n for n in names if n == ".git" or n.startswith((".git/", "tests/"))], "the checkout leaked in"
        wheels = sorted(pathlib.PurePosixPath(n).name for n in names if n.endswith(".whl"))
        assert sorted((w.split("-")[0], w.split("-")[2]) for w in wheels) == BUNDLED, (platform, wheels)
        for wheel in wheels:
            tags = wheel.removesuffix(".whl").split("-")[-1].split(".")
            assert all(re.fullmatch(PLATFORM_WHEEL_TAGS[platform] + "|any", t) for t in tags), (platform, wheel)
        assert generated["platforms"] == [platform]
        assert sorted(pathlib.PurePosixPath(w).name for w in generated["wheels"]) == wheels
    user = tmp_path / "user"
    out = tmp_path / "render.exr"
    stdout = run("-c", INSTALL_AND_RENDER, zips["linux-x64"], EXAMPLES / "cornell_area.blend", out,
                 env={"BLENDER_USER_EXTENSIONS": str(user / "extensions"), "BLENDER_USER_CONFIG": str(user / "config"),
                      "VPL_GI_CACHE": str(user / "cache")})
    engine_file = next(l.split(" ", 1)[1] for l in stdout.splitlines() if l.startswith("ENGINE_FILE"))
    assert engine_file.startswith(str(user)), "the render must run the installed copy, not the checkout"
    assert list(user.glob("extensions/.local/lib/python3.11/site-packages/embreex/rtcore_scene*.so")), \
        "the bundled embreex wheel was not installed"
    assert list(user.glob("extensions/.local/lib/python3.11/site-packages/scipy/spatial/_ckdtree*.so")), \
        "the bundled scipy wheel was not installed"
    assert list(user.glob("extensions/.local/lib/python3.11/site-packages/llvmlite/binding/libllvmlite*")), \
        "the bundled llvmlite wheel (numba's compiler, core.compiled) was not installed"
    assert list(user.glob("cache/numba/bl_ext.user_default.vpl_gi.vpl_addon.*/**/*.nbc")), \
        "the installed extension's kernels are cached in the user's cache folder under its import name"
    assert "denoised" not in next(line for line in stdout.splitlines() if line.startswith("REPORTS")), \
        "the bundled OpenImageDenoise (pyoidn, cffi, pycparser) must load in the installed extension"
    passes, _ = read_passes(str(out))
    assert passes["Diffuse Direct"].shape == (64, 64, 3) and passes["Diffuse Direct"].mean() > 0.05
