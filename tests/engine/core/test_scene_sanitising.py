"""The scene as the engine takes it (``core.scene``): triangles that are degenerate or not finite are dropped and
their object named, bad shading normals and UVs fall back, material values are clamped to their ranges."""
import numpy as np

from vpl_addon.core.camera import Camera, view_window
from vpl_addon.core.scene import Materials, Scene

CAM = Camera(np.eye(4), 8, 8, view_window(8, 8, orthographic=False))


def test_scene_drops_degenerate_and_nonfinite_triangles_and_names_their_object():
    tri = np.array([
        [[0, 0, 0], [1, 0, 0], [0, 1, 0]],  # fine
        [[0, 0, 0], [1, 0, 0], [2, 0, 0]],  # collinear: zero area
        [[0, 0, 0], [0, 0, 0], [0, 0, 0]],  # collapsed
        [[0, 0, 0], [np.nan, 0, 0], [0, 1, 0]],  # NaN corner
    ], float)
    scene = Scene.build(tri, Materials.make([]), [], CAM, object_id=[0, 1, 1, 1], object_names=["good", "bad"])
    assert len(scene.triangles) == 1
    assert scene.dropped == {"bad": 3}


def test_bad_shading_normals_and_uvs_fall_back():
    tri = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]]], float)
    normals = np.array([[[0, 0, 0], [np.nan, 0, 1], [0, 0, 2]]], float)
    uvs = np.array([[[np.inf, 0], [0, np.nan], [0.5, 0.5]]])
    scene = Scene.build(tri, Materials.make([]), [], CAM, normals=normals, uvs=uvs)
    assert np.allclose(scene.normals[0], [[0, 0, 1]] * 3)
    assert np.isfinite(scene.uvs).all()


def test_material_values_are_clamped_to_their_ranges():
    m = Materials.make([{"name": "x", "base_color": (2, -1, np.nan), "roughness": 3, "emission": (np.inf, -1, 1)}])
    assert np.allclose(m.base_color[1], [1, 0, 0]) and m.roughness[1] == 1
    assert np.allclose(m.emission[1], [0, 0, 1])
