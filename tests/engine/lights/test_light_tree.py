"""The light tree that chooses which light a light sample goes to (``vpl_addon/lights/light_tree.py``): the
probability it reports is the one it samples with, it keeps lights below a point's horizon to the floor share, and
direct light sampled through it equals the sum of every light's own estimate."""
from dataclasses import replace

import numpy as np
import pytest

from conftest import plane_scene
from vpl_addon.core.scene import Materials, Scene
from vpl_addon.core.tracer import Tracer
from vpl_addon.lights import AreaLight, EmissiveTriangles, LightSet, PointLight, SpotLight, SunLight
from vpl_addon.lights.direct import diffuse_direct
from vpl_addon.lights.light_set import _distinct
from vpl_addon.lights.light_tree import FLOOR, LightTree
from vpl_addon.paths.gbuffer import GBuffer
from vpl_addon.render import RenderSettings, render


def mixed_lights(count, seed=1):
    """``count`` lights of every kind over the floor z = 0 (some of them under it), facing every way."""
    rng = np.random.default_rng(seed)
    out = []
    for i, (x, y, z) in enumerate(rng.uniform([-2, -2, -0.5], [2, 2, 2.5], (count, 3))):
        power, normal = rng.uniform(1.0, 20.0, 3), rng.normal(size=3)
        kind = i % 5
        if kind == 0:
            out.append(PointLight(f"p{i}", [x, y, z], power, radius=rng.choice([0.0, 0.1])))
        elif kind == 1:
            scaled = np.diag([2.0, 1.0, 1.0]) if i % 2 else None
            out.append(SpotLight(f"s{i}", [x, y, z], power, direction=normal, spot_size=rng.uniform(0.3, 2.0),
                                 inverse_basis=scaled))
        elif kind == 2:
            u = np.cross(normal, [0.3, 0.5, 0.8])
            out.append(AreaLight(f"a{i}", [x, y, z], 0.3 * u / np.linalg.norm(u),
                                 0.2 * np.cross(normal, u) / np.linalg.norm(np.cross(normal, u)), normal, power,
                                 round=bool(i % 2), spread=rng.uniform(0.5, np.pi)))
        elif kind == 3:
            tri = np.array([[x, y, z], [x + 0.2, y, z], [x, y + 0.2, z + 0.1]])
            facing = np.cross(tri[1] - tri[0], tri[2] - tri[0])
            out.append(EmissiveTriangles(tri[None], facing[None] / np.linalg.norm(facing), [power]))
        else:
            out.append(SunLight(f"sun{i}", normal, 0.2 * power, angle=rng.uniform(0.0, 0.3)))
    return out


POINTS = [([0.3, 0.2, 0.0], [0, 0, 1.0]), ([1.9, 0.0, 1.0], [-1, 0, 0]), ([0.0, 0.0, 1.0], [0, 0.6, 0.8])]


@pytest.mark.parametrize("count, cut", [(200, 256), (200, 8), (40, 1)])
def test_choices_follow_the_reported_probability(count, cut):
    """At a few points, how often each light is chosen matches the probability ``probability`` gives it, and each
    sample reports that probability: all choices among a cut of every leaf, a walk below a cut of 8 nodes, a walk
    from the root."""
    lights = mixed_lights(count)
    tree = LightTree(lights, cut)
    rng = np.random.default_rng(2)
    draws = 200_000
    for p, n in POINTS:
        p, n = np.array([p]), np.array([n]) / np.linalg.norm(n)
        which, prob = tree.sample(p, n, np.zeros(draws, np.int64), rng.random(draws))
        exact = tree.probability(np.repeat(p, count, 0), np.repeat(n, count, 0), np.arange(count))
        assert exact.sum() == pytest.approx(1.0, rel=1e-12)
        assert exact.min() >= FLOOR / count * (1 - 1e-12)
        np.testing.assert_allclose(prob, exact[which], rtol=1e-12)
        seen = np.bincount(which, minlength=count) / draws
        assert (np.abs(seen - exact) <= 5.0 * np.sqrt(exact / draws) + 1.0 / draws).all()


def test_lights_below_the_horizon_get_only_the_floor():
    """A floor point (normal +Z) gives the point lights under it nothing but the uniform share; those above share
    the rest by intensity cos / d^2."""
    above = [PointLight(f"a{i}", [i * 0.3, 0.0, 1.0], [10.0] * 3) for i in range(4)]
    below = [PointLight(f"b{i}", [i * 0.3, 0.0, -1.0], [10.0] * 3) for i in range(4)]
    tree = LightTree(above + below)
    p, n = np.zeros((8, 3)), np.tile([0.0, 0.0, 1.0], (8, 1))
    prob = tree.probability(p, n, np.arange(8))
    np.testing.assert_allclose(prob[4:], FLOOR / 8)
    share = np.array([1.0 / (1.0 + (i * 0.3) ** 2) ** 1.5 for i in range(4)])
    np.testing.assert_allclose(prob[:4], (1 - FLOOR) * share / share.sum() + FLOOR / 8, rtol=1e-6)  # in float32


def test_nothing_behind_an_area_lights_plane():
    """A ceiling point just above a downward panel (inside the panel's bounding sphere's reach) gives the panel only
    the uniform share and the emitter beside it the rest: the panel emits nothing upward (cornell_textured's
    ceiling, where the sphere's bound alone gave the panel 97 % of the samples and doubled Diffuse Direct's rMAE)."""
    panel = AreaLight("panel", [0.0, 0.0, 1.98], [0.5, 0.0, 0.0], [0.0, 0.5, 0.0], [0.0, 0.0, -1.0], [40.0] * 3)
    tri = np.array([[[0.6, 0.9, 1.2], [0.8, 0.9, 1.2], [0.6, 0.9, 1.4]]])
    glow = EmissiveTriangles(tri, np.array([[0.0, -1.0, 0.0]]), [[0.1] * 3])
    p, n = np.array([[0.1, 0.1, 2.0], [0.1, 0.1, 0.0]]), np.array([[0.0, 0.0, -1.0], [0.0, 0.0, 1.0]])
    tree = LightTree([panel, glow])
    on_ceiling, on_floor = tree.probability(p, n, np.zeros(2, np.int64))
    assert on_ceiling == pytest.approx(FLOOR / 2) and on_floor > 0.9


@pytest.mark.parametrize("cut", [256, 4])
def test_direct_light_equals_the_sum_of_each_lights_own(cut):
    """Next-event estimation through the light tree is unbiased: over a floor lit by 40 lights of every kind, its
    direct light matches the sum of each light's estimate alone (the one-light path) within the noise."""
    scene = plane_scene(mixed_lights(40), size=3.0, res=12, view=5.0)
    tracer = Tracer(scene.triangles, threads=1)
    surface = GBuffer.build(scene, tracer, scene.camera.frame_pixels(np.arange(144)), 1,
                            np.random.default_rng(0)).surface
    lights = LightSet(scene)
    assert len(lights.local) == 40
    lights.tree = LightTree(lights.local, cut)
    tree = diffuse_direct(surface, lights, tracer, 8192, np.random.default_rng(1))[:, 0]
    one_by_one = sum(diffuse_direct(surface, LightSet(lights=[light], center=lights.center, radius=lights.radius),
                                    tracer, 256, np.random.default_rng(2 + i))[:, 0]
                     for i, light in enumerate(lights.local))
    assert tree.mean() == pytest.approx(one_by_one.mean(), rel=0.02)  # a few pixels near lights dominate
    assert np.median(np.abs(tree - one_by_one) / one_by_one) < 0.01


def test_glossy_direct_of_many_lights_equals_the_sum_of_each_lights_own():
    """The metallic lobe's multiple importance sampling weighs each light's samples by the probability the tree
    gives that light (``LightSet.local_pdf``, ``LightSet.selection``): over a rough metal floor under 12 area lights,
    Glossy Direct with all of them equals the sum of the renders with each alone, which choose no light."""
    rng = np.random.default_rng(3)
    places = rng.uniform([-1, -1, 0.5], [1, 1, 1.5], (12, 3))
    lights = [AreaLight(f"a{i}", place, [0.2, 0, 0], [0, 0.15, 0], [0, 0, -1], [20.0 * (i + 1)] * 3, round=i % 3 == 0)
              for i, place in enumerate(places)]
    floor = plane_scene(lights, view=2.0, res=16)
    metal = Materials.make([{"name": "metal", "base_color": (0.9, 0.7, 0.5), "metallic": 1.0, "roughness": 0.15}])
    settings = RenderSettings(samples=16, light_samples=16, method="none", passes=("Glossy Direct", "Glossy Color"))

    def shine(with_lights, seed):
        scene = Scene.build(floor.triangles, metal, with_lights, floor.camera, material=[1, 1])
        out = render(scene, replace(settings, seed=seed)).passes
        return (out["Glossy Direct"] * out["Glossy Color"])[..., 0]

    together = shine(lights, 0)
    alone = sum(shine([light], 1 + i) for i, light in enumerate(lights))
    assert together.mean() == pytest.approx(alone.mean(), rel=0.01)


def test_distinct_owners_are_numpy_unique_with_the_inverse():
    """``LightSet.sample_incident``'s per-light points: one pass over sorted owners, numpy's unique otherwise."""
    rng = np.random.default_rng(0)
    for values in (np.sort(rng.integers(0, 50, 1000)), rng.integers(0, 50, 1000), np.zeros(0, np.int64),
                   np.array([3])):
        points, at = _distinct(values)
        expected = np.unique(values, return_inverse=True)
        assert np.array_equal(points, expected[0]) and np.array_equal(at, expected[1])
