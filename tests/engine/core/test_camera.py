"""The camera (``core.camera``): Blender's sensor fit and shift, the pixel filter's tables and the offsets read from
them, rays through the image corners and through a thin lens."""
import numpy as np
import pytest

from vpl_addon.core.camera import Camera, filter_inverse_cdf, view_window

CAM = Camera(np.eye(4), 8, 8, view_window(8, 8, orthographic=False))


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
