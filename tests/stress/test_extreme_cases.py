"""Hostile cases that need more than one render or a look inside the pipeline: the furnace with its analytic
value, a VPL exactly on a shading point, an object moving through a VPL between frames, millions of triangles."""
import numpy as np
import pytest

from stress_scenes import budget, METHODS, WHITE, box, room, small_settings, tally
from vpl_addon.core.scene import Materials, Scene
from vpl_addon.core.tracer import Tracer
from vpl_addon.gather.summing import GatherSettings, gather
from vpl_addon.gather.virtual_lights import STANDARD, VirtualLights
from vpl_addon.lights import LightSet
from vpl_addon.methods import MethodContext, place
from vpl_addon.paths.gbuffer import GBuffer
from vpl_addon.render import render


@pytest.mark.parametrize("method", METHODS[1:])
@pytest.mark.parametrize("albedo, bounces", [(1.0, 1), (1.0, 3), (0.5, 3)])
def test_furnace_indirect_light_stays_at_the_analytic_value(method, albedo, bounces):
    """A closed room whose walls all emit radiance Le and reflect with albedo a: the light arriving at any point
    after k reflections is Le a^k, everywhere, whatever the room's shape. So with the bounce limit B the Diffuse
    Indirect pass is exactly Le (a + ... + a^B) at every pixel; its mean must not exceed that (energy is never
    created) nor fall far below it (nor lose the light)."""
    glowing = Materials.make([{"name": "glowing", "base_color": (albedo,) * 3, "emission": (1.0, 1.0, 1.0)}])
    scene = room(lights=[], materials=glowing, max_bounces=bounces)
    result = render(scene, small_settings(method, placement=budget(256)))
    assert tally(f"furnace, albedo {albedo}, {bounces} bounces", result) == 0
    analytic = sum(albedo ** k for k in range(1, bounces + 1))
    assert 0.85 * analytic <= result.passes["Diffuse Indirect"].mean() <= 1.1 * analytic


def test_vpl_exactly_on_a_shading_point_gives_finite_light():
    """VPLs placed exactly at the points the camera sees (distance 0 to one of them, tiny distances to their
    neighbours), gathered without clamping and with it, exactly and interleaved: the light is finite and
    non-negative, and a VPL does not light the point it sits on."""
    scene = room()
    tracer = Tracer(scene.triangles)
    try:
        gbuf = GBuffer.build(scene, tracer, np.arange(16 * 16), 2, np.random.default_rng(0))
        surf = gbuf.surface
        n = len(surf)
        vpls = VirtualLights(surf.position.copy(), surf.shading_normal.copy(), np.ones((n, 3)),
                             np.ones(n, np.int32), np.full(n, STANDARD, np.int8), np.arange(n))
        pix = gbuf.pixel_of_hit
        xy = np.stack([pix % 16, pix // 16], 1)
        lights = []
        for clamp_distance, interleave in [(0.0, 1), (0.0, 4), (0.05, 1)]:
            light = gather(surf, xy, vpls, tracer, GatherSettings(interleave=interleave), clamp_distance,
                           np.random.default_rng(1).permutation(n))
            assert np.isfinite(light).all() and (light >= 0).all()
            lights.append(light)
        alone = gather(surf.take([0]), xy[:1], vpls.take([0]), tracer, GatherSettings(interleave=1), 0.0,
                       np.arange(1))
        assert (alone == 0).all()
        assert lights[0].max() > 0  # the VPLs do light the room
    finally:
        tracer.close()


@pytest.mark.parametrize("method", METHODS[1:])
def test_object_moving_through_a_vpl_between_frames(method):
    """Frame 1 places VPLs in a room; in frames 2 and 3 a block moves through the spot where one of them sat (same
    seed, so the light paths start the same): every frame renders finite and non-negative, the block in frame 2
    really encloses the old VPL, and what the camera sees changes."""
    scene = room()
    tracer = Tracer(scene.triangles)
    try:
        context = MethodContext(scene, tracer, LightSet(scene), np.random.default_rng([0, 1 << 20]), 8)
        vpls, _ = place(method, context, budget(64))
    finally:
        tracer.close()
    visible_floor = vpls.position[(vpls.position[:, 2] < 1e-3) & (vpls.position[:, 1] > 0)]
    target = visible_floor[0] if len(visible_floor) else vpls.position[0]
    frames = []
    for step in (-1.0, 0.0, 1.0):  # before, through, after
        center = target + [step * 0.3, 0, 0.1]
        block = box(center - 0.15, center + 0.15, inward=False)
        moved = Scene.build(np.concatenate([scene.triangles, block]), WHITE, scene.lights, scene.camera,
                            material=np.ones(len(scene.triangles) + 12, int))
        if step == 0.0:
            assert ((center - 0.15 <= target) & (target <= center + 0.15)).all()
        result = render(moved, small_settings(method, placement=budget(64)))
        assert tally(f"object through a VPL, frame {int(step) + 2}", result) == 0
        frames.append(result.passes["Combined"])
    assert not np.array_equal(frames[0], frames[2])


def grid(n):
    """2 n^2 triangles tiling the square [-1, 1]^2 at z = 0."""
    x = np.linspace(-1, 1, n + 1)
    v = np.stack(np.meshgrid(x, x, [0.0], indexing="ij"), -1)[:, :, 0]
    a, b, c, d = v[:-1, :-1], v[1:, :-1], v[1:, 1:], v[:-1, 1:]
    return np.concatenate([np.stack([a, b, c], -2).reshape(-1, 3, 3), np.stack([a, c, d], -2).reshape(-1, 3, 3)])


def test_two_million_triangles():
    """The room's floor replaced by a 1000 x 1000 grid of 2 million tiny triangles (a 2 mm pitch): every method
    renders it, finite and non-negative, with the floor lit as it is when the floor is two triangles."""
    base = room(res=8)
    floor = grid(1000)
    scene = Scene.build(np.concatenate([base.triangles[2:], floor]), WHITE, base.lights, base.camera,
                        material=np.ones(len(floor) + 10, int))
    assert len(scene.triangles) == 2_000_010
    plain = render(base, small_settings("none", samples=16, light_samples=4)).passes["Diffuse Direct"]
    for method in METHODS:
        result = render(scene, small_settings(method, samples=16, light_samples=4,
                                              placement=budget(16)))
        assert tally("two million triangles", result) == 0
        direct = result.passes["Diffuse Direct"]
        assert abs(direct.mean() / plain.mean() - 1.0) < 0.1
