"""Sequences without Blender: motion between frames, the static-frame rule, the state's persistence."""
import io
import json
import pickle

import numpy as np
import pytest

from conftest import plane_scene
from vpl_addon.core.scene import Scene
from vpl_addon.gather.summing import GatherSettings
from vpl_addon.core.scene import Environment, Materials
from vpl_addon.lights import AreaLight, PointLight, SpotLight, SunLight
from vpl_addon.methods import METHODS, MethodSettings
from vpl_addon.methods.smc import SMCSettings
from vpl_addon.methods.vbnl import VBNLSettings
from vpl_addon.render import RenderSettings, render
from vpl_addon.sequence.motion import Motion, Snapshot
from vpl_addon.sequence.persisted import pack
from vpl_addon.sequence.state import STATE_FORMAT, SequenceState, frame_seed

WALL = np.array([[[-5, 1, 0], [5, 1, 0], [5, 1, 5]], [[-5, 1, 0], [5, 1, 5], [-5, 1, 5]]], float)


def lamp_scene(light_at=(0, 0.5, 1), wall_shift=0.0):
    """A floor and a wall (object 1) lit by a lamp: indirect light on the floor comes off the wall."""
    base = plane_scene([PointLight("lamp", list(light_at), [100.0] * 3)], size=5, view=1.0, res=12)
    tri = np.concatenate([base.triangles, WALL + [0, wall_shift, 0]])
    return Scene.build(tri, base.materials, base.lights, base.camera, object_id=[0, 0, 1, 1],
                       object_names=["Floor", "Wall"], max_bounces=2)


def settings(method, placement_seed=None):
    return RenderSettings(samples=2, light_samples=1, method=method, placement_seed=placement_seed, passes=("Combined", "Diffuse Indirect"),
                          placement=MethodSettings(vpls=128, vbnl=VBNLSettings(photons=4096),
                                                   smc=SMCSettings(warmup=3, radiosity_samples=4, camera_points=256)),
                          gather=GatherSettings(interleave=2))


def test_motion_names_what_moved():
    still = Snapshot.of(lamp_scene())
    assert Motion.between(still, Snapshot.of(lamp_scene())).static()
    assert Motion.between(None, still).first and not Motion.between(None, still).static()
    moved = Motion.between(still, Snapshot.of(lamp_scene(wall_shift=0.25)))
    assert moved.moved_objects == ["Wall"] and not moved.lights_changed and not moved.static()
    lo, hi = moved.boxes[0]
    assert lo[1] == pytest.approx(1.0) and moved.boxes[1][0][1] == pytest.approx(1.25)
    lit = Motion.between(still, Snapshot.of(lamp_scene(light_at=(0, 0.4, 1))))
    assert lit.lights_changed and lit.changed_lights == [0] and not lit.moved_objects
    assert not lit.static(view_dependent=False)


def test_frame_seeds_differ_per_frame_and_repeat():
    assert frame_seed(0, 1) == frame_seed(0, 1) != frame_seed(0, 2) != frame_seed(1, 2)
    assert 0 <= frame_seed(3, -5) < 2 ** 31


@pytest.mark.parametrize("method", list(METHODS))
def test_a_static_sequence_traces_no_light_paths_after_frame_one(method):
    """Nothing moves: frames 2..N reuse frame 1's lights (no light path, no BVH build) and their images equal
    frame 1's exactly (the pixels are sampled with the same seed in every frame, as Cycles does)."""
    state = SequenceState(method)
    results = [render(lamp_scene(), settings(method, frame_seed(0, f)), sequence=state) for f in (1, 2, 3)]
    first_cost = results[0].info["light_paths"] or results[0].info.get("sampling_rays", 0)
    assert first_cost > 0 and not results[0].info.get("reused")
    for later in results[1:]:
        assert later.info["light_paths"] == 0 and later.info.get("reused")
        assert later.info.get("sampling_rays", 0) == 0
    assert state.bvh_builds == 1
    first = results[0].passes["Diffuse Indirect"]
    for later in results[1:]:
        image = later.passes["Diffuse Indirect"]
        assert np.isfinite(image).all() and (image >= 0).all()
        np.testing.assert_array_equal(image, first)  # the same lights, pixel samples and gather order
    state.close()


def test_a_moving_light_is_placed_again_and_a_moving_camera_only_for_view_dependent_methods():
    for method, camera_matters in (("ir", False), ("bidir", True)):
        state = SequenceState(method)
        render(lamp_scene(), settings(method), sequence=state)
        moved_light = render(lamp_scene(light_at=(0.3, 0.5, 1)), settings(method), sequence=state)
        assert moved_light.info["light_paths"] > 0 and not moved_light.info.get("reused")
        assert state.bvh_builds == 1  # the light moved, the triangles did not
        scene = lamp_scene(light_at=(0.3, 0.5, 1))
        scene.camera.to_world[0, 3] += 0.1
        moved_camera = render(scene, settings(method), sequence=state)
        assert bool(moved_camera.info.get("reused")) is not camera_matters
        render(lamp_scene(light_at=(0.3, 0.5, 1), wall_shift=0.1), settings(method), sequence=state)
        assert state.bvh_builds == 2
        state.close()


def test_a_saved_state_renders_the_next_frame_exactly_as_the_live_one():
    live = SequenceState("bidir")
    render(lamp_scene(), settings("bidir", frame_seed(0, 1)), sequence=live)
    saved = SequenceState.loads(live.dumps())
    a = render(lamp_scene(), settings("bidir", frame_seed(0, 2)), sequence=live)
    b = render(lamp_scene(), settings("bidir", frame_seed(0, 2)), sequence=saved)
    assert b.info.get("reused") and saved.bvh_builds == 2  # a loaded state builds its BVH again...
    for name in a.passes:  # ...and renders the same pixels
        np.testing.assert_array_equal(a.passes[name], b.passes[name])
    live.close()
    saved.close()
    with pytest.raises(ValueError, match="not a sequence state"):
        SequenceState.loads(pack({"not": "a state"}, {"format": STATE_FORMAT, "key": ""}))


@pytest.mark.parametrize("method", list(METHODS))
def test_a_saved_state_of_every_method_continues_a_moving_sequence_to_the_bit(method):
    """Each method's own state (smc's VPL set, the kept light paths of ir, bidir and vbnl, vbnl's photon lights and
    light tree) saved after two frames of a moving block renders the next frames exactly as the live state does."""
    from test_path_verification import room_with_block
    live = SequenceState(method)
    live.learns = True
    for frame, offset in ((1, -0.6), (2, 0.0)):
        render(room_with_block(offset), settings(method, frame_seed(0, frame)), sequence=live)
    saved = SequenceState.loads(live.dumps("bake 2"), "bake 2")
    for frame, offset in ((3, 0.3), (4, 0.3)):
        a = render(room_with_block(offset), settings(method, frame_seed(0, frame)), sequence=live)
        b = render(room_with_block(offset), settings(method, frame_seed(0, frame)), sequence=saved)
        for name in a.passes:
            assert a.passes[name].tobytes() == b.passes[name].tobytes(), (method, frame, name)
    live.close()
    saved.close()


@pytest.mark.parametrize("world", ["constant", "environment"])
def test_kept_light_paths_of_every_kind_of_light_are_saved(world):
    """ir keeps the lights its paths came from: point, spot, area and sun lights, an emissive mesh (whose lock and
    tracer are made afresh) and the world, constant or an environment map, all come back and follow the next
    frame as the live ones do."""
    from test_path_verification import room_with_block

    def scene(offset):
        room = room_with_block(offset)
        lamps = [PointLight("lamp", [0, 0, 2.5], [100.0] * 3), SpotLight("spot", [1, 0, 2], [200.0] * 3),
                 AreaLight("panel", [-1, 0, 2.9], [0.5, 0, 0], [0, 0.5, 0], [0, 0, -1], [80.0] * 3),
                 SunLight("sun", [0.3, 0.2, -1], [2.0] * 3, 0.05)]
        glowing = np.zeros(len(room.triangles), np.int32)
        glowing[2:4] = 1  # the wall glows
        sky = np.random.default_rng(2).random((8, 16, 3)).astype(np.float32)
        return Scene.build(room.triangles, Materials.make([{"name": "glow", "emission": (0.5, 0.5, 0.5)}]),
                           lamps, room.camera, material=glowing, object_id=room.object_id,
                           object_names=room.object_names, max_bounces=3, world=(0.2, 0.2, 0.2),
                           environment=Environment.checked(sky) if world == "environment" else None)
    live = SequenceState("ir")
    render(scene(0.0), settings("ir", frame_seed(0, 1)), sequence=live)
    kinds = [type(light).__name__ for light in live.method_state.emitters]
    assert kinds == ["PointLight", "SpotLight", "AreaLight", "SunLight", "EmissiveTriangles",
                     "EnvironmentLight" if world == "environment" else "WorldLight"]
    saved = SequenceState.loads(live.dumps())
    a = render(scene(0.3), settings("ir", frame_seed(0, 2)), sequence=live)
    b = render(scene(0.3), settings("ir", frame_seed(0, 2)), sequence=saved)
    assert a.passes["Diffuse Indirect"].tobytes() == b.passes["Diffuse Indirect"].tobytes()
    live.close()
    saved.close()


class _RunsCode:
    """Pickles as a call that writes ``marker``: what a crafted bake state would make ``pickle.loads`` run."""

    def __init__(self, marker):
        self.marker = str(marker)

    def __reduce__(self):
        return exec, (f"open({self.marker!r}, 'w').write('ran')",)


def test_a_crafted_state_that_would_run_code_is_refused_and_runs_nothing(tmp_path):
    """A bake state is read as data: a pickle that runs code when unpickled, as a file or as an array of objects
    in an npz, is refused with a ValueError (the bake starts cold) and its code never runs."""
    proof = tmp_path / "proof"
    pickle.loads(pickle.dumps(_RunsCode(proof)))
    assert proof.read_text() == "ran"  # the payload is live
    marker = tmp_path / "marker"
    in_npz = io.BytesIO()
    tree = json.dumps({"header": {"format": STATE_FORMAT, "key": ""}, "value": {"array": "a0"}})
    np.savez(in_npz, tree=np.frombuffer(tree.encode(), np.uint8), a0=np.array([_RunsCode(marker)], object))
    for data in (pickle.dumps(_RunsCode(marker)), in_npz.getvalue()):
        with pytest.raises(ValueError, match="another version of VPL GI, or damaged"):
            SequenceState.loads(data)
    assert not marker.exists()


@pytest.mark.parametrize("data", [b"\x80\x05not a pickle", b"",
                                  b"cvpl_addon.sequence\nSequenceState\n)\x81.",  # a pickle of an earlier engine
                                  b"cvpl_addon.path_verification\nLightPathStore\n)\x81."])
def test_a_state_of_another_kind_or_damaged_is_refused_with_a_value_error(data):
    """Bake states saved as pickles by earlier engines, and damaged ones: the bake is told by a ValueError (and
    starts cold)."""
    with pytest.raises(ValueError, match="another version of VPL GI, or damaged"):
        SequenceState.loads(data)


def test_a_state_of_another_format_or_bake_is_refused_with_a_value_error():
    """A state whose layout may differ (another format) is refused before a frame reaches for a field it lacks;
    one saved for another scene, settings or frame (its key) is refused too."""
    state = SequenceState("smc")
    with pytest.raises(ValueError, match=f"format {STATE_FORMAT - 1}, where this engine reads {STATE_FORMAT}"):
        SequenceState.loads(pack(state, {"format": STATE_FORMAT - 1, "key": ""}))
    with pytest.raises(ValueError, match="another scene, settings or frame"):
        SequenceState.loads(state.dumps("frame 3"), "frame 4")
    assert SequenceState.loads(state.dumps("frame 3"), "frame 3").method == "smc"


@pytest.mark.parametrize("method", list(METHODS))
def test_a_block_moving_through_the_lights_renders_finite_light_in_every_frame(method):
    """A block slides through the room, over the floor's VPLs: every method's carried
    state gives finite, non-negative light in every frame and follows the change."""
    from test_path_verification import room_with_block
    state = SequenceState(method)
    images = []
    for frame, offset in enumerate((-0.6, 0.0, 0.6), start=1):
        scene = room_with_block(offset)
        result = render(scene, settings(method, frame_seed(0, frame)), sequence=state)
        image = result.passes["Diffuse Indirect"]
        assert np.isfinite(image).all() and (image >= 0).all()
        images.append(image)
    assert not np.array_equal(images[0], images[2])
    state.close()


def test_a_scene_without_some_objects_keeps_the_rest_aligned():
    from test_path_verification import room_with_block
    scene = room_with_block(0.0)
    rest = scene.without(("Block", "Nothing"))
    kept = scene.object_id != scene.object_names.index("Block")
    assert len(rest.triangles) == kept.sum() < len(scene.triangles)
    for name in ("triangles", "normals", "uvs", "material", "object_id"):
        assert np.array_equal(getattr(rest, name), getattr(scene, name)[kept]), name
    assert rest.camera is scene.camera and rest.lights == scene.lights
    assert scene.without(("Nothing",)) is scene


def test_vbnl_lights_stay_where_they_were_while_an_animated_object_moves():
    """Told which objects move in the sequence, vbnl finds its candidates in the rest of the scene: a block sliding
    through the room leaves every light where it was (only their light changes) and renders finite light; without
    the names the lights move all over the room. The still scene's tracer is built once and its rays are counted."""
    from test_path_verification import room_with_block
    moved = {}
    for animated in (None, ("Block",)):
        state = SequenceState("vbnl")
        state.animated = animated
        lights, images = [], []
        for frame, offset in enumerate((-0.6, 0.0, 0.6), start=1):
            result = render(room_with_block(offset), settings("vbnl", frame_seed(0, frame)), sequence=state)
            lights.append(state.lights.position.copy())
            images.append(result.passes["Diffuse Indirect"])
            assert np.isfinite(images[-1]).all() and (images[-1] >= 0).all()
        moved[animated] = [not np.array_equal(lights[0], later) for later in lights[1:]]
        assert not np.array_equal(images[0], images[2])
        if animated:
            still = state._still[1]
            assert 0 < still.rays_traced and result.rays > still.rays_traced
            assert state.still(room_with_block(0.6))[1] is still  # the rest did not change: the same BVH
        state.close()
    assert moved == {None: [True, True], ("Block",): [False, False]}


def test_the_still_scene_is_what_is_not_named_and_none_when_nothing_is_left():
    """A state that names no object, or every object, has no still scene; one that names some has the rest, its
    tracer built once and left out of the saved state."""
    from test_path_verification import room_with_block
    scene = room_with_block(0.0)
    state = SequenceState("vbnl")
    state.begin(scene)
    assert state.still(scene) is None  # nothing named
    state.animated = ("Floor", "Wall", "Block")
    assert state.still(scene) is None
    state.animated = ("Wall", "Block")
    rest, tracer = state.still(scene)
    assert len(rest.triangles) == 2 and tracer.triangle_count == 2
    restored = SequenceState.loads(state.dumps())  # the tracer is not saved; the names are
    assert restored.animated == ("Wall", "Block") and restored._still is None
    state.close()


def test_a_still_scene_the_camera_barely_sees_gives_way_to_the_whole_scene():
    """The floor (most of the view) named as moving: the rest gives fewer than half the candidates, so vbnl finds
    them in the whole scene, and the frame's lights are those of a state that names nothing."""
    from test_path_verification import room_with_block
    lights = []
    for animated in (None, ("Floor",)):
        state = SequenceState("vbnl")
        state.animated = animated
        render(room_with_block(0.0), settings("vbnl", frame_seed(0, 1)), sequence=state)
        lights.append(state.lights.position)
        if animated:
            assert state._still is not None  # it was asked, and found too little
        state.close()
    assert np.array_equal(*lights)


def test_a_state_that_learns_names_each_object_once_it_has_moved():
    """An animation render cannot look ahead: its state learns the objects as they move, so from the frame after
    the block first moved vbnl's lights stay where they were."""
    from test_path_verification import room_with_block
    state = SequenceState("vbnl")
    state.learns = True
    named, lights = [], []
    for frame, offset in enumerate((-0.6, 0.0, 0.6, 0.6), start=1):
        render(room_with_block(offset), settings("vbnl", frame_seed(0, frame)), sequence=state)
        named.append(state.animated)
        lights.append(state.lights.position.copy())
    state.close()
    assert named == [None, ("Block",), ("Block",), ("Block",)]
    assert not np.array_equal(lights[0], lights[1]) and np.array_equal(lights[1], lights[2])


def test_an_object_learnt_to_move_at_the_scenes_edge_leaves_the_lights_where_they_were():
    """A speck below the floor, out of every ray's way, stretches the scene's bounds and moves: learnt in frame 2,
    it leaves the still scene, whose tracer takes its float32 coordinates from the first frame's centre, so vbnl's
    lights stay where they were to the bit (with the centre of its own bounds, rounding moved them all over the
    room). The centre is saved: a resumed sequence traces from it too."""
    from test_path_verification import room_with_block

    def scene(x):
        room = room_with_block(0.0)
        speck = np.array([[[x, 0, -5], [x + 0.01, 0, -5], [x, 0.01, -5]]], float)
        return Scene.build(np.concatenate([room.triangles, speck]), room.materials, room.lights, room.camera,
                           object_id=[*room.object_id, 3], object_names=[*room.object_names, "Speck"],
                           max_bounces=3)
    state = SequenceState("vbnl")
    state.learns = True
    lights = []
    for frame, x in ((1, -4.0), (2, 4.0)):
        render(scene(x), settings("vbnl", frame_seed(0, frame)), sequence=state)
        lights.append(state.lights.position.copy())
    assert np.array_equal(lights[0], lights[1])
    assert state.animated == ("Speck",) and state._still[1].center.tolist() == state.center.tolist()
    assert SequenceState.loads(state.dumps()).center.tolist() == state.center.tolist()
    state.close()
