"""Morton (Z-order) codes: a point's leading bits name the octants of a box, one level after another, that hold it,
so points sorted by code are near their neighbours in the order, and the binary radix tree of the sorted codes is a
tree of boxes: the photon lights' tree down which the gather chooses a light (``virtual_light_sampling._descend``)."""
from __future__ import annotations

import numpy as np

from ...core.compiled import kernel

BITS = 21  # per axis: three of them fill a 63-bit code


def _spread(x: np.ndarray) -> np.ndarray:
    """The ``BITS`` low bits of each of ``x`` (uint64) moved to every third bit."""
    x = x & np.uint64((1 << BITS) - 1)
    for shift, mask in ((32, 0x1F00000000FFFF), (16, 0x1F0000FF0000FF), (8, 0x100F00F00F00F00F),
                        (4, 0x10C30C30C30C30C3), (2, 0x1249249249249249)):
        x = (x | (x << np.uint64(shift))) & np.uint64(mask)
    return x


def morton_codes(points: np.ndarray, box: tuple) -> np.ndarray:
    """(N,) uint64 Morton codes of ``points`` (N,3) in ``box`` = (lo, hi); points outside it are clamped to it."""
    points = np.asarray(points, np.float64).reshape(-1, 3)
    lo, hi = np.asarray(box[0], np.float64), np.asarray(box[1], np.float64)
    unit = np.clip((points - lo) / np.maximum(hi - lo, 1e-300), 0.0, 1.0)
    q = (unit * ((1 << BITS) - 1)).astype(np.uint64)
    return _spread(q[:, 0]) | (_spread(q[:, 1]) << np.uint64(1)) | (_spread(q[:, 2]) << np.uint64(2))


@kernel
def radix_tree(code):
    """The binary radix tree of the sorted ``code`` (N,), N >= 2, as its N - 1 internal nodes, the root first:
    (lo, hi, mid, left, right), node k holding the codes lo[k]:hi[k] and split at mid[k], where the highest bit
    in which its codes differ turns on (halved by count where they are equal); a child is an internal node's index,
    or -1 - i for the single code i."""
    n = len(code)
    lo, hi, mid = np.empty(n - 1, np.int64), np.empty(n - 1, np.int64), np.empty(n - 1, np.int64)
    left, right = np.empty(n - 1, np.int64), np.empty(n - 1, np.int64)
    lo[0], hi[0] = 0, n
    made = 1
    for k in range(n - 1):  # every node is made before it is split: nodes are numbered as they are made
        a, b = lo[k], hi[k] - 1
        diff = code[a] ^ code[b]
        if diff == 0:
            split = (a + b + 1) // 2
        else:
            bit = int(np.log2(np.float64(diff)))  # the highest differing bit (rounding may give one too many)
            if (diff >> np.uint64(bit)) == 0:
                bit -= 1
            top = np.uint64(1) << np.uint64(bit)
            while b - a > 1:  # code[a] lacks the bit, code[b] has it: the first with it
                m = (a + b) // 2
                if code[m] & top:
                    b = m
                else:
                    a = m
            split = b
        mid[k] = split
        for side, first, last in ((0, lo[k], split), (1, split, hi[k])):
            if last - first == 1:
                child = -1 - first
            else:
                child = made
                lo[made], hi[made] = first, last
                made += 1
            if side == 0:
                left[k] = child
            else:
                right[k] = child
    return lo, hi, mid, left, right
