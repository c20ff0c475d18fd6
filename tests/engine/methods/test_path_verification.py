"""Light paths kept between frames and verified against moved objects (Moreau et al.), without Blender."""
import numpy as np
import pytest

from conftest import plane_scene
from vpl_addon.core.scene import Scene
from vpl_addon.core.tracer import Tracer
from vpl_addon.gather.summing import GatherSettings
from vpl_addon.lights import LightSet, PointLight
from vpl_addon.methods import MethodSettings
from vpl_addon.paths.light_paths import trace_until
from vpl_addon.render import RenderSettings, render
from vpl_addon.sequence.motion import Motion, Snapshot
from vpl_addon.sequence.path_verification import LightPathStore, PathRows, segments_crossing_boxes
from vpl_addon.sequence.state import SequenceState, frame_seed

BOX = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float)
FACES = [(0, 2, 1), (0, 3, 2), (4, 5, 6), (4, 6, 7), (0, 1, 5), (0, 5, 4), (1, 2, 6), (1, 6, 5), (2, 3, 7),
         (2, 7, 6), (3, 0, 4), (3, 4, 7)]


def test_segments_crossing_boxes():
    box = [(np.zeros(3), np.ones(3))]
    origin = np.array([[-1, 0.5, 0.5], [-1, 0.5, 0.5], [-1, 0.5, 0.5], [-1, 2.0, 0.5], [0.5, 0.5, 0.5],
                       [-1, 0.5, 0.5], [-1, 0.0, 0.5]])
    direction = np.array([[1, 0, 0], [1, 0, 0], [-1, 0, 0], [1, 0, 0], [0, 0, 1], [1, 0, 0], [1, 0, 0]], float)
    length = np.array([3.0, 0.5, np.inf, np.inf, 0.1, 1.0, 5.0])
    # through; stops short; points away; misses beside; starts inside; ends on the face; grazes the face y = 0
    assert segments_crossing_boxes(origin, direction, length, box).tolist() == [True, False, False, False, True,
                                                                              True, True]
    assert segments_crossing_boxes(origin, direction, length, []).tolist() == [False] * 7
    # a second box beside the first catches the ray that passed beside it; a margin the segment that stopped short
    beside = [box[0], (np.array([0.0, 1.5, 0.0]), np.array([1.0, 2.5, 1.0]))]
    crossing = segments_crossing_boxes(origin, direction, length, beside)
    assert crossing.tolist() == [True, False, False, True, True, True, True]
    assert segments_crossing_boxes(origin, direction, length, box, margin=0.6).tolist()[1] is True


def test_path_rows_find_each_path_and_bounce():
    rows = PathRows(np.array([3, 1, 2, 1]), np.array([1, 2, 1, 1]))
    assert rows.find(np.array([1, 1, 2, 3, 5, 1]), np.array([1, 2, 1, 1, 1, 3])).tolist() == [3, 1, 2, 0, -1, -1]
    assert PathRows(np.zeros(0, np.int64), np.zeros(0, np.int32)).find(np.array([1]), np.array([1])).tolist() == [-1]


def room_with_block(offset=0.0):
    """A floor and a back wall lit by a lamp, with a 0.4 m block (object "Block") standing at x = offset."""
    base = plane_scene([PointLight("lamp", [0, 0, 2.5], [300.0] * 3)], size=3, view=4.0, res=16)
    wall = np.array([[[-3, 2, 0], [3, 2, 0], [3, 2, 4]], [[-3, 2, 0], [3, 2, 4], [-3, 2, 4]]], float)
    block = (BOX * 0.4 + [offset - 0.2, 0.5, 0])[np.array(FACES)]
    tri = np.concatenate([base.triangles, wall, block])
    ids = [0, 0, 1, 1] + [2] * len(block)
    return Scene.build(tri, base.materials, base.lights, base.camera, object_id=ids,
                       object_names=["Floor", "Wall", "Block"], max_bounces=3)


def test_verification_retraces_only_paths_the_moved_block_cuts():
    before, after = room_with_block(0.0), room_with_block(0.3)
    motion = Motion.between(Snapshot.of(before), Snapshot.of(after))
    assert motion.moved_objects == ["Block"]
    store = LightPathStore()
    tracer = Tracer(before.triangles)
    store.trace(before, tracer, LightSet(before), 4000, np.random.default_rng(0), 3)
    full_rays, paths = store.rays_last_frame, store.paths
    tracer.close()
    tracer = Tracer(after.triangles)
    try:
        retraced = store.update(after, tracer, LightSet(after), motion.boxes, np.random.default_rng(1), 3, 1e-6,
                                threshold=0.0)
        assert 0 < retraced < paths / 4 and 0 < store.rays_last_frame < full_rays / 3
        assert store.paths == paths
        lo, hi = motion.boxes[1]
        on_new = ((store.vpls.position >= lo - 1e-6) & (store.vpls.position <= hi + 1e-6)).all(axis=1)
        assert on_new.any()  # the re-traced paths found the block where it is now
        lo, hi = motion.boxes[0]
        in_old = ((store.vpls.position >= lo + 1e-3) & (store.vpls.position <= hi - 1e-3)).all(axis=1)
        assert not (in_old & ~on_new).any()  # nothing floats where the block was
        assert len(np.unique(store.vpls.path)) <= paths and store.vpls.path.max() < paths
        assert store.update(after, tracer, LightSet(after), [], np.random.default_rng(2), 3) == 0
        assert store.rays_last_frame == 0
    finally:
        tracer.close()


def test_ir_in_a_sequence_reuses_paths_and_lights_like_a_full_retrace():
    """Frame 2 (the block moved): ir with path reuse traces a fraction of the rays of a full re-trace and lights
    the scene the same (the same mean within noise)."""
    settings = dict(samples=2, light_samples=0, method="ir", passes=("Combined", "Diffuse Indirect"),
                    gather=GatherSettings(interleave=1, clamp=0.0))
    results = {}
    for reuse in (True, False):
        state = SequenceState("ir")
        first = render(room_with_block(0.0), RenderSettings(**settings, seed=frame_seed(0, 1), placement=MethodSettings(
            vpls=3000, path_reuse=reuse)), sequence=state)
        second = render(room_with_block(0.3), RenderSettings(**settings, seed=frame_seed(0, 2),
                                                             placement=MethodSettings(vpls=3000, path_reuse=reuse)),
                        sequence=state)
        third = render(room_with_block(0.3), RenderSettings(**settings, seed=frame_seed(0, 3),
                                                            placement=MethodSettings(vpls=3000, path_reuse=reuse)),
                       sequence=state)
        assert third.info["light_paths"] == 0 and third.info["light_path_rays"] == 0  # nothing moved
        results[reuse] = (first, second)
        state.close()
    full = results[False][1].info
    reused = results[True][1].info
    assert full["light_paths"] == full["paths_kept"] and 0 < reused["light_paths"] < full["light_paths"]
    assert reused["light_path_rays"] * 3 < full["light_path_rays"]
    a = results[True][1].passes["Diffuse Indirect"]
    b = results[False][1].passes["Diffuse Indirect"]
    assert np.isfinite(a).all() and (a >= 0).all()
    assert a.mean() == pytest.approx(b.mean(), rel=0.1)


def room_with_lamp(x=0.0, power=300.0, radius=0.05):
    """room_with_block with its lamp a sphere of the given radius at (x, 0, 2.5)."""
    s = room_with_block(0.0)
    return Scene.build(s.triangles, s.materials, [PointLight("lamp", [x, 0, 2.5], [power] * 3, radius=radius)],
                       s.camera, object_id=s.object_id, object_names=s.object_names, max_bounces=3)


def test_paths_follow_a_moving_light_through_distribution_maps():
    """Sec. 3.1: a lamp moved by 0.1 m carries its paths' emission samples; the distribution map keeps each cell
    near its target; the result agrees with a full re-trace; a power change rescales without a ray; a static frame
    traces nothing."""
    from vpl_addon.sequence import distribution_map as dm
    a, b = room_with_lamp(0.0), room_with_lamp(0.1)
    assert Motion.between(Snapshot.of(a), Snapshot.of(b)).lights_changed
    ta, tb = Tracer(a.triangles), Tracer(b.triangles)
    try:
        store = LightPathStore()
        store.trace(a, ta, LightSet(a), 3000, np.random.default_rng(0), 3)
        paths = store.paths
        ids = set(store.segments["path"][store.segments["bounce"] == 1].tolist())
        assert store.update(b, tb, LightSet(b), [], np.random.default_rng(1), 3) is not None
        first = store.segments["bounce"] == 1
        lamp = store.emitters[0]
        assert np.allclose(np.linalg.norm(store.segments["origin"][first] - [0.1, 0, 2.5], axis=1), 0.05)
        kept = ids & set(store.segments["path"][first].tolist())
        assert len(kept) > 0.8 * len(ids) and store.paths == paths  # pruned and filled only a few
        counts = np.bincount(dm.cells(lamp, store.segments["origin"][first], store.segments["direction"][first]),
                             minlength=int(np.prod(dm.bins(lamp))))
        assert abs(counts.sum() - paths) < 0.05 * paths  # DM_C sums to DM_T's total
        fresh, _ = trace_until(b, tb, LightSet(b), 3000, np.random.default_rng(2), 3)
        assert store.vpls.intensity.sum() == pytest.approx(fresh.intensity.sum(), rel=0.03)
        for bounce in (2, 3):
            got = store.vpls.intensity[store.vpls.bounce == bounce].sum()
            assert got == pytest.approx(fresh.intensity[fresh.bounce == bounce].sum(), rel=0.15)
        assert store.update(b, tb, LightSet(b), [], np.random.default_rng(3), 3) == 0 and store.rays_last_frame == 0
        before = store.vpls.intensity.copy()
        brighter = room_with_lamp(0.1, power=600.0)
        assert store.update(brighter, tb, LightSet(brighter), [], np.random.default_rng(4), 3) == 0
        assert store.rays_last_frame == 0 and np.allclose(store.vpls.intensity, 2.0 * before)
        bigger = room_with_lamp(0.1, radius=0.2)  # a new shape: its paths are emitted again
        assert store.update(bigger, tb, LightSet(bigger), [], np.random.default_rng(5), 3) > 0.9 * paths
    finally:
        ta.close()
        tb.close()


def test_threshold_keeps_tails_that_reflect_the_same_energy():
    """Eq. 2 / Algorithm 1: with T = 0.1 % the block's move re-traces fewer paths than T = 0 (segments through its
    box that hit where they hit before keep their tails) and no more rays; both agree with each other per bounce."""
    before, after = room_with_block(0.0), room_with_block(0.3)
    motion = Motion.between(Snapshot.of(before), Snapshot.of(after))
    tb, ta = Tracer(before.triangles), Tracer(after.triangles)
    try:
        out = {}
        for threshold in (0.0, 1e-3):
            store = LightPathStore()
            store.trace(before, tb, LightSet(before), 4000, np.random.default_rng(0), 3)
            traced = store.update(after, ta, LightSet(after), motion.boxes, np.random.default_rng(1), 3, 1e-6,
                                  threshold)
            flux = [store.vpls.intensity[store.vpls.bounce == b].sum() for b in (1, 2, 3)]
            out[threshold] = traced, store.rays_last_frame, flux, store
        assert 0 < out[1e-3][0] < out[0.0][0] and out[1e-3][1] <= out[0.0][1]
        assert out[1e-3][2] == pytest.approx(out[0.0][2], rel=0.05)
        store = out[1e-3][3]
        lo, hi = motion.boxes[0]
        in_old = ((store.vpls.position >= lo + 1e-3) & (store.vpls.position <= hi - 1e-3)).all(axis=1)
        lo, hi = motion.boxes[1]
        on_new = ((store.vpls.position >= lo - 1e-6) & (store.vpls.position <= hi + 1e-6)).all(axis=1)
        assert not (in_old & ~on_new).any()  # nothing floats where the block was
    finally:
        ta.close()
        tb.close()


@pytest.mark.parametrize("method", ["bidir", "vbnl"])
def test_bidir_and_vbnl_keep_their_light_paths_in_the_same_store(method):
    """bidir's standard VPLs and vbnl's photons come from a LightPathStore too: the block's move traces a fraction
    of a full re-trace's light-path rays, and the frame stays finite and as bright."""
    from vpl_addon.methods.vbnl import VBNLSettings
    settings = dict(samples=1, light_samples=0, method=method, passes=("Diffuse Indirect",),
                    gather=GatherSettings(interleave=1, clamp=0.0))
    out = {}
    for reuse in (True, False):
        state = SequenceState(method)
        for frame, offset in ((1, 0.0), (2, 0.3)):
            placement = MethodSettings(vpls=300, path_reuse=reuse, vbnl=VBNLSettings(photons=8192))
            result = render(room_with_block(offset), RenderSettings(**settings, seed=frame_seed(0, frame),
                                                                    placement=placement), sequence=state)
        assert isinstance(state.method_state.paths, LightPathStore)
        out[reuse] = result
        state.close()
    assert out[True].info["light_path_rays"] * 3 < out[False].info["light_path_rays"]
    a, b = out[True].passes["Diffuse Indirect"], out[False].passes["Diffuse Indirect"]
    assert np.isfinite(a).all() and (a >= 0).all()
    assert a.mean() == pytest.approx(b.mean(), rel=0.15)
