"""Registering the extension in a fresh bpy process: without a package the engine needs it still registers and says
which and how to fix it; with all of them it starts compiling its kernels in the background, and unregistering stops
that thread, so that unregistering and registering again works in one session (Blender's disable / enable)."""
import os
import subprocess
import sys
import textwrap

import pytest

from conftest import ROOT

pytestmark = pytest.mark.blender


def run(script: str, tmp_path) -> str:
    """The output of ``script`` run by a new Python with the checkout importable, the user's kernel cache kept."""
    proc = subprocess.run([sys.executable, "-c", textwrap.dedent(script)], capture_output=True, text=True,
                          timeout=600, cwd=tmp_path, env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert proc.returncode == 0, proc.stdout + proc.stderr
    return proc.stdout


def test_a_package_that_does_not_load_is_named_at_registration_in_the_panel_and_at_f12(tmp_path):
    out = run("""
        import sys
        sys.modules["numba"] = None  # what Python does with a package that cannot import: ImportError
        import bpy
        from vpl_addon.__main__ import extension_package
        extension_package().register()
        from vpl_gi.operators.ui import unavailable
        print("ENGINE", "VPL_GI" in {getattr(e, "bl_idname", "") for e in bpy.types.RenderEngine.__subclasses__()})
        print("PANEL", hasattr(bpy.types, "RENDER_PT_vpl_gi_unavailable"))
        scene = bpy.context.scene
        scene.render.engine = "VPL_GI"
        scene.render.resolution_x = scene.render.resolution_y = 8
        try:
            bpy.ops.render.render()
        except RuntimeError as err:
            print("F12", str(err).strip().splitlines()[-1])
        extension_package().unregister()
        print("AFTER", hasattr(bpy.types, "RENDER_PT_vpl_gi_unavailable"))
    """, tmp_path)
    lines = out.splitlines()
    said = next(line for line in lines if line.startswith("VPL GI cannot render"))
    assert "numba (compiled kernels) does not load" in said and "Fix: install the VPL GI zip of this platform" in said
    assert "ENGINE True" in lines and "PANEL True" in lines and "AFTER False" in lines
    assert any(line.startswith("F12") and "numba" in line for line in lines), out


def test_unregister_stops_the_kernel_thread_and_register_again_renders(tmp_path):
    out = run("""
        import threading, bpy
        from vpl_addon.__main__ import extension_package
        package = extension_package()
        package.register()
        from vpl_gi.vpl_addon.precompile import KERNELS
        print("COMPILING", [t.name for t in threading.enumerate() if t.name.startswith("vpl_gi")])
        package.unregister()
        print("AFTER", [t.name for t in threading.enumerate() if t.name.startswith("vpl_gi")],
              hasattr(bpy.types.Scene, "vpl_gi"))
        package.register()
        KERNELS.wait("vbnl")
        scene = bpy.context.scene
        scene.render.engine = "VPL_GI"
        scene.render.resolution_x = scene.render.resolution_y = 16
        scene.vpl_gi.samples = 1
        bpy.ops.render.render()
        from vpl_gi.operators.engine import render_engine
        print("REPORTS", [r for r in render_engine.LAST_REPORTS if r[0] == "ERROR"], render_engine.LAST_STATS["width"])
        package.unregister()
        print("END", [t.name for t in threading.enumerate() if t.name.startswith("vpl_gi")])
    """, tmp_path)
    lines = out.splitlines()
    assert "COMPILING ['vpl_gi kernels']" in lines, out
    assert "AFTER [] False" in lines and "REPORTS [] 16" in lines and "END []" in lines, out
