"""The render engine inside a long-lived Blender: what a render frees goes back to the system."""
import pytest

from conftest import EXAMPLES

pytestmark = pytest.mark.blender


def test_blender_does_not_keep_the_memory_a_render_freed(ext):
    """A 64 x 64 vbnl render of the Cornell box allocates and frees about half a GB of arrays; without the heap
    handed back after the render, Blender stays that much larger (458 MB here) until it exits."""
    import bpy
    from vpl_gi.operators.engine import render_engine as engine
    from vpl_gi.vpl_addon.core.memory import status_kb, trim_heap
    bpy.ops.wm.open_mainfile(filepath=str(EXAMPLES / "cornell_area.blend"))
    scene = bpy.context.scene
    scene.render.engine = engine.VPLGIRenderEngine.bl_idname
    scene.render.resolution_percentage = 25
    scene.vpl_gi.method = "vbnl"
    trim_heap()  # what earlier tests freed would otherwise serve this render and hide its growth
    before = status_kb("VmRSS") / 1024
    bpy.ops.render.render()
    assert engine.LAST_STATS["width"] == 64, engine.LAST_REPORTS
    assert status_kb("VmRSS") / 1024 - before < 150
