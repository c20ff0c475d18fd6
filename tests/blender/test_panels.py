"""The property tabs with VPL GI chosen (issue 22): Blender's own Light, Material and World panels show for the
engine (EEVEE's, whose polls read their own COMPAT_ENGINES), our Light Paths and Film panels hold settings that
default to the scene's Cycles values and change the render, and unregistering takes the engine off the panels."""
import numpy as np
import pytest

from conftest import add_mesh, add_sun, camera_and_black_world

pytestmark = pytest.mark.blender

ENGINE = "VPL_GI"


def _shown(bpy, tab, **members):
    """The names of the Properties editor's panels of ``tab`` (bl_context) that show, polled with Blender's context
    holding ``members`` (the light, material, world or object being shown): their poll admits them, and their parent
    panel shows (a subpanel's poll often leaves the engine to its parent's)."""
    found, parent = set(), {}
    with bpy.context.temp_override(**members):
        for name in dir(bpy.types):
            panel = getattr(bpy.types, name)
            if getattr(panel, "bl_space_type", "") != "PROPERTIES" or getattr(panel, "bl_context", "") != tab or \
                    not isinstance(panel, type) or not issubclass(panel, bpy.types.Panel):
                continue
            try:
                if not hasattr(panel, "poll") or panel.poll(bpy.context):
                    found.add(name)
                    parent[name] = getattr(panel, "bl_parent_id", "")
            except AttributeError:  # it reads a member this tab's context has not (a camera's, a mesh's): hidden
                pass

    def top_shows(name):
        return not parent[name] or (parent[name] in found and top_shows(parent[name]))
    return {name for name in found if top_shows(name)}


def test_the_light_material_and_world_tabs_show_their_panels_for_the_engine(ext):
    import bpy
    from vpl_gi.operators.ui import panels
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = ENGINE
    spot, area = bpy.data.lights.new("Spot", "SPOT"), bpy.data.lights.new("Area", "AREA")
    material, world = bpy.data.materials.new("Paint"), bpy.data.worlds.new("Sky")
    cube = add_mesh(bpy, "Cube", [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [(0, 1, 2)], material)
    light_tab = _shown(bpy, "data", light=spot)
    # power, colour and size in Blender's own Light panel, not the panel that shows the light's type alone
    assert {"DATA_PT_EEVEE_light", "DATA_PT_spot"} <= light_tab and "DATA_PT_light" not in light_tab
    assert "DATA_PT_vpl_gi_area_spread" in _shown(bpy, "data", light=area)
    assert {"EEVEE_MATERIAL_PT_context_material", "EEVEE_MATERIAL_PT_surface"} <= _shown(
        bpy, "material", material=material, object=cube)
    assert "EEVEE_WORLD_PT_surface" in _shown(bpy, "world", world=world)
    render_tab = _shown(bpy, "render")
    assert {"RENDER_PT_vpl_gi", "RENDER_PT_vpl_gi_light_paths", "RENDER_PT_vpl_gi_film",
            "RENDER_PT_vpl_gi_performance"} <= render_tab
    # no EEVEE or Cycles setting the engine does not read: EEVEE's light shadow, volumes, Cycles' panels
    assert not any(name.startswith("CYCLES_") for name in light_tab | render_tab)
    assert "DATA_PT_EEVEE_light_shadow" not in light_tab
    assert "EEVEE_MATERIAL_PT_volume" not in _shown(bpy, "material", material=material, object=cube)

    panels.unregister()  # as when the extension is disabled: EEVEE's panels are EEVEE's again
    try:
        assert "DATA_PT_EEVEE_light" not in _shown(bpy, "data", light=spot)
        assert ENGINE not in bpy.types.EEVEE_WORLD_PT_surface.COMPAT_ENGINES
        scene.render.engine = "BLENDER_EEVEE"
        assert "DATA_PT_EEVEE_light" in _shown(bpy, "data", light=spot)
    finally:
        panels.register()


def _lit_floor(bpy):
    """A floor and a wall lit by a sun: the wall's light reaches the floor after one diffuse bounce."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 32, 24
    add_mesh(bpy, "Floor", [(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)], [(0, 1, 2, 3)])
    add_mesh(bpy, "Wall", [(-3, 1, 0), (3, 1, 0), (3, 1, 3), (-3, 1, 3)], [(0, 1, 2, 3)])
    add_sun(bpy, scene, (np.radians(-50.0), 0.0, 0.0), energy=3.0)  # from behind the camera, onto wall and floor
    camera_and_black_world(bpy, scene, (0.0, -6.0, 3.0), (np.radians(65.0), 0.0, 0.0))
    return scene


def test_light_paths_and_film_settings_default_to_cycles_and_change_the_render(ext, tmp_path):
    import bpy
    from vpl_gi.operators.scene.extract import camera_of
    from vpl_gi.operators.output.render_file import render_to
    from vpl_gi.vpl_addon.core.exr import read_passes
    scene = _lit_floor(bpy)
    scene.render.engine = ENGINE
    scene.view_layers[0].use_pass_diffuse_indirect = True
    settings = scene.vpl_gi
    settings.method, settings.samples, settings.light_samples, settings.vpls = "ir", 4, 1, 256
    # until set, our settings are the scene's Cycles settings, and setting ours leaves Cycles' alone
    scene.cycles.max_bounces, scene.cycles.diffuse_bounces, scene.cycles.pixel_filter_type = 7, 3, "GAUSSIAN"
    assert (settings.max_bounces, settings.diffuse_bounces, settings.pixel_filter_type) == (7, 3, "GAUSSIAN")
    settings.pixel_filter_type, settings.filter_width = "BOX", 2.5
    assert scene.cycles.pixel_filter_type == "GAUSSIAN"
    assert (camera_of(scene).filter_type, camera_of(scene).filter_width) == ("BOX", 2.5)

    indirect = {}
    for bounces in (3, 0):
        settings.diffuse_bounces = bounces
        render_to(scene, str(tmp_path / f"{bounces}.exr"))
        indirect[bounces] = read_passes(str(tmp_path / f"{bounces}.exr"))[0]["Diffuse Indirect"]
    assert scene.cycles.diffuse_bounces == 3
    print(f"Diffuse Indirect mean: {indirect[3].mean():.4f} with 3 diffuse bounces, {indirect[0].mean():.4f} with 0")
    assert indirect[3].mean() > 1e-3 and (indirect[0] == 0.0).all()


def test_the_render_runs_on_the_threads_blender_is_set_to(ext, tmp_path):
    """Performance > Threads: Blender's own setting (every core, or a fixed number), as Cycles follows it."""
    import os

    import bpy
    from vpl_gi.operators.engine import render_engine as engine
    from vpl_gi.operators.output.render_file import render_to
    scene = _lit_floor(bpy)
    scene.render.engine = ENGINE
    scene.vpl_gi.method, scene.vpl_gi.samples = "none", 1
    for mode, expected in (("FIXED", 1), ("AUTO", os.cpu_count())):
        scene.render.threads_mode, scene.render.threads = mode, 1
        render_to(scene, str(tmp_path / f"{mode}.exr"))
        assert engine.LAST_STATS["threads"] == expected, mode


def test_the_passes_panel_shows_every_pass_the_engine_writes(ext):
    """Each toggle the engine reads has its checkbox in the engine's Passes panel, and each checkbox is a view
    layer setting (a wrong name would break the panel's drawing in Blender)."""
    import bpy
    from vpl_gi.operators.engine import render_engine as engine
    from vpl_gi.operators.ui import panels
    shown = [toggle for _, toggles in panels.VIEWLAYER_PT_vpl_gi_passes.GROUPS for toggle in toggles]
    read = [toggle for _, toggle, _, _ in engine.PASS_TOGGLES] + list(engine.CRYPTOMATTE_TOGGLES.values())
    assert sorted(shown) == sorted(read + ["pass_cryptomatte_depth"])
    assert all(toggle in bpy.types.ViewLayer.bl_rna.properties for toggle in shown)
