"""The compiled kernels of the gathers and the filter (issue 26) against the formulas they evaluate, written out
plainly on small inputs: the rewrite must give the numbers the numpy passes gave (to rounding)."""
import numpy as np
import pytest

from vpl_addon.gather.bilateral import NORMAL_POWER, PLANE_SIGMA, deinterleave


def guides(h, w, seed=0):
    """A small G-buffer with a depth step, a turn of the surface, jittered normals and holes."""
    rng = np.random.default_rng(seed)
    grid = np.stack(np.meshgrid(np.arange(w), np.arange(h)) + [np.zeros((h, w))], -1)
    position = 0.01 * grid + 0.002 * rng.normal(size=(h, w, 3))
    position[:, w // 2:, 2] += 0.3
    normal = rng.normal(size=(h, w, 3)) * 0.1 + [0.0, 0.0, 1.0]
    normal[h // 3:] = [1.0, 0.0, 0.0]
    normal /= np.linalg.norm(normal, axis=2, keepdims=True)
    valid = rng.random((h, w)) > 0.15
    footprint = 0.01 * (1.0 + rng.random((h, w)))
    return rng.random((h, w, 3)), position, normal, valid, footprint


def filtered_pixel(image, position, normal, valid, footprint, tile, y, x):
    """One pixel of the cross-bilateral filter, straight from its definition."""
    if not valid[y, x]:
        return image[y, x]
    h, w = valid.shape
    total, acc = 0.0, np.zeros(image.shape[2])
    for yy in range(y - tile, y + tile):
        for xx in range(x - tile, x + tile):
            if 0 <= yy < h and 0 <= xx < w and valid[yy, xx]:
                plane = normal[y, x] @ (position[yy, xx] - position[y, x]) / (PLANE_SIGMA * footprint[y, x])
                agree = np.clip(normal[y, x] @ normal[yy, xx], 0.0, 1.0) ** NORMAL_POWER
                total += np.exp(-plane * plane) * agree
                acc += np.exp(-plane * plane) * agree * image[yy, xx]
    return acc / total if total > 0.0 else image[y, x]


@pytest.mark.parametrize("threads", [1, 3])
@pytest.mark.parametrize("tile", [2, 4])
def test_filter_is_the_weighted_mean_of_its_window(tile, threads):
    """Every pixel of a 13 x 17 image (bands of rows on several threads or one) is the cross-bilateral mean."""
    inputs = guides(13, 17)
    out = deinterleave(*inputs, tile, threads=threads)
    expected = np.array([[filtered_pixel(*inputs, tile, y, x) for x in range(17)] for y in range(13)])
    np.testing.assert_allclose(out, expected, rtol=1e-9, atol=1e-12)


def test_filter_keeps_pixels_without_a_surface_or_weight():
    """Invalid pixels keep their value and give none; a pixel alone in its window keeps its own, and so does one
    that weighs every neighbour 0 (a zero normal: its samples' normals cancelled)."""
    image, position, normal, valid, footprint = guides(9, 9, seed=1)
    valid[:] = False
    valid[4, 4] = valid[0, 0] = valid[0, 1] = True
    normal[0, 0] = 0.0
    out = deinterleave(image, position, normal, valid, footprint, 4, threads=2)
    np.testing.assert_array_equal(out[[0, 4], [0, 4]], image[[0, 4], [0, 4]])
    np.testing.assert_array_equal(np.delete(out.reshape(81, 3), [0, 1, 40], axis=0),
                                  np.delete(image.reshape(81, 3), [0, 1, 40], axis=0))
    assert np.isfinite(out).all()


def test_filter_of_tile_one_is_the_image():
    image = guides(5, 6)[0]
    assert deinterleave(image, *guides(5, 6)[1:], 1) is image
