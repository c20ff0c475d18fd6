"""The ray tracer (``core.tracer``): hits, misses and occlusion, big batches split over threads, an empty scene,
origins offset off a surface at any scale, and the time its callers wait on embree, per thread."""
import threading

import numpy as np
import pytest

from vpl_addon.core.tracer import Tracer


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


def test_each_thread_counts_its_own_wait_on_embree():
    """``waited`` is the calling thread's time in embree calls, and ``embree_seconds`` all threads' together: a
    thread that traces nothing has waited nothing, whatever the others trace."""
    rng = np.random.default_rng(1)
    tracer = Tracer(rng.random((200, 3, 3)), threads=2)
    o, d = rng.random((100_000, 3)), rng.normal(size=(100_000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    seen = {}

    def work(name, rays):
        for _ in range(rays):
            tracer.intersect(o, d)
            tracer.occluded(o, d, np.ones(len(o)))
        seen[name] = tracer.waited()
    threads = [threading.Thread(target=work, args=(name, rays)) for name, rays in (("tracing", 3), ("idle", 0))]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert seen["idle"] == 0.0 < seen["tracing"] == tracer.embree_seconds and tracer.waited() == 0.0
    tracer.close()


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
