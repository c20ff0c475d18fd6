"""``lightmap.lookup``: a map read at UV points as a texture unit reads it, and corners' values joined per vertex."""
import numpy as np

from vpl_addon.lightmap.lookup import lookup, per_vertex


def _ramp(height=4, width=8):
    """A map whose value is u in channel 0 and v in channel 1 at each texel centre (row 0 at v = 1)."""
    u = (np.arange(width) + 0.5) / width
    v = 1.0 - (np.arange(height) + 0.5) / height
    return np.stack(np.broadcast_arrays(u[None, :], v[:, None]), axis=-1)


def test_a_linear_map_is_read_exactly_between_texel_centres():
    uv = np.random.default_rng(0).uniform([1 / 16, 1 / 8], [15 / 16, 7 / 8], (200, 2))  # inside the centres
    assert np.allclose(lookup(_ramp(), uv), uv, atol=1e-12)


def test_texel_centres_read_their_own_texel():
    image = np.random.default_rng(1).random((4, 8, 3))
    x, y = np.meshgrid(np.arange(8), np.arange(4))
    uv = np.stack([(x.ravel() + 0.5) / 8, 1.0 - (y.ravel() + 0.5) / 4], axis=1)
    assert np.allclose(lookup(image, uv), image[y.ravel(), x.ravel()])


def test_points_past_the_border_and_bad_uvs_read_the_border_texels():
    image = _ramp()
    got = lookup(image, np.array([[-3.0, 0.5], [2.0, 2.0], [np.nan, np.inf]]))
    assert np.isfinite(got).all()
    assert np.allclose(got[0], [1 / 16, 0.5]) and np.allclose(got[1], [15 / 16, 7 / 8])
    assert np.allclose(got[2], [1 / 16, 7 / 8])  # nan -> u 0, inf -> v 1


def test_a_vertex_holds_the_mean_of_its_corners():
    values = np.array([[1.0], [3.0], [5.0], [7.0]])
    assert np.allclose(per_vertex(values, np.array([0, 0, 2, 0]), 4), [[11 / 3], [0.0], [5.0], [0.0]])
