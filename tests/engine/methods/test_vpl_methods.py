"""The parts of the VPL methods without Blender: emission, light paths, the gather, resampling, methods."""
import numpy as np
import pytest

from conftest import plane_scene
from vpl_addon.core.scene import Materials, Scene
from vpl_addon.core.tracer import Tracer
from vpl_addon.gather.summing import GatherSettings, clamp_distance, gather
from vpl_addon.gather.virtual_lights import VirtualLights
from vpl_addon.lights import AreaLight, EmissiveTriangles, LightSet, PointLight, SpotLight, SunLight, WorldLight
from vpl_addon.materials.surface import Surface
from vpl_addon.methods import MethodSettings
from vpl_addon.methods.bidir.resampling import resample
from vpl_addon.methods.vbnl import VBNLSettings
from vpl_addon.paths.light_paths import trace_until
from vpl_addon.render import RenderSettings, render

CENTER, RADIUS = np.zeros(3), 2.0


@pytest.mark.parametrize("light, total", [
    (PointLight("p", [0, 0, 1], [10.0, 20.0, 30.0]), [10, 20, 30]),
    (PointLight("p", [0, 0, 1], [10.0] * 3, radius=0.5), [10] * 3),
    (AreaLight("a", [0, 0, 1], [1, 0, 0], [0, 2, 0], [0, 0, -1], [7.0] * 3, spread=np.radians(60)), [7] * 3),
    (SunLight("s", [0, 0, -1], [3.0] * 3, angle=0.1), [3 * np.pi * RADIUS ** 2] * 3),
    (WorldLight(np.array([0.5] * 3)), [0.5 * 4 * np.pi ** 2 * RADIUS ** 2] * 3),
])
def test_light_paths_start_with_the_lights_power(light, total):
    rng = np.random.default_rng(0)
    origins, dirs, power = light.emit(200_000, rng, CENTER, RADIUS)
    assert np.allclose(np.linalg.norm(dirs, axis=1), 1.0)
    assert np.allclose(power.mean(axis=0), total, rtol=0.02)


def test_spot_emission_is_the_cone_share_of_a_point_light():
    spot = SpotLight("s", [0, 0, 0], [100.0] * 3, spot_size=np.radians(90), spot_blend=0.0)
    _, dirs, power = spot.emit(400_000, np.random.default_rng(1), CENTER, RADIUS)
    cone = 2 * np.pi * (1 - np.cos(np.radians(45))) / (4 * np.pi)
    assert power[:, 0].mean() == pytest.approx(100 * cone, rel=0.02)
    assert (power[(dirs @ [0, 0, -1]) < np.cos(np.radians(45)) - 1e-9] == 0).all()


def test_emissive_triangles_emit_from_both_sides():
    tri = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]]], float)
    light = EmissiveTriangles(tri, np.array([[0, 0, 1.0]]), np.array([[2.0, 2.0, 2.0]]))
    _, dirs, power = light.emit(100_000, np.random.default_rng(2), CENTER, RADIUS)
    assert power[:, 0].mean() == pytest.approx(2 * np.pi * 2.0 * 0.5, rel=1e-6)  # pi L A per side
    assert 0.45 < (dirs[:, 2] > 0).mean() < 0.55


def test_first_bounce_vpls_carry_the_power_that_reaches_the_floor():
    """A point light over a huge floor of albedo 0.5: half its power hits the floor; the first-bounce VPLs hold
    that power times albedo / pi, whatever the number of paths."""
    floor = plane_scene([PointLight("p", [0, 0, 1], [100.0] * 3)], size=1e4,
                        materials=Materials.make([{"name": "grey", "base_color": (0.5, 0.5, 0.5)}]))
    scene = Scene.build(floor.triangles, floor.materials, floor.lights, floor.camera, material=[1, 1])
    tracer = Tracer(scene.triangles)
    vpls, paths = trace_until(scene, tracer, LightSet(scene), 20_000, np.random.default_rng(3), max_bounces=1)
    assert (vpls.bounce == 1).all() and paths >= 20_000
    assert vpls.intensity[:, 0].sum() * np.pi / 0.5 == pytest.approx(50.0, rel=0.02)


def _surface(points, normal):
    k = len(points)
    n = np.broadcast_to(np.asarray(normal, float), (k, 3)).copy()
    return Surface(np.asarray(points, float), n, n, np.zeros(k, int), np.zeros(k, int), np.ones((k, 3)),
                   np.ones(k), np.zeros(k), np.zeros((k, 3)), np.ones((k, 3)), np.zeros((k, 3)), np.zeros((k, 3)),
                   np.ones(k), -n)


def _vpls(points, normal, intensity):
    k = len(points)
    return VirtualLights(np.asarray(points, float), np.broadcast_to(np.asarray(normal, float), (k, 3)).copy(),
                         np.full((k, 3), intensity, float), np.ones(k, np.int32), np.zeros(k, np.int8),
                         np.arange(k))


def test_gather_of_one_vpl_is_the_cosine_lobe_over_distance_squared():
    tracer = Tracer(np.array([[[-9, -9, 0], [9, -9, 0], [9, 9, 0]], [[-9, -9, 0], [9, 9, 0], [-9, 9, 0]]], float))
    points = _surface([[0, 0, 0], [1, 0, 0]], [0, 0, 1])
    light = _vpls([[0, 0, 2]], [0, 0, -1], 3.0)
    out = gather(points, np.zeros((2, 2), int), light, tracer, GatherSettings(interleave=1), 0.0, np.arange(1))
    d2 = 5.0
    cos = 2 / np.sqrt(d2)
    assert out[0, 0] == pytest.approx(3.0 / (np.pi * 4))
    assert out[1, 0] == pytest.approx(3.0 * cos * cos / (np.pi * d2))


def test_clamping_bounds_a_vpl_on_the_shading_point():
    tracer = Tracer(np.zeros((0, 3, 3)))
    points = _surface([[0, 0, 0]], [0, 0, 1])
    light = _vpls([[0, 0, 1e-9], [1e-12, 0, 1e-12]], [0, 0, -1], 1.0)
    out = gather(points, np.zeros((1, 2), int), light, tracer, GatherSettings(interleave=1), 0.1, np.arange(2))
    assert np.isfinite(out).all() and (out >= 0).all() and out[0, 0] <= 2 / (np.pi * 0.01)
    assert clamp_distance(4.0, 100, 1.0) == pytest.approx(np.sqrt(4 / (np.pi * 100)))


def test_interleaved_gather_averages_to_the_exact_one_over_a_tile():
    tracer = Tracer(np.zeros((0, 3, 3)))
    xy = np.stack(np.meshgrid(np.arange(4), np.arange(4)), -1).reshape(-1, 2)
    points = _surface(np.c_[xy * 1e-3, np.zeros(16)], [0, 0, 1])
    rng = np.random.default_rng(4)
    lights = _vpls(np.c_[rng.random((64, 2)), np.ones(64)], [0, 0, -1], 1.0)
    exact = gather(points, xy, lights, tracer, GatherSettings(interleave=1), 0.0, np.arange(64))
    perm = rng.permutation(64)
    inter = gather(points, xy, lights, tracer, GatherSettings(interleave=4), 0.0, perm)
    assert inter[:, 0].mean() == pytest.approx(exact[:, 0].mean(), rel=0.01)
    assert not np.allclose(inter, exact)  # each pixel really saw a subset


def test_systematic_resampling_is_unbiased_and_keeps_the_budget():
    rng = np.random.default_rng(5)
    power = rng.random(1000) ** 4
    index, weight = resample(power, 100, 1.0, rng)
    q = (power + power.mean()) / (power + power.mean()).sum()
    assert np.round(weight * 100 * q[index]).sum() == 100  # times chosen add up to the budget
    values = rng.random(1000)
    means = [(lambda i, w: (values[i] * w).sum())(*resample(power, 100, 1.0, np.random.default_rng(s)))
             for s in range(400)]
    assert np.mean(means) == pytest.approx(values.sum(), rel=0.02)


def _lamp_floor_and_wall(**build) -> Scene:
    """A point lamp over a floor seen from above, and a wall standing on the floor beside it."""
    wall = np.array([[[-5, 1, 0], [5, 1, 0], [5, 1, 5]], [[-5, 1, 0], [5, 1, 5], [-5, 1, 5]]], float)
    base = plane_scene([PointLight("p", [0, 0.5, 1], [100.0] * 3)], size=5, view=1.0, res=16)
    return Scene.build(np.concatenate([base.triangles, wall]), base.materials, base.lights, base.camera, **build)


@pytest.mark.parametrize("method", ["ir", "bidir", "vbnl"])
def test_methods_light_a_floor_under_a_lamp_like_each_other(method):
    """A lamp over a floor with a wall: indirect light on the floor comes off the wall. Every method agrees on it
    (the summing ones with an exact gather), and nothing is negative or non-finite."""
    scene = _lamp_floor_and_wall(max_bounces=1)
    settings = RenderSettings(samples=4, light_samples=0, method=method,
                              placement=MethodSettings(vpls=2048, vbnl=VBNLSettings(photons=1 << 17)),
                              gather=GatherSettings(interleave=1, clamp=0.0))
    image = render(scene, settings).passes["Combined"][..., 0]
    expected = render(scene, RenderSettings(samples=4, light_samples=0, method="ir",
                                            placement=MethodSettings(vpls=16384),
                                            gather=GatherSettings(interleave=1, clamp=0.0), seed=9)).passes
    assert np.isfinite(image).all() and (image >= 0).all()
    assert image.mean() == pytest.approx(expected["Combined"][..., 0].mean(), rel=0.1)


@pytest.mark.parametrize("method", ["ir", "vbnl"])
def test_a_render_says_how_long_each_stage_waited_on_embree(method):
    """``RenderResult.embree_seconds``: every stage that traces has waited on embree for part of its own seconds
    (blocks' stages: never more than them, summed over the same threads), so the profile's shares are shares."""
    result = render(_lamp_floor_and_wall(), RenderSettings(samples=2, light_samples=1, method=method, block_pixels=64,
                                          placement=MethodSettings(vpls=256, vbnl=VBNLSettings(photons=1 << 12))))
    waited = result.embree_seconds
    assert set(waited) == {"place", "gbuffer", "direct", "gather"}
    assert all(0.0 < waited[stage] <= result.seconds[stage] for stage in ("gbuffer", "direct", "gather"))
    assert waited["place"] > 0.0


def test_vbnl_gathers_one_pair_per_camera_sample_unless_told_otherwise():
    """Gather Samples 0 (the default) gives the gather one pair per camera sample, so Samples alone raises the
    render's quality: the same image, to the bit, as that number of pairs set by hand, and not the image of
    another number. A negative number is refused."""
    from vpl_addon.methods.vbnl.virtual_light_sampling import SamplingSettings
    wall = np.array([[[-5, 1, 0], [5, 1, 0], [5, 1, 5]], [[-5, 1, 0], [5, 1, 5], [-5, 1, 5]]], float)
    base = plane_scene([PointLight("p", [0, 0.5, 1], [100.0] * 3)], size=5, view=1.0, res=8)
    scene = Scene.build(np.concatenate([base.triangles, wall]), base.materials, base.lights, base.camera,
                        max_bounces=2)

    def indirect(samples, pairs):
        vbnl = VBNLSettings(photons=1 << 13, sampling=SamplingSettings(samples=pairs))
        settings = RenderSettings(samples=samples, light_samples=0, placement=MethodSettings(vpls=256, vbnl=vbnl),
                                  passes=("Combined", "Diffuse Indirect"))
        return render(scene, settings).passes["Diffuse Indirect"]

    assert SamplingSettings().samples == 0
    auto = indirect(6, 0)
    np.testing.assert_array_equal(auto, indirect(6, 6))
    assert np.isfinite(auto).all() and auto.mean() > 0.0
    assert not np.array_equal(auto, indirect(6, 2))
    with pytest.raises(ValueError, match="gather samples"):
        VBNLSettings(sampling=SamplingSettings(samples=-1))
