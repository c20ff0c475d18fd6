"""Real scenes: the Mitsuba XML parser and the Cornell measured data (no bpy, ``importers/``), and one conversion of the
smallest real scene through bpy checked down to the engine's extracted arrays."""
from __future__ import annotations

import importlib.util
import math
import os

import numpy as np
import pytest

from conftest import ROOT
from importers import cornell_measured, mitsuba, wavefront  # no bpy in them: tests/repository/test_layout.py

SHARED = ROOT.parent / "shared" / "scenes"
NEED_SHARED = pytest.mark.skipif(not SHARED.is_dir(), reason="../shared/scenes is not beside the repository")




def parse(body: str, tmp_path=None, width=256, version="2.1.0"):
    folder = str(tmp_path) if tmp_path is not None else "/nonexistent"
    return mitsuba.parse(os.path.join(folder, "scene.xml"), width, text=f'<scene version="{version}">{body}</scene>')


SENSOR = """<sensor type="perspective"><float name="fov" value="{fov}"/>{axis}
  <transform name="to_world"><lookat origin="1, 2, 3" target="1, 2, 4" up="0, 1, 0"/></transform>
  <film type="hdrfilm"><integer name="width" value="{w}"/><integer name="height" value="{h}"/></film></sensor>"""


def test_camera_fov_axis_and_film_scaled_to_the_requested_width():
    s = parse(SENSOR.format(fov=45, axis='<string name="fov_axis" value="y"/>', w=1024, h=768))
    cam = s.camera
    assert (cam.width, cam.height, cam.source_size) == (256, 192, (1024, 768))
    assert cam.fov_deg == 45 and cam.fov_axis == "y"
    assert np.allclose(cam.matrix[:3, 3], [1, 2, 3]) and np.allclose(cam.matrix[:3, 2], [0, 0, 1])
    assert np.allclose(cam.matrix[:3, 0], [1, 0, 0])  # Mitsuba's lookat: +X = up x forward (the image's left)
    assert parse(SENSOR.format(fov=30, axis="", w=100, h=100), width=64).camera.fov_axis == "x"  # the default


def test_defaults_are_substituted():
    s = parse('<default name="resx" value="800"/><default name="resy" value="400"/>'
              + SENSOR.format(fov=30, axis="", w="$resx", h="$resy")
              + '<integrator type="path"><integer name="max_depth" value="$d"/></integrator>'
              .replace("$d", "9"))
    assert (s.camera.width, s.camera.height) == (256, 128)
    assert s.max_bounces == 8  # Mitsuba's max_depth counts the segments of a path: 9 -> 8 bounces


def test_transform_steps_apply_in_order():
    warnings = []
    import xml.etree.ElementTree as ET
    m = mitsuba.parse_transform(ET.fromstring(
        '<transform name="to_world"><scale x="2"/><rotate y="1" angle="90"/><translate x="1" y="2" z="3"/>'
        '</transform>'), warnings)
    p = m @ [1.0, 0.0, 0.0, 1.0]  # scale -> (2,0,0); rotate 90 about y -> (0,0,-2); translate
    assert np.allclose(p[:3], [1, 2, 1]) and not warnings
    m = mitsuba.parse_transform(ET.fromstring('<transform><matrix value="1 0 0 5 0 1 0 6 0 0 1 7 0 0 0 1"/>'
                                              '<scale value="3"/></transform>'), warnings)
    assert np.allclose(m @ [1.0, 1.0, 1.0, 1.0], [18, 21, 24, 1])


def test_materials_map_to_principled_and_approximations_name_their_element():
    s = parse("""
      <bsdf type="twosided" id="Red"><bsdf type="diffuse"><rgb name="reflectance" value="0.5, 0.1, 0.1"/></bsdf></bsdf>
      <bsdf type="roughconductor" id="Metal"><float name="alpha" value="0.09"/>
         <rgb name="eta" value="0.2, 0.2, 0.2"/><rgb name="k" value="3, 3, 3"/></bsdf>
      <bsdf type="twosided" id="Wood"><bsdf type="roughplastic"><float name="alpha" value="0.25"/>
         <rgb name="diffuse_reflectance" value="0.3, 0.2, 0.1"/></bsdf></bsdf>
      <bsdf type="dielectric" id="Glass"><float name="int_ior" value="1.33"/></bsdf>
      <bsdf type="bumpmap" id="Bumpy"><bsdf type="diffuse"/></bsdf>
      <bsdf type="hair" id="Odd"/>
      <shape type="rectangle"><ref id="Red"/></shape>
      <shape type="rectangle"><ref id="Metal"/></shape>
      <shape type="cube"><ref id="Wood"/></shape>
      <shape type="sphere"><float name="radius" value="2"/><ref id="Glass"/></shape>
      <shape type="disk"><ref id="Bumpy"/></shape>
      <shape type="disk"><ref id="Odd"/></shape>""")
    red, metal, wood, glass, bumpy, odd = (sh.material for sh in s.shapes)
    assert red.base_color == (0.5, 0.1, 0.1) and red.roughness == 1 and red.metallic == 0 and red.specular == 0
    f0 = ((0.2 - 1) ** 2 + 9) / ((0.2 + 1) ** 2 + 9)  # normal-incidence Fresnel of eta 0.2, k 3
    assert metal.metallic == 1 and metal.roughness == pytest.approx(0.3) and metal.base_color[0] == pytest.approx(f0)
    assert wood.base_color == pytest.approx((0.3, 0.2, 0.1)) and wood.roughness == pytest.approx(0.5)
    assert glass.transmission == 1 and glass.ior == pytest.approx(1.33 / 1.000277)
    assert np.allclose(s.shapes[3].matrix[:3, :3], 2 * np.eye(3))  # sphere radius into the matrix
    w = "\n".join(s.warnings)
    assert 'bsdf id="Metal" type="roughconductor": approximated as metallic' in w
    assert 'bsdf id="Wood" type="twosided" > bsdf type="roughplastic": approximated' in w
    assert 'bsdf id="Glass" type="dielectric": approximated' in w
    assert 'bsdf id="Bumpy" type="bumpmap": bump map is not supported' in w
    assert 'bsdf id="Odd" type="hair": BSDF type is not supported' in w
    assert not any("Red" in line for line in s.warnings)  # an exact mapping says nothing


def test_textures_checkerboard_and_bitmap(tmp_path):
    s = parse("""<shape type="rectangle"><bsdf type="diffuse"><texture name="reflectance" type="bitmap">
        <string name="filename" value="tex/a.jpg"/></texture></bsdf></shape>
      <shape type="rectangle"><bsdf type="diffuse"><texture name="reflectance" type="checkerboard">
        <rgb name="color0" value="0.8"/><rgb name="color1" value="0.2"/>
        <transform name="to_uv"><scale x="20" y="80"/></transform></texture></bsdf></shape>""", tmp_path)
    bitmap, checker = (sh.material.texture for sh in s.shapes)
    assert bitmap.kind == "bitmap" and bitmap.filename == os.path.join(str(tmp_path), "tex/a.jpg")
    assert checker.kind == "checkerboard" and checker.uv_scale == pytest.approx((20, 80))
    assert checker.color0 == pytest.approx((0.8,) * 3) and s.shapes[1].material.base_color == pytest.approx((0.5,) * 3)


def test_emitters_lights_and_environment(tmp_path):
    (tmp_path / "m.obj").write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n")
    s = parse("""
      <emitter type="area" id="lamp"><rgb name="radiance" value="5, 4, 3"/></emitter>
      <shape type="obj"><string name="filename" value="m.obj"/><ref id="lamp"/></shape>
      <shape type="rectangle"><emitter type="area"><spectrum name="radiance" value="7"/></emitter></shape>
      <shape type="obj"><string name="filename" value="gone.obj"/></shape>
      <emitter type="point"><point name="position" value="1, 2, 3"/><rgb name="intensity" value="10"/></emitter>
      <emitter type="spot"><float name="cutoff_angle" value="30"/><rgb name="intensity" value="2"/></emitter>
      <emitter type="envmap"><string name="filename" value="sky.exr"/><float name="scale" value="2"/></emitter>
      <emitter type="sunsky" id="sun"/>""", tmp_path)
    assert [sh.kind for sh in s.shapes] == ["obj", "rectangle"]
    assert np.allclose(s.shapes[0].radiance, [5, 4, 3]) and np.allclose(s.shapes[1].radiance, 7)
    point, spot = s.lights
    assert np.allclose(point.position, [1, 2, 3]) and np.allclose(point.intensity, 10)
    assert spot.cutoff_deg == 30 and spot.beam_width_deg == pytest.approx(22.5)
    assert s.environment.kind == "envmap" and s.environment.scale == 2
    w = "\n".join(s.warnings)
    assert 'shape type="obj" filename="gone.obj": mesh file gone.obj is missing' in w
    assert 'emitter id="sun" type="sunsky": emitter type is not supported' in w
    assert 'emitter type="spot": spot falloff approximated' in w
    assert "no perspective <sensor>" in w
    assert parse('<emitter type="constant"><rgb name="radiance" value="0.5"/></emitter>').environment.kind \
        == "constant"


def test_instances_of_shape_groups(tmp_path):
    (tmp_path / "m.obj").write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n")
    s = parse("""<shape type="shapegroup" id="g"><shape type="obj"><string name="filename" value="m.obj"/></shape>
      </shape>
      <shape type="instance"><ref id="g"/><transform name="to_world"><translate x="5"/></transform></shape>
      <shape type="instance" id="var_x"><ref id="g"/><vector name="min_bounds" value="0, 0.3, 0"/></shape>""",
              tmp_path)
    assert [sh.matrix[:3, 3].tolist() for sh in s.shapes] == [[5, 0, 0], [0, 0.3, 0]]
    assert any(line.startswith('shape id="var_x" type="instance": randomised instance') for line in s.warnings)


def test_not_a_scene_is_one_clear_error(tmp_path):
    with pytest.raises(mitsuba.MitsubaError, match="not <scene>"):
        mitsuba.parse("x.xml", text="<film/>")
    with pytest.raises(mitsuba.MitsubaError, match="not a readable XML"):
        mitsuba.parse(str(tmp_path / "none.xml"))


def test_obj_reader_polygons_uvs_normals_and_relative_indices(tmp_path):
    path = tmp_path / "q.obj"
    path.write_text("o q\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\n"
                    "f 1/1/1 2/2/1 3/3/1 4/4/1\nf -4/-4/-1 -2/-2/-1 -1/-1/-1\n")
    m = wavefront.read_obj(str(path))
    assert m.face_sizes.tolist() == [4, 3] and m.triangle_count == 3
    assert m.corner_vertex.tolist() == [0, 1, 2, 3, 0, 2, 3]
    assert np.allclose(m.corner_uv[5], [1, 1]) and np.allclose(m.corner_normal, [0, 0, 1])
    path.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1//1 2 3\n")
    assert wavefront.read_obj(str(path)).corner_uv is None


def test_spectra_to_rgb():
    assert np.allclose(mitsuba.spectrum_to_rgb([400, 700], [0.6, 0.6]), 0.6, atol=0.01)
    red = mitsuba.spectrum_to_rgb([400, 580, 600, 700], [0.05, 0.05, 0.6, 0.6])
    assert red[0] > 0.4 and red[1] < 0.2 and red[2] < 0.1


@NEED_SHARED
def test_cornell_measured_data():
    s = cornell_measured.parse(str(SHARED / "cornell_box_measured"))
    by_name = {sh.name: sh for sh in s.shapes}
    light = by_name["Light"]
    # the measured light spectrum comes out near the RGB everyone uses, (17, 12, 4)
    assert light.radiance == pytest.approx([17.2, 11.5, 3.0], abs=0.3)
    red, green = by_name["left_wall_red"].material.base_color, by_name["right_wall_green"].material.base_color
    assert red[0] > 5 * red[1] and green[1] > 3 * green[0] and by_name["floor"].material.base_color[0] > 0.7
    assert (s.camera.width, s.camera.height) == (256, 256) and s.camera.fov_deg == pytest.approx(39.3077, abs=1e-3)
    assert np.allclose(s.camera.matrix[:3, 3], [0.278, 0.273, -0.8])
    assert len(by_name["tall_block"].polygons[1]) == 5 and light.polygons[0][:, 1].max() == pytest.approx(548.3)


@NEED_SHARED
def test_real_scenes_parse_and_say_what_is_missing():
    ajar = mitsuba.parse(str(SHARED / "veach_ajar_bitterli_partial" / "scene.xml"))
    assert len(ajar.shapes) == 16 and sum(sh.radiance is not None for sh in ajar.shapes) == 1
    missing = [w for w in ajar.warnings if "is missing; shape skipped" in w]
    assert len(missing) == 6 and all(w.startswith('shape type="obj" filename="meshes/Mesh00') for w in missing)
    living = mitsuba.parse(str(SHARED / "living_room_bitterli" / "scene.xml"))
    assert living.environment.kind == "envmap" and living.environment.filename.endswith("Sky 19.exr")
    assert living.camera.fov_deg == 90 and living.max_bounces == 8
    for w in ajar.warnings + living.warnings:  # every warning starts with the element it is about
        assert w.split(":")[0].split()[0] in ("bsdf", "shape", "emitter", "sensor", "scene"), w


# --- through bpy -----------------------------------------------------------------------------------------------

@pytest.mark.blender
@NEED_SHARED
def test_cornell_measured_converts_to_blender_and_extracts(ext, tmp_path):
    import bpy
    shared_scenes = importlib.import_module(f"{ext.__name__}.importers.shared_scenes")
    extract = importlib.import_module(f"{ext.__name__}.operators.scene.extract")
    out = tmp_path / "cornell.blend"
    written, _ = shared_scenes.convert(str(SHARED), "cornell_measured", str(out))
    assert written and out.is_file()
    assert shared_scenes.convert(str(SHARED), "cornell_measured", str(out)) == (False, [])  # fingerprint current
    bpy.ops.wm.open_mainfile(filepath=str(out))
    scene = bpy.context.scene
    assert (scene.render.resolution_x, scene.render.resolution_y) == (256, 256)
    cam = scene.camera
    assert np.allclose(cam.matrix_world.translation, [0.278, 0.8, 0.273], atol=1e-6)  # Y up -> Z up
    assert np.allclose(np.array(cam.matrix_world.to_3x3()) @ [0, 0, -1.0], [0, -1, 0], atol=1e-6)  # Mitsuba's +z
    assert math.degrees(cam.data.angle_x) == pytest.approx(39.3077, abs=1e-3)
    lamp = bpy.data.objects["Light"]
    assert lamp.type == "LIGHT" and lamp.data.type == "AREA"
    area = 0.13 * 0.105
    radiance = np.array(lamp.data.color) * lamp.data.energy / (math.pi * area)
    assert radiance == pytest.approx([17.2, 11.5, 3.0], abs=0.3)
    assert np.allclose(np.array(lamp.matrix_world.to_3x3()) @ [0, 0, -1.0], [0, 0, -1], atol=1e-6)  # shines down
    assert lamp.matrix_world.translation.z == pytest.approx(0.5483, abs=1e-6)
    got, warnings = extract.extract(bpy.context.evaluated_depsgraph_get())
    assert not warnings
    assert len(got.triangles) == 2 * 15  # 5 room quads + 5 per block; the light is a lamp, not a mesh
    assert len(got.lights) == 1
    assert got.lights[0].power == pytest.approx(np.array(lamp.data.color) * lamp.data.energy, rel=1e-5)
    white = bpy.data.materials["White"].node_tree.nodes["Principled BSDF"].inputs
    assert white["Roughness"].default_value == 1 and white["Specular IOR Level"].default_value == 0


@pytest.mark.blender
def test_envmap_reads_the_texel_mitsuba_reads(ext, tmp_path):
    """A lat-long map whose texels encode their own (u, v), rotated by a to_world: Cycles, looking along a few
    directions through the converted world, sees the texel Mitsuba's envmap lookup gives for that direction."""
    import OpenEXR
    import tempfile
    shared_scenes = importlib.import_module(f"{ext.__name__}.importers.shared_scenes")
    read_passes = importlib.import_module(f"{ext.__name__}.vpl_addon.core.exr").read_passes
    render_to = importlib.import_module(f"{ext.__name__}.operators.output.render_file").render_to
    from mathutils import Vector
    h, w = 32, 64
    v, u = np.mgrid[0:h, 0:w]
    img = np.stack([(u + 0.5) / w, (v + 0.5) / h, np.full((h, w), 0.25)], -1).astype(np.float32)
    path = str(tmp_path / "sky.exr")
    OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}, {"RGB": img}).write(path)
    to_world = mitsuba._rotation([0.3, 1.0, 0.2], 70.0)
    data = mitsuba.MitsubaScene(path, mitsuba.Camera(np.eye(4), 1.0, "x", 4, 4, (4, 4)),
                                environment=mitsuba.Environment("envmap", filename=path, matrix=to_world,
                                                                element='emitter type="envmap"'))
    scene, warnings = shared_scenes.build(data, samples=4)
    assert not any("envmap" in line for line in warnings)
    extract = importlib.import_module(f"{ext.__name__}.operators.scene.extract")
    found = []
    constant, environment = extract._world(scene, found)  # VPL GI renders the map itself, rotated as Cycles does
    assert not found and environment is not None and environment.image.shape[2] == 3
    # the importer's Vector-type Mapping, whose lookups the Cycles render below checks against Mitsuba's
    assert np.allclose(environment.rotation, shared_scenes.envmap_rotation(to_world), atol=1e-6)
    bg = scene.world.node_tree.nodes["Background"]
    mean = np.array(bg.inputs["Color"].default_value[:3]) * bg.inputs["Strength"].default_value
    # kept in the unlinked colour: the solid-angle mean (v is symmetric about the horizon, so its mean is 1/2)
    assert mean == pytest.approx([0.5, 0.5, 0.25], rel=2e-3)
    assert np.allclose(scene.world["vpl_gi_mean_radiance"], mean)
    scene.render.film_transparent = False
    scene.cycles.pixel_filter_type = "BOX"
    scene.camera.data.lens = 3000.0  # a pencil of rays around the view direction
    rot_inv = np.linalg.inv(to_world[:3, :3])
    for d in ([0.6, 0.3, 0.5], [-0.2, 0.7, 0.3], [-0.5, -0.6, 0.4], [0.3, -0.5, -0.6]):
        d_blender = np.array(d) / np.linalg.norm(d)
        scene.camera.matrix_world = Vector(d_blender).to_track_quat("-Z", "Z").to_matrix().to_4x4()
        with tempfile.TemporaryDirectory() as tmp:
            render_to(scene, os.path.join(tmp, "x.exr"))
            got = read_passes(os.path.join(tmp, "x.exr"))[0]["Combined"][..., :2].mean((0, 1))
        local = rot_inv @ (shared_scenes.C[:3, :3].T @ d_blender)  # Mitsuba world, then the map's local frame
        want = [(math.atan2(local[0], -local[2]) / (2 * math.pi)) % 1.0, math.acos(local[1]) / math.pi]
        assert got == pytest.approx(want, abs=1.5 / h), d


def test_color_divided_passes_leave_out_pixels_without_diffuse_colour():
    """Cycles writes Diffuse Direct/Indirect = 0 where Diffuse Color is 0 (a metal floor): those pixels are not
    compared, or a correct engine value there would count as an error of 100 times the mean."""
    from vpl_addon.evaluation.metrics import errors, pass_mask
    ref_color = np.ones((2, 2, 3))
    ref_color[0, 0] = 0.0  # metal
    reference = {"Diffuse Color": ref_color, "Diffuse Indirect": np.where(ref_color > 0, 0.5, 0.0)}
    mine = np.full((2, 2, 3), 0.5)
    full = np.ones((2, 2), bool)
    assert pass_mask("Combined", reference, full).all()
    kept = pass_mask("Diffuse Indirect", reference, full)
    assert kept.sum() == 3 and not kept[0, 0]
    assert errors(mine, reference["Diffuse Indirect"], kept)["rmae"] == 0.0
    assert errors(mine, reference["Diffuse Indirect"], full)["rmae"] > 10


def test_scenes_command_bad_input_is_one_line(tmp_path):
    from conftest import run_cli
    from test_cli import assert_one_line_error
    code, _, stderr = run_cli("scenes", "--source", tmp_path / "nowhere", "--out", tmp_path)
    assert_one_line_error(code, stderr, "no such folder")
    code, _, stderr = run_cli("scenes", "kitchen", "--source", tmp_path, "--out", tmp_path)
    assert_one_line_error(code, stderr, "unknown scene 'kitchen'")
