"""``python -m vpl_addon lightmap`` with the real bpy module: one EXR per object with its time, a re-bake of some
objects that leaves the others' files alone, and each bad input answered in one line with nothing written."""
import os

import numpy as np
import pytest

from conftest import EXAMPLES, run_cli
from lightmap_scenes import dark_floor, read_map, uv_cornell
from test_cli import assert_one_line_error

pytestmark = pytest.mark.blender


@pytest.fixture(scope="module")
def box(ext, tmp_path_factory):
    import bpy
    return uv_cornell(bpy, tmp_path_factory.mktemp("lightmap") / "cornell_uv.blend")


def test_lightmap_writes_one_exr_per_object_with_its_time(box, tmp_path):
    code, stdout, stderr = run_cli("lightmap", box, "-o", tmp_path, "--objects", "Floor,TallBox", "--size", "32",
                                   "--uv-map", "Lightmap")
    assert code == 0, stderr
    for name in ("Floor", "TallBox"):
        line = next(l for l in stdout.splitlines() if l.startswith(f"wrote {tmp_path / name}.exr"))
        assert line.endswith(" s") and "32x32 Diffuse Indirect" in line
        image = read_map(tmp_path / f"{name}.exr")
        assert image.shape == (32, 32, 4) and np.isfinite(image).all() and (image >= 0).all()
        assert 0.0 < image[..., :3].mean() and (image[..., 3] <= 1.0).all()
    assert sorted(os.listdir(tmp_path)) == ["Floor.exr", "TallBox.exr"]  # no partial files left
    assert "VPLs placed for 2 objects" in stdout


def test_rebaking_some_objects_leaves_the_others_files_alone(box, tmp_path):
    code, _, stderr = run_cli("lightmap", box, "-o", tmp_path, "--objects", "Floor,ShortBox", "--size", "16")
    assert code == 0, stderr
    kept = tmp_path / "ShortBox.exr"
    before = (kept.stat().st_ino, kept.read_bytes())
    code, stdout, stderr = run_cli("lightmap", box, "-o", tmp_path, "--objects", "Floor", "--size", "16",
                                   "--pass", "Diffuse Direct")
    assert code == 0, stderr
    assert (kept.stat().st_ino, kept.read_bytes()) == before


def test_a_texel_density_sizes_each_map_by_its_object(box, tmp_path):
    """At 40 texels a metre the floor (4 m^2 in 99 % of its map: 80 texels a side) gets 64 x 64 texels and the tall
    box (3.6 m^2 in 61 %: 98) 128 x 128, each file as large as its line says; ``--size`` is not used."""
    code, stdout, stderr = run_cli("lightmap", box, "-o", tmp_path, "--objects", "Floor,TallBox", "--size", "16",
                                   "--texel-density", "40", "--uv-map", "Lightmap")
    assert code == 0, stderr
    sizes = {}
    for name in ("Floor", "TallBox"):
        line = next(l for l in stdout.splitlines() if l.startswith(f"wrote {tmp_path / name}.exr"))
        sizes[name] = int(line.split(": ")[1].split("x")[0])
        assert read_map(tmp_path / f"{name}.exr").shape == (sizes[name], sizes[name], 4)
    assert sizes == {"Floor": 64, "TallBox": 128}


@pytest.mark.parametrize("flags, words", [
    (("--size", "0"), ("--size 0", "between 1 and 16384")),
    (("--size", "16385"), ("--size 16385",)),
    (("--pass", "Glossy"), ("--pass", "Diffuse Indirect")),
    (("--texel-density", "0"), ("--texel-density 0.0", "positive")),
    (("--objects", "Camera"), ("'Camera'", "not a mesh")),
    (("--objects", "Nothing"), ("no object 'Nothing'",)),
    (("--uv-map", "Nope"), ("no UV map 'Nope'", "Lightmap")),
])
def test_bad_input_is_one_line_and_nothing_is_written(box, tmp_path, flags, words):
    out = tmp_path / "maps"
    code, _, stderr = run_cli("lightmap", box, "-o", out, *flags)
    assert_one_line_error(code, stderr, *words)
    assert not out.exists()


def test_an_object_without_a_uv_map_is_named(tmp_path):
    code, _, stderr = run_cli("lightmap", EXAMPLES / "cornell_area.blend", "-o", tmp_path / "maps")
    assert_one_line_error(code, stderr, "has no UV map", "Smart UV Project")
    assert not (tmp_path / "maps").exists()


def test_a_scene_without_lights_bakes_black_maps_and_says_so_once(ext, tmp_path):
    import bpy
    blend = dark_floor(bpy, tmp_path / "dark.blend")
    code, stdout, stderr = run_cli("lightmap", blend, "-o", tmp_path / "maps", "--size", "8", "--pass", "Diffuse")
    assert code == 0, stderr
    assert stderr.count("no lights") == 1
    image = read_map(tmp_path / "maps" / "Floor.exr")
    assert image[..., :3].max() == 0.0 and image[..., 3].min() == 1.0
