"""Hostile scenes built in code, rendered by every method: the output is finite and non-negative, or the run
stops with a message naming the problem. A first part of the stress suite (issue 8); the counts of cases and of
bad pixels are printed at the end of the run."""
import numpy as np
import pytest

from vpl_addon import passes as P
from vpl_addon.camera import Camera, view_window
from vpl_addon.gather import GatherSettings
from vpl_addon.lights import AreaLight, PointLight, SpotLight, SunLight
from vpl_addon.methods import MethodSettings
from vpl_addon.render import RenderSettings, render
from vpl_addon.scene import Materials, Scene

METHODS = ("none", "ir", "bidir")
RESULTS = {"cases": 0, "bad_pixels": 0}  # printed at the end of the run by tests/conftest.py
WHITE = Materials.make([{"name": "white", "base_color": (0.8, 0.8, 0.8)}])
ALBEDO_ONE = Materials.make([{"name": "one", "base_color": (1.0, 1.0, 1.0)}])
BLACK = Materials.make([{"name": "black", "base_color": (0.0, 0.0, 0.0)}])


def look_at(eye, target, res=16, lens=20.0):
    eye, target = np.asarray(eye, float), np.asarray(target, float)
    back = eye - target
    back /= np.linalg.norm(back)
    right = np.cross([0, 0, 1.0], back) if abs(back[2]) < 0.999 else np.array([1.0, 0, 0])
    right /= np.linalg.norm(right)
    up = np.cross(back, right)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = right, up, back, eye
    return Camera(m, res, res, view_window(res, res, orthographic=False, lens=lens), clip_start=1e-6)


def box(lo, hi, inward=True):
    """12 triangles of an axis-aligned box, facing in (a room) or out (a block)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    c = np.array([[x, y, z] for z in (lo[2], hi[2]) for y in (lo[1], hi[1]) for x in (lo[0], hi[0])])
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    tris = []
    for a, b, cc, d in quads:
        tris += [(a, b, cc), (a, cc, d)] if not inward else [(a, cc, b), (a, d, cc)]
    return c[np.array(tris)]


def room(scale=1.0, offset=(0, 0, 0), lights=None, materials=WHITE, world=(0, 0, 0), eye=None, res=16):
    """A closed 2 m room (scaled and moved), camera inside, a point light under the ceiling."""
    off = np.asarray(offset, float)
    tri = box([-1, -1, 0], [1, 1, 2]) * scale + off
    lights = [PointLight("lamp", off + np.array([0, 0, 1.8]) * scale, [100.0 * scale ** 2] * 3)] \
        if lights is None else lights
    cam = look_at(off + np.array(eye or [0.5, -0.9, 1.0]) * scale, off + np.array([0, 0.5, 0.6]) * scale, res)
    return Scene.build(tri, materials, lights, cam, material=np.ones(len(tri), int), world=world)


def with_triangles(scene, extra, material=1):
    tri = np.concatenate([scene.triangles, np.asarray(extra, float).reshape(-1, 3, 3)])
    mat = np.concatenate([scene.material, np.full(len(tri) - len(scene.triangles), material)])
    return Scene.build(tri, scene.materials, scene.lights, scene.camera, material=mat, world=scene.world)


def cases():
    base = room()
    yield "plain room", base
    yield "degenerate and zero-area triangles", with_triangles(base, [
        [[0, 0, 1], [0, 0, 1], [0, 0, 1]], [[0, 0, 1], [1, 0, 1], [2, 0, 1]],
        [[0, 0, 1], [1e-20, 0, 1], [0, 1e-20, 1]]])
    yield "duplicated coplanar triangles", with_triangles(base, base.triangles)
    yield "coincident vertices of a fan", with_triangles(base, [[[0, 0, 0.5], [0.2, 0, 0.5], [0.2, 0.2, 0.5]]] * 5)
    yield "light inside a closed block", with_triangles(
        room(lights=[PointLight("boxed", [0.5, 0.5, 0.3], [100.0] * 3)]), box([0.3, 0.3, 0.1], [0.7, 0.7, 0.5], False))
    yield "single-sided plane seen from behind", with_triangles(base, [[[-0.5, 0.3, 0.2], [0.5, 0.3, 1.2],
                                                                        [0.5, 0.3, 0.2]]])
    yield "black materials", room(materials=BLACK)
    yield "albedo-1 closed room", room(materials=ALBEDO_ONE)
    yield "tiny scene (1e-4 m)", room(scale=1e-4)
    yield "huge scene (1e4 m)", room(scale=1e4)
    yield "far from the origin (1e5 m)", room(offset=(1e5, -1e5, 1e5))
    yield "very bright tiny light", room(lights=[PointLight("sun-in-a-box", [0, 0, 1], [1e12] * 3, radius=1e-6)])
    yield "light on a surface", room(lights=[PointLight("on-floor", [0, 0, 0], [100.0] * 3)])
    yield "only world light (open room)", Scene.build(box([-1, -1, 0], [1, 1, 2])[2:], WHITE, [],
                                                       look_at([0, -3, 1], [0, 0, 1]),
                                                       material=np.ones(10, int), world=(0.5, 0.6, 0.7))
    yield "no light at all", room(lights=[])
    yield "one triangle", Scene.build([[[-1, 1, 0], [1, 1, 0], [0, 1, 2]]], WHITE,
                                      [PointLight("p", [0, 0, 1], [10.0] * 3)], look_at([0, -2, 1], [0, 1, 1]),
                                      material=[1])
    nan_tri = base.triangles.copy()
    nan_tri[0, 0, 0] = np.nan
    nan_tri[1, 1, 2] = np.inf
    yield "NaN and inf corners", Scene.build(nan_tri, WHITE, base.lights, base.camera, material=base.material)
    bad_n = np.full((len(base.triangles), 3, 3), np.nan)
    bad_uv = np.full((len(base.triangles), 3, 2), np.inf)
    yield "NaN normals and inf UVs", Scene.build(base.triangles, WHITE, base.lights, base.camera, normals=bad_n,
                                                 uvs=bad_uv, material=base.material)
    yield "zero-sized area light", room(lights=[AreaLight("flat", [0, 0, 1.9], [0, 0, 0], [0, 0.5, 0], [0, 0, -1],
                                                          [50.0] * 3)])
    yield "NaN light power", room(lights=[PointLight("nan", [0, 0, 1.8], [np.nan, 1.0, np.inf])])
    yield "negative light power", room(lights=[PointLight("neg", [0, 0, 1.8], [-5.0] * 3),
                                               PointLight("ok", [0, 0.5, 1.5], [50.0] * 3)])
    yield "camera inside a solid block", with_triangles(room(eye=[0.5, 0.5, 0.3]),
                                                        box([0.3, 0.3, 0.1], [0.7, 0.7, 0.5], False))
    yield "grazing sun", room(lights=[SunLight("low sun", [1, 0, -1e-6], [3.0] * 3)])
    yield "spot of zero size", room(lights=[SpotLight("pin", [0, 0, 1.8], [100.0] * 3, spot_size=0.0)])
    yield "emission a billion times the lights", with_triangles(
        Scene.build(base.triangles, Materials.make([{"name": "w"}, {"name": "glow", "emission": (1e9, 1e9, 1e9)}]),
                    base.lights, base.camera, material=base.material), [[[0, 0.9, 1], [0.1, 0.9, 1], [0, 0.9, 1.1]]],
        material=2)
    yield "nothing in front of the camera", Scene.build(box([-1, -1, 0], [1, 1, 2]) + [0, 100, 0], WHITE,
                                                        base.lights, look_at([0, 0, 1], [0, -5, 1]),
                                                        material=np.ones(12, int))
    yield "light a million metres away", room(lights=[PointLight("far", [1e6, 0, 1], [1e14] * 3)])


CASES = list(cases())


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("name, scene", CASES, ids=[c[0] for c in CASES])
def test_hostile_scene_renders_finite_non_negative(name, scene, method):
    settings = RenderSettings(samples=4, light_samples=2, method=method, indirect_samples=1,
                              placement=MethodSettings(vpls=64), gather=GatherSettings(interleave=2),
                              passes=(P.COMBINED, P.DIFFUSE_DIRECT, P.DIFFUSE_INDIRECT, P.DIFFUSE_COLOR, P.EMIT))
    result = render(scene, settings)  # raises passes.BadOutput, naming method and stage, on any bad value
    bad = sum(int((~np.isfinite(img)).sum() + (img < 0).sum()) for img in result.passes.values())
    RESULTS["cases"] += 1
    RESULTS["bad_pixels"] += bad
    assert bad == 0


def test_albedo_one_room_stays_below_its_energy_bound():
    """A closed room of albedo 1 lit by a point light: each bounce up to the limit B adds at most the light's power
    again, so the mean indirect irradiance over the walls is B P / A; the pass (E / pi) seen by the camera stays
    below a generous multiple of that."""
    scene = room(materials=ALBEDO_ONE)
    scene.max_bounces = 3
    result = render(scene, RenderSettings(samples=4, light_samples=2, method="ir", placement=MethodSettings(vpls=512),
                                          passes=(P.COMBINED, P.DIFFUSE_INDIRECT)))
    bound = scene.max_bounces * 100.0 / scene.surface_area / np.pi
    assert 0.0 < result.passes[P.DIFFUSE_INDIRECT].mean() <= 3.0 * bound



@pytest.mark.parametrize("method", ["ir", "bidir"])
@pytest.mark.parametrize("variant", [dict(scale=1e-4), dict(scale=1e4), dict(offset=(1e5, -1e5, 1e5))],
                         ids=["tiny", "huge", "far"])
def test_scale_and_position_do_not_change_the_image(method, variant):
    """The same room at 1e-4 or 1e4 scale (light power scaled to keep the radiance) or 1e5 m away renders like the
    room at unit scale near the origin: their difference is below 1.5x the method's own seed-to-seed difference."""
    from vpl_addon.metrics import errors

    def image(scene, seed):
        settings = RenderSettings(samples=4, light_samples=2, method=method, seed=seed,
                                  placement=MethodSettings(vpls=256), passes=(P.COMBINED, P.DIFFUSE_INDIRECT))
        return render(scene, settings).passes[P.DIFFUSE_INDIRECT]

    base = image(room(), 0)
    noise = errors(image(room(), 1), base)["rmae"]
    moved = errors(image(room(**variant), 0), base)["rmae"]
    assert moved < 1.5 * noise
