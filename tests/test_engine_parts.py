"""Unit tests of the engine's parts: scene sanitising, camera, tracer, textures, metrics, EXR files."""
import os

import numpy as np
import pytest

from vpl_addon.core.camera import Camera, filter_inverse_cdf, view_window
from vpl_addon.core.exr import read_header, read_passes, write_passes
from vpl_addon.core.scene import Materials, Scene
from vpl_addon.core.tracer import Tracer
from vpl_addon.evaluation.metrics import clean_rrmse, coverage_mask, errors, noise_floor
from vpl_addon.materials.textures import sample_bilinear

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


@pytest.mark.parametrize("fit, w, h, expect", [
    ("AUTO", 320, 200, (-0.36, 0.36, -0.225, 0.225)),
    ("AUTO", 200, 320, (-0.225, 0.225, -0.36, 0.36)),
    ("HORIZONTAL", 200, 320, (-0.36, 0.36, -0.576, 0.576)),
    ("VERTICAL", 320, 200, (-0.384, 0.384, -0.24, 0.24)),
])
def test_view_window_follows_blender_sensor_fit(fit, w, h, expect):
    # lens 50 mm, sensor 36 x 24: half extent of the fitted side is sensor / (2 lens)
    assert np.allclose(view_window(w, h, orthographic=False, lens=50, sensor_width=36, sensor_height=24,
                                   sensor_fit=fit), expect)


def test_view_window_shift_is_a_fraction_of_the_fitted_side():
    x0, x1, y0, y1 = view_window(320, 200, orthographic=True, ortho_scale=4.0, shift_x=0.25, shift_y=-0.1)
    assert np.allclose([x0, x1], [-2 + 1.0, 2 + 1.0]) and np.allclose([y0, y1], [-1.25 - 0.4, 1.25 - 0.4])


@pytest.mark.parametrize("kind, width, support", [("BOX", 1.0, 0.5), ("BOX", 3.0, 0.5), ("BLACKMAN_HARRIS", 1.5, 1.5),
                                                  ("GAUSSIAN", 1.5, 2.25)])
def test_pixel_filter_tables_are_symmetric_and_within_support(kind, width, support):
    table = filter_inverse_cdf(kind, width)
    assert np.all(np.diff(table) >= 0)
    assert table[0] >= -support - 1e-9 and table[-1] <= support + 1e-9
    assert np.allclose(table, -table[::-1], atol=1e-6)


@pytest.mark.parametrize("kind", ["BOX", "BLACKMAN_HARRIS", "GAUSSIAN"])
def test_filter_offsets_read_the_table_linearly(kind):
    """The sub-pixel offsets are the filter's inverse CDF read linearly between its uniform steps, as np.interp
    reads it, at the ends and on the steps too; numbers past [0, 1] take the ends."""
    from dataclasses import replace
    camera = replace(CAM, filter_type=kind, filter_width=1.5)
    table = filter_inverse_cdf(kind, 1.5)
    u = np.concatenate([np.random.default_rng(1).random(5000), np.linspace(0.0, 1.0, len(table)), [-0.5, 1.5]])
    expected = np.interp(u, np.linspace(0.0, 1.0, len(table)), table)
    np.testing.assert_allclose(camera.filter_offsets(u), expected, rtol=0, atol=1e-12)


def test_perspective_rays_go_through_the_image_corners():
    o, d, _ = CAM.rays(np.array([0.0, 8.0]), np.array([0.0, 8.0]))
    x0, x1, y0, y1 = CAM.window
    assert np.allclose(d[0], np.array([x0, y1, -1]) / np.linalg.norm([x0, y1, -1]))  # top left
    assert np.allclose(d[1], np.array([x1, y0, -1]) / np.linalg.norm([x1, y0, -1]))  # bottom right


def test_a_thin_lens_sends_a_pixels_rays_from_all_over_its_aperture_to_one_point_of_the_plane_of_focus():
    from dataclasses import replace
    k = 4096
    u = np.random.default_rng(3).random((2, k))
    for ortho in (False, True):
        cam = replace(CAM, orthographic=ortho, aperture=0.05, focus=3.0)
        o, d, near = cam.rays(np.full(k, 2.3), np.full(k, 5.1), lens=(u[0], u[1]))
        pin_o, pin_d, _ = cam.rays(np.array([2.3]), np.array([5.1]))
        sharp = pin_o[0] + pin_d[0] * 3.0 / -pin_d[0, 2]  # where the pinhole ray meets the plane z = -3
        t = (-3.0 - o[:, 2]) / d[:, 2]
        assert np.allclose(o + d * t[:, None], sharp, atol=1e-9)
        lens = o - pin_o[0]
        assert np.allclose(lens[:, 2], 0.0) and np.linalg.norm(lens, axis=1).max() <= 0.05 + 1e-12
        assert abs(np.mean(np.linalg.norm(lens, axis=1) < 0.05 / np.sqrt(2)) - 0.5) < 0.03  # uniform over the disc
        if ortho:  # the near clip stays a plane
            assert np.allclose((o + d * near[:, None])[:, 2], -cam.clip_start, rtol=1e-9)
    # six blades: the regular hexagon, uniform (its inner disc of radius cos 30 deg holds pi cos^2 30 / area of it)
    cam = replace(CAM, aperture=1.0, blades=6, blade_rotation=0.3)
    x, y = cam.aperture_points(u[0], u[1])
    angle = np.arctan2(y, x) - 0.3
    edge = np.cos(np.pi / 6) / np.cos(((angle + np.pi / 6) % (np.pi / 3)) - np.pi / 6)  # its radius there
    assert (np.hypot(x, y) <= edge + 1e-12).all() and np.hypot(x, y).max() > 0.97
    inner = np.pi * np.cos(np.pi / 6) ** 2 / (1.5 * np.sqrt(3))
    assert abs(np.mean(np.hypot(x, y) < np.cos(np.pi / 6)) - inner) < 0.03
    x, y = replace(CAM, aperture=1.0, aperture_ratio=2.0).aperture_points(u[0], u[1])  # anamorphic: half as wide
    assert abs(x.max() - 0.5) < 0.02 and abs(y.max() - 1.0) < 0.02
    assert np.array_equal(replace(CAM, aperture=0.05).rays(np.array([1.0]), np.array([1.0]))[1],
                          CAM.rays(np.array([1.0]), np.array([1.0]))[1])  # no lens numbers: the pinhole's ray


def test_tracer_hits_misses_and_occludes():
    tri = np.array([[[-1, -1, 0], [1, -1, 0], [0, 1, 0]]], float)
    tracer = Tracer(tri, threads=2)
    o = np.array([[0, 0, 1], [5, 5, 1]], float)
    d = np.array([[0, 0, -1], [0, 0, -1]], float)
    hits = tracer.intersect(o, d)
    assert list(hits.prim) == [0, -1] and hits.t[0] == pytest.approx(1.0) and np.isinf(hits.t[1])
    assert list(tracer.occluded(o, d, np.array([2.0, 2.0]))) == [True, False]
    assert list(tracer.occluded(o, d, np.array([0.5, 0.5]))) == [False, False]
    tracer.close()


def test_tracer_splits_big_batches_over_threads_with_identical_results():
    rng = np.random.default_rng(0)
    tri = rng.random((500, 1, 3)) + rng.normal(size=(500, 3, 3)) * 0.05
    o = rng.random((200_000, 3)) * 2 - 0.5
    d = rng.normal(size=(200_000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    one, two = Tracer(tri, threads=1), Tracer(tri, threads=2)
    assert np.array_equal(one.intersect(o, d).prim, two.intersect(o, d).prim)
    assert two.rays_traced == 200_000
    two.close()


def test_empty_scene_traces_nothing():
    tracer = Tracer(np.zeros((0, 3, 3)))
    hits = tracer.intersect(np.zeros((3, 3)), np.tile([0, 0, 1.0], (3, 1)))
    assert (hits.prim == -1).all() and not tracer.occluded(np.zeros((3, 3)), np.tile([0, 0, 1.0], (3, 1)), 1).any()


@pytest.mark.parametrize("scale, offset", [(1e-4, 0.0), (1.0, 0.0), (1e4, 0.0), (1.0, 1e5)])
def test_offset_origin_escapes_the_surface_at_any_scale(scale, offset):
    """Rays leaving random points of a tilted triangle never hit that triangle again."""
    rng = np.random.default_rng(1)
    tri = (np.array([[[0, 0, 0], [1, 0.2, 0.1], [0.1, 1, 0.3]]]) * scale) + offset
    tracer = Tracer(tri, threads=1)
    b = rng.random((100_000, 2))
    b[b.sum(1) > 1] = 1 - b[b.sum(1) > 1]
    t = tri[0]
    p = t[0] + b[:, :1] * (t[1] - t[0]) + b[:, 1:] * (t[2] - t[0])
    n = np.cross(t[1] - t[0], t[2] - t[0])
    n /= np.linalg.norm(n)
    d = n + rng.normal(size=(100_000, 3)) * 0.7  # leaving through the front, grazing included
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    d[d @ n <= 0.01] = n
    origin = tracer.offset_origin(p, np.broadcast_to(n, p.shape))
    assert not tracer.occluded(origin, d, np.full(len(p), 10 * scale)).any()
    # and the push stays a few float32 steps, not a visible distance
    step = np.spacing(np.abs(p).max().astype(np.float32))
    assert np.linalg.norm(origin - p, axis=1).max() <= max(64 * step, 1e-3 * scale)


def test_bilinear_texture_lookup_repeats_and_interpolates():
    tex = np.zeros((2, 2, 3), np.float32)
    tex[0, 0] = 1.0  # bottom-left texel
    assert np.allclose(sample_bilinear(tex, np.array([[0.25, 0.25]])), 1.0)  # its centre
    assert np.allclose(sample_bilinear(tex, np.array([[1.25, -0.75]])), 1.0)  # repeated
    assert np.allclose(sample_bilinear(tex, np.array([[0.5, 0.25]])), 0.5)  # halfway to the next texel


def test_metrics_on_known_images():
    ref = np.ones((4, 4, 3))
    img = ref * 1.1
    e = errors(img, ref)
    assert e["mean_ratio"] == pytest.approx(1.1)
    assert e["rmae"] == pytest.approx(0.1 / 1.01)
    assert e["relmse"] == pytest.approx(0.01 / (1 + 1e-4))
    assert errors(ref, ref)["rmae"] == 0.0


def test_block_rmae_forgives_a_checkerboard_of_noise_but_not_a_bias_and_keeps_to_whole_blocks():
    """rmae4: a +-10 % checkerboard averages out in 4 x 4 blocks, a +10 % bias does not; a block the mask cuts is
    left out, and an image smaller than a block falls back to the pixels' rMAE."""
    ref = np.ones((8, 12, 3))
    checker = ref * (1.0 + 0.1 * ((np.indices((8, 12)).sum(axis=0) % 2) * 2 - 1))[..., None]
    assert errors(checker, ref)["rmae"] == pytest.approx(0.1 / 1.01)
    assert errors(checker, ref)["rmae4"] == pytest.approx(0.0, abs=1e-12)
    assert errors(ref * 1.1, ref)["rmae4"] == pytest.approx(0.1 / 1.01)
    img = ref.copy()
    img[0, 0] = 100.0
    mask = np.ones((8, 12), bool)
    mask[0, 0] = False  # the first block is not whole: left out
    assert errors(img, ref, mask)["rmae4"] == 0.0 and errors(img, ref)["rmae4"] > 1.0
    small = errors(ref[:2, :2] * 1.1, ref[:2, :2])
    assert small["rmae4"] == small["rmae"]


def test_clean_rrmse_takes_the_references_own_noise_out_and_keeps_an_images_error():
    """Two references with independent noise (sigma 0.3 of a mean of 1) stand for the truth: an image with noise
    0.1 of its own measures 0.1 where its RMSE against one reference is sqrt(0.1^2 + 0.3^2) = 0.32; the truth
    itself measures about 0 and a 10 % bias 0.1. One of the references scores 0: its noise is theirs, the case the
    metric leaves out (a renderer's image is independent of the references)."""
    rng = np.random.default_rng(7)
    truth = np.ones((256, 256, 3))
    a, b = (truth + rng.normal(0.0, 0.3, truth.shape) for _ in range(2))
    image = truth + rng.normal(0.0, 0.1, truth.shape)
    assert np.sqrt(np.mean((image - a) ** 2)) == pytest.approx(0.316, rel=0.02)
    assert clean_rrmse(image, a, b) == pytest.approx(0.1, rel=0.05)
    assert clean_rrmse(truth, a, b) < 0.01
    assert clean_rrmse(1.1 * truth, a, b) == pytest.approx(0.1, rel=0.05)
    assert clean_rrmse(a, a, b) < 1e-6
    mask = np.zeros((256, 256), bool)
    mask[:, :128] = True
    dark = image.copy()
    dark[:, 128:] = 0.0  # outside the mask: ignored
    assert clean_rrmse(dark, a, b, mask) == pytest.approx(0.1, rel=0.05)
    with pytest.raises(ValueError):
        clean_rrmse(image, a, b[:8])


def test_the_noise_floor_is_what_the_truth_scores_and_no_image_scores_less():
    """Two references with independent Gaussian noise (sigma 0.05 over an image ramping from 0.2 to 2): the truth
    scores the twin's rMAE over sqrt 2 against the reference (pixels and 4 x 4 blocks, and over a mask of the dim
    side, where the relative noise is twice the mean); images independent of the reference, the truth with noise of
    its own or 3 % too bright, score more; a render with the reference's noise scores sqrt 2 times the floor."""
    rng = np.random.default_rng(11)
    truth = np.repeat(np.linspace(0.2, 2.0, 256)[None, :, None], 256, axis=0) * np.ones((1, 1, 3))
    a, b = (truth + rng.normal(0.0, 0.05, truth.shape) for _ in range(2))
    floor = noise_floor(a, b)
    assert floor["rmae"] == pytest.approx(errors(truth, a)["rmae"], rel=0.02)
    assert floor["rmae4"] == pytest.approx(errors(truth, a)["rmae4"], rel=0.03)
    assert floor["rmae_bound"] == pytest.approx(floor["rmae"] / np.sqrt(2.0))
    assert errors(b, a)["rmae"] == pytest.approx(np.sqrt(2.0) * floor["rmae"])
    assert errors(truth + rng.normal(0.0, 0.02, truth.shape), a)["rmae"] > 1.05 * floor["rmae"]
    assert errors(1.03 * truth, a)["rmae"] > 1.1 * floor["rmae"]
    mask = np.zeros((256, 256), bool)
    mask[:, :64] = True
    dim = noise_floor(a, b, mask)["rmae"]
    assert dim > 2.0 * floor["rmae"] and dim == pytest.approx(errors(truth, a, mask)["rmae"], rel=0.03)


def test_metrics_ignore_pixels_the_reference_does_not_cover_fully():
    ref = np.ones((2, 2, 3))
    img = ref.copy()
    img[0, 0] = 100.0
    alpha = np.array([[0.5, 1.0], [1.0, 0.9995]])
    mask = coverage_mask(alpha, (2, 2))
    assert mask.sum() == 3 and errors(img, ref, mask)["rmae"] == 0.0


def test_exr_round_trip_with_attributes_and_no_partial_file(tmp_path):
    passes = {"Combined": np.random.rand(3, 5, 4).astype(np.float32),
              "Diffuse Direct": np.random.rand(3, 5, 3).astype(np.float32)}
    path = tmp_path / "x.exr"
    write_passes(str(path), passes, {"vplReference": '{"hash": "abc"}'})
    back, header = read_passes(str(path))
    assert header["vplReference"] == read_header(str(path))["vplReference"] == '{"hash": "abc"}'
    for name in passes:
        assert np.array_equal(back[name], passes[name])
    assert os.listdir(tmp_path) == ["x.exr"]
