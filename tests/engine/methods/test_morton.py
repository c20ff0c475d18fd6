"""The Morton curve (``methods.vbnl.morton``): points near in its order are near in space."""
import numpy as np

from vpl_addon.methods.vbnl.morton import morton_codes, radix_tree


def morton_order(points):
    return np.argsort(morton_codes(points, (points.min(axis=0), points.max(axis=0))), kind="stable")


def test_the_morton_order_visits_each_octant_and_sub_octant_in_one_run():
    """A 16^3 grid in random order: every octant of the box, and every octant of those, is one run of the order;
    consecutive points are 1.5 cells apart on average (in the random order 10.5)."""
    rng = np.random.default_rng(1)
    grid = np.stack(np.meshgrid(*[np.arange(16.0)] * 3, indexing="ij"), -1).reshape(-1, 3)
    points = rng.permutation(grid) * 0.1 + 2.0
    ordered = points[morton_order(points)]
    index = np.rint((ordered - 2.0) / 0.1)
    for cells in (8, 4):
        octant = (index // cells) @ np.array([1, 16 // cells, (16 // cells) ** 2])
        assert np.count_nonzero(np.diff(octant)) == (16 // cells) ** 3 - 1
    steps = np.linalg.norm(np.diff(ordered, axis=0), axis=1) / 0.1
    assert steps.mean() < 2.0
    assert np.linalg.norm(np.diff(points, axis=0), axis=1).mean() / 0.1 > 5.0
    assert morton_codes(np.zeros((0, 3)), (np.zeros(3), np.ones(3))).shape == (0,)
    assert morton_order(np.ones((3, 3))).tolist() == [0, 1, 2]  # one point three times: a flat box, order kept


def test_codes_in_a_given_box_clamp_the_points_outside_it():
    """Codes in the scene's box (the light tree's): a point outside takes the code of the nearest point inside, the
    box's corners the least and the greatest codes."""
    box = (np.zeros(3), np.ones(3))
    codes = morton_codes(np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [2.0, -1.0, 0.5], [1.0, 0.0, 0.5]]), box)
    assert codes[0] == 0 and codes[1] == (1 << 63) - 1 and codes[2] == codes[3]


def test_the_radix_tree_splits_each_node_where_its_codes_first_differ():
    """Every internal node's codes share the bits above the one its split turns on (codes equal: halved by count),
    its children cover its range, and every code is one leaf."""
    rng = np.random.default_rng(2)
    code = np.sort(np.r_[rng.choice(1 << 20, 300, replace=False), [7, 7, 7]]).astype(np.uint64)
    lo, hi, mid, left, right = radix_tree(code)
    assert len(lo) == len(code) - 1 and lo[0] == 0 and hi[0] == len(code)
    leaves = []
    for k in range(len(lo)):
        a, b, m = lo[k], hi[k], mid[k]
        assert a < m < b
        diff = int(code[a] ^ code[b - 1])
        if diff:
            top = 1 << (diff.bit_length() - 1)
            assert not any(int(c) & top for c in code[a:m]) and all(int(c) & top for c in code[m:b])
        else:
            assert m == (a + b) // 2
        for child, first, last in ((left[k], a, m), (right[k], m, b)):
            if child < 0:
                assert last - first == 1 and -1 - child == first
                leaves.append(first)
            else:
                assert (lo[child], hi[child]) == (first, last)
    assert sorted(leaves) == list(range(len(code)))
