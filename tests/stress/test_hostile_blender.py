"""Hostile Blender scenes through the real extraction and the command line (the bpy module): each renders finite,
non-negative passes (with a warning naming the object when something was skipped) or fails with ONE line
``vpl_addon: error: ...`` naming the object or setting; no traceback reaches the user."""
import math

import numpy as np
import pytest

from conftest import add_mesh, run_cli
from stress_scenes import RESULTS

pytestmark = pytest.mark.blender


def one_error_line(code, stderr):
    """The single error line of a failed run (and proof that nothing else, such as a traceback, was printed)."""
    assert code != 0 and "Traceback" not in stderr, stderr
    lines = [line for line in stderr.splitlines() if line.startswith("vpl_addon: error:")]
    assert len(lines) == 1, stderr
    return lines[0]


def add_light(bpy, name, kind="POINT", location=(0, 0, 2), energy=100.0):
    obj = bpy.data.objects.new(name, bpy.data.lights.new(name, kind))
    obj.location = location
    obj.data.energy = energy
    bpy.context.scene.collection.objects.link(obj)
    return obj


CUBE_V = [(x, y, z) for z in (-1, 1) for y in (-1, 1) for x in (-1, 1)]
CUBE_F = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
QUAD = ([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], [(0, 1, 2, 3)])


def nan_location(bpy):
    add_mesh(bpy, "Broken", *QUAD).location = (math.nan, 0, 1)


def infinite_scale(bpy):
    add_mesh(bpy, "Broken", *QUAD, location=(0, 0, 1)).scale = (math.inf, 1, 1)


def zero_scale(bpy):
    add_mesh(bpy, "Broken", CUBE_V, CUBE_F, location=(0, 0, 1)).scale = (0, 0, 0)


def nan_uvs(bpy):
    floor = bpy.data.objects["Floor"]
    uv = floor.data.uv_layers.new(name="UV")
    for loop in uv.data:
        loop.uv = (math.nan, math.inf)
    image = bpy.data.images.new("Broken picture", 2, 2)
    image.pixels.foreach_set(np.full(16, 0.5, np.float32))
    mat = bpy.data.materials.new("Broken textured")
    node = mat.node_tree.nodes.new("ShaderNodeTexImage")
    node.image = image
    mat.node_tree.links.new(node.outputs["Color"], mat.node_tree.nodes["Principled BSDF"].inputs["Base Color"])
    floor.data.materials.append(mat)


def nan_custom_normals(bpy):
    floor = bpy.data.objects["Floor"].data
    floor.normals_split_custom_set([(math.nan, math.inf, 0.0)] * len(floor.loops))


def missing_texture(bpy):
    mat = bpy.data.materials.new("Broken material")
    node = mat.node_tree.nodes.new("ShaderNodeTexImage")
    node.image = bpy.data.images.new("Picture", 4, 4)
    node.image.source = "FILE"
    node.image.filepath = "/nonexistent/folder/picture.png"
    mat.node_tree.links.new(node.outputs["Color"], mat.node_tree.nodes["Principled BSDF"].inputs["Base Color"])
    bpy.data.objects["Floor"].data.materials.append(mat)


def nan_material(bpy):
    mat = bpy.data.materials.new("Broken material")
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (math.nan, 1, math.inf, 1)
    bsdf.inputs["Emission Strength"].default_value = math.nan
    bsdf.inputs["Emission Color"].default_value = (1, math.inf, 1, 1)
    bpy.data.objects["Floor"].data.materials.append(mat)


def empty_mesh(bpy):
    add_mesh(bpy, "Broken", [], [])


def loose_vertices_and_edges(bpy):
    mesh = bpy.data.meshes.new("Broken")
    mesh.from_pydata([(0, 0, 1), (1, 0, 1), (0, 1, 1)], [(0, 1), (1, 2)], [])
    bpy.context.scene.collection.objects.link(bpy.data.objects.new("Broken", mesh))


def zero_size_area_light(bpy):
    light = add_light(bpy, "Broken", "AREA")
    light.data.size = 0.0
    bpy.data.objects.remove(bpy.data.objects["Lamp"])


def nan_light_colour(bpy):
    add_light(bpy, "Broken").data.color = (math.nan, 1, 1)


def infinite_light_energy(bpy):
    add_light(bpy, "Broken").data.energy = math.inf


def nan_light_location(bpy):
    add_light(bpy, "Broken", "SPOT").location = (0, math.nan, 2)


def nan_sun_rotation(bpy):
    add_light(bpy, "Broken", "SUN", energy=3).rotation_euler = (math.nan, 0, 0)


def nan_world(bpy):
    world = bpy.data.worlds.new("Broken world")
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = math.nan
    bpy.context.scene.world = world


def camera_inside_a_cube(bpy):
    add_mesh(bpy, "Block", CUBE_V, CUBE_F, location=(0, 0, 5))


def camera_clip_inverted(bpy):
    cam = bpy.context.scene.camera.data
    cam.clip_start, cam.clip_end = 100.0, 1.0


def nan_camera(bpy):
    bpy.context.scene.camera.location = (math.nan, 0, 5)


def zero_scale_camera(bpy):
    bpy.context.scene.camera.scale = (0, 0, 0)


def one_pixel(bpy):
    bpy.context.scene.render.resolution_x = bpy.context.scene.render.resolution_y = 1


# name -> (change to the base scene, None if it must render / words its one-line error must contain,
#          words a warning must contain when it renders)
HAZARDS = {
    "NaN in a mesh's location": (nan_location, None, "'Broken'"),
    "infinite scale of a mesh": (infinite_scale, None, "'Broken'"),
    "zero scale of a mesh": (zero_scale, None, "'Broken'"),
    "NaN and inf UVs on a textured floor": (nan_uvs, None, None),
    "NaN and inf custom normals": (nan_custom_normals, None, None),
    "missing image texture file": (missing_texture, None, "'Broken material'"),
    "NaN and inf material inputs": (nan_material, None, None),
    "empty mesh object": (empty_mesh, None, None),
    "mesh of loose vertices and edges": (loose_vertices_and_edges, None, None),
    "zero-size area light (the only light)": (zero_size_area_light, None, "'Broken'"),
    "light with NaN colour": (nan_light_colour, None, "'Broken'"),
    "light with infinite energy": (infinite_light_energy, None, "'Broken'"),
    "spot with NaN location": (nan_light_location, None, "'Broken'"),
    "sun with NaN rotation": (nan_sun_rotation, None, "'Broken'"),
    "world of NaN strength": (nan_world, None, None),
    "camera inside a cube": (camera_inside_a_cube, None, None),
    "camera clip start beyond clip end": (camera_clip_inverted, None, None),
    "camera with NaN location": (nan_camera, "'Camera'", None),
    "camera scaled to zero": (zero_scale_camera, None, None),
    "one-pixel image": (one_pixel, None, None),
}


@pytest.fixture
def hostile_blend(ext, tmp_path):
    """A floor, a camera above it looking down, a point light; ``make(change)`` applies a hazard and saves."""
    import bpy

    def make(change, name="hostile.blend"):
        bpy.ops.wm.read_factory_settings(use_empty=True)
        scene = bpy.context.scene
        scene.render.resolution_x = scene.render.resolution_y = 12
        add_mesh(bpy, "Floor", [(-5, -5, 0), (5, -5, 0), (5, 5, 0), (-5, 5, 0)], [(0, 1, 2, 3)])
        add_mesh(bpy, "Wall", [(-5, 3, 0), (5, 3, 0), (5, 3, 4), (-5, 3, 4)], [(0, 1, 2, 3)])
        cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
        cam.location = (0, 0, 5)
        scene.collection.objects.link(cam)
        scene.camera = cam
        add_light(bpy, "Lamp")
        change(bpy)
        path = tmp_path / name
        bpy.ops.wm.save_as_mainfile(filepath=str(path))
        return path

    return make


@pytest.mark.parametrize("hazard", HAZARDS)
def test_hostile_blender_scene_renders_or_fails_in_one_line(hazard, hostile_blend, tmp_path):
    """Through the real extraction and CLI: finite, non-negative passes (and a warning naming the object when the
    hazard made it skip something), or one error line naming the object; never a traceback, never a file left
    behind by a failed run."""
    from vpl_addon.core.exr import read_passes
    change, error_words, warning_words = HAZARDS[hazard]
    out = tmp_path / "out.exr"
    code, _, stderr = run_cli("render", hostile_blend(change), "-o", out, "--samples", "2", "--light-samples", "1",
                              "--vpls", "32", "--method", "ir")
    assert "Traceback" not in stderr, stderr
    if error_words is not None:
        assert error_words in one_error_line(code, stderr)
        assert not out.exists() and not list(tmp_path.glob(".partial-*"))
        return
    assert code == 0, stderr
    if warning_words is not None:
        assert [line for line in stderr.splitlines() if line.startswith("warning:") and warning_words in line], \
            stderr
    passes, _ = read_passes(str(out))
    bad = sum(int((~np.isfinite(p)).sum() + (p < 0).sum()) for p in passes.values())
    RESULTS["scenes"].add(f"blender: {hazard}")
    RESULTS["renders"] += 1
    RESULTS["bad_values"] += bad
    assert bad == 0


@pytest.mark.parametrize("flag, value", [("--samples", "0"), ("--vpls", "-5"), ("--interleave", "100"),
                                         ("--clamp", "nan"), ("--clamp", "-1"), ("--light-samples", "-1")])
def test_out_of_range_settings_are_refused_in_one_line(flag, value, hostile_blend, tmp_path):
    """A number outside a setting's range (Blender would clamp it silently, and keeps NaN) is refused in one line
    naming the flag, and nothing is written."""
    out = tmp_path / "out.exr"
    code, _, stderr = run_cli("render", hostile_blend(lambda bpy: None), "-o", out, flag, value)
    assert f"{flag} {value}" in one_error_line(code, stderr)
    assert not out.exists() and not list(tmp_path.glob(".partial-*"))
