"""The numbers a pixel's samples share (``core.sampling.pixel_nets``): one scrambled Sobol net per pixel, dealt to
its rows in random order, whatever order the rows come in; and keyed by the path (``core.sampling.PathNumbers``)."""
import numpy as np
import pytest

from vpl_addon.core.sampling import PathNumbers, pixel_nets


def _by_pixel(pixel, *arrays):
    order = np.argsort(pixel, kind="stable")
    return [a[order] for a in arrays]


def test_each_pixel_holds_a_net_whatever_the_rows_order():
    """16 rows a pixel in shuffled order: each pixel's 16 points put one in every elementary box of area 1/16
    (16 x 1, 8 x 2, 4 x 4, 2 x 8, 1 x 16), independent numbers would not."""
    rng = np.random.default_rng(1)
    pixel = rng.permutation(np.repeat(np.arange(200), 16))
    u, v = _by_pixel(pixel, *pixel_nets(pixel, 1, rng))
    u, v = u.reshape(200, 16), v.reshape(200, 16)
    assert np.all((u >= 0.0) & (u < 1.0) & (v >= 0.0) & (v < 1.0))
    for columns in (1, 2, 4, 8, 16):
        box = (u * columns).astype(int) * (16 // columns) + (v * (16 // columns)).astype(int)
        assert np.all(np.sort(box, axis=1) == np.arange(16))
    free = rng.random((200, 16))
    assert not np.all(np.sort((free * 16).astype(int), axis=1) == np.arange(16))


def test_nets_of_the_same_rows_are_independent_and_a_row_may_take_several():
    """Two nets for the same rows are uncorrelated, and a row's two numbers of one net as little as two of a
    pixel's 16 strata drawn without replacement (-1/15); a pixel's rows x per_row numbers are its net (8 rows x 2);
    a pixel with fewer rows takes distinct points of it."""
    rng = np.random.default_rng(2)
    pixel = np.repeat(np.arange(4000), 8)
    (u, _), (w, _) = pixel_nets(pixel, 1, rng), pixel_nets(pixel, 1, rng)
    assert abs(np.corrcoef(u[:, 0], w[:, 0])[0, 1]) < 0.03
    u, v = pixel_nets(pixel, 2, rng)
    assert u.shape == (len(pixel), 2)
    assert np.corrcoef(u[:, 0], u[:, 1])[0, 1] == pytest.approx(-1 / 15, abs=0.03)
    assert np.all(np.sort((u.reshape(4000, 16) * 16).astype(int), axis=1) == np.arange(16))
    short = np.r_[np.zeros(8, int), np.ones(3, int)]  # pixel 1 has 3 rows of a net of 8
    u, _ = pixel_nets(short, 1, rng)
    assert len(np.unique((u[8:, 0] * 8).astype(int))) == 3


def test_path_numbers_are_a_net_per_pixel_and_pair_and_keyed_by_the_path():
    """``PathNumbers``: each pixel's 16 paths hold a net in every pair of dimensions, at every depth and stream;
    a path's numbers are the same whichever other paths are asked for with it (so one path more or fewer changes
    no other path's numbers), and its pairs, depths, streams and branches are independent of each other."""
    rng = np.random.default_rng(3)
    pixel = rng.permutation(np.repeat(np.arange(500), 16))
    paths = PathNumbers(pixel, rng)
    every = np.arange(len(pixel))
    numbers = paths.numbers(5, every, 0, 0, 0)
    assert numbers.shape == (5, len(pixel)) and np.all((numbers >= 0.0) & (numbers < 1.0))
    order = np.argsort(pixel, kind="stable")
    for first in (0, 2):  # dimensions (0, 1) and (2, 3): each pixel's 16 points one in each 4 x 4 box
        box = (numbers[first] * 4).astype(int) * 4 + (numbers[first + 1] * 4).astype(int)
        assert np.all(np.sort(box[order].reshape(500, 16), axis=1) == np.arange(16))
    assert np.all(np.sort((numbers[4][order] * 16).astype(int).reshape(500, 16), axis=1) == np.arange(16))
    some = rng.choice(len(pixel), 1000, replace=False)
    np.testing.assert_array_equal(paths.numbers(5, some, 0, 0, 0), numbers[:, some])
    others = [paths.numbers(1, every, 0, 1, 0)[0], paths.numbers(1, every, 0, 0, 1)[0],
              paths.numbers(1, every, 1, 0, 0)[0], numbers[2], numbers[4]]
    for other in others:
        assert abs(np.corrcoef(numbers[0], other)[0, 1]) < 0.03
    other_block = PathNumbers(pixel, np.random.default_rng(4))  # another key: other numbers
    assert abs(np.corrcoef(other_block.numbers(1, every, 0, 0, 0)[0], numbers[0])[0, 1]) < 0.03
    assert pixel_nets(np.zeros(0, int), 2, rng)[0].shape == (0, 2)
    assert PathNumbers(np.zeros(0, int), rng).numbers(3, np.zeros(0, int), 0, 0, 0).shape == (3, 0)


def test_independent_path_numbers_are_keyed_uniform_and_uncorrelated():
    """``PathNumbers.independent``: keyed as the nets are (a subset of the paths gets the same numbers), uniform,
    and uncorrelated from one row to the next and with the nets' numbers."""
    rng = np.random.default_rng(5)
    pixel = np.repeat(np.arange(2000), 8)
    paths = PathNumbers(pixel, rng)
    every = np.arange(len(pixel))
    numbers = paths.independent(5, every, 0, 1, 3)
    assert numbers.shape == (5, len(pixel)) and np.all((numbers >= 0.0) & (numbers < 1.0))
    np.testing.assert_allclose(np.sort(numbers[2]), (np.arange(len(pixel)) + 0.5) / len(pixel), atol=0.02)
    some = np.arange(0, len(pixel), 5)
    np.testing.assert_array_equal(paths.independent(5, some, 0, 1, 3), numbers[:, some])
    for other in (numbers[1], numbers[4], paths.numbers(1, every, 0, 1, 3)[0], paths.independent(1, every, 1, 1, 3)[0]):
        assert abs(np.corrcoef(numbers[0], other)[0, 1]) < 0.03


def test_a_4d_net_stratifies_the_filter_and_the_lens_together():
    from vpl_addon.core.sampling import stratified_2d, stratified_4d
    rng = np.random.default_rng(1)
    points = np.stack(stratified_4d(50, 16, rng), axis=-1)  # (pixels, samples, 4)
    assert points.min() >= 0.0 and points.max() < 1.0
    halves = (points * 2).astype(int) @ [8, 4, 2, 1]
    assert all(len(set(row)) == 16 for row in halves)  # each of the 16 half-boxes of the 4D cube holds one point
    quarters = (points[..., :2] * 4).astype(int) @ [4, 1], (points[..., 2:] * 4).astype(int) @ [4, 1]
    assert all(len(set(row)) == 16 for q in quarters for row in q)  # and each pair is a 2D net
    # two 2D nets drawn at the same sample indices are one point set shifted twice: 4 of the 16 half-boxes
    apart = np.stack(stratified_2d(50, 16, rng) + stratified_2d(50, 16, rng), axis=-1)
    assert max(len(set(row)) for row in (apart * 2).astype(int) @ [8, 4, 2, 1]) == 4
    assert np.array_equal(np.stack(stratified_4d(3, 16, np.random.default_rng(2))),
                          np.stack(stratified_4d(3, 16, np.random.default_rng(2))))
