"""Virtual Blue Noise Lighting without Blender: sample elimination, photon lights and splitting, the sampled gather."""
import heapq

import numpy as np
import pytest
from scipy.spatial import cKDTree

from conftest import plane_scene
from vpl_addon.core.tracer import Tracer
from vpl_addon.lights import LightSet, PointLight
from vpl_addon.methods import MethodContext, MethodSettings, place
from vpl_addon.methods.vbnl import VBNLSettings, catchment
from vpl_addon.methods.vbnl.photon_lights import PhotonLights
from vpl_addon.methods.vbnl.sample_elimination import WEIGHT_EXPONENT, eliminate


def uneven_points(count, seed=1):
    """Candidates on the unit square, denser toward x = 0 (as camera importance makes them)."""
    rng = np.random.default_rng(seed)
    return np.c_[rng.random(count) ** 1.5, rng.random(count), np.zeros(count)]


def spacing(points, keep, r_max):
    """Nearest-neighbour distance of the kept points over their r_max: (mean, 5th percentile)."""
    kept = points[keep]
    d, _ = cKDTree(kept).query(kept, k=2)
    ratio = d[:, 1] / r_max
    return ratio.mean(), np.percentile(ratio, 5)


def sequential_greedy(points, count, local=32, neighbours=40):
    """Yuksel's elimination one sample at a time with a heap, on the same weights: the reference."""
    total = len(points)
    dist, near = cKDTree(points).query(points, k=neighbours + 1)
    r = np.sqrt(total * np.pi * dist[:, local] ** 2 / (2 * np.sqrt(3) * count * local))
    dist, near = dist[:, 1:], near[:, 1:]
    term = np.where(dist < 2 * r[:, None], (1 - dist / (2 * r[:, None])) ** WEIGHT_EXPONENT, 0.0)
    listed_by = [[] for _ in range(total)]
    for i, j in zip(*np.nonzero(term)):
        listed_by[near[i, j]].append((i, term[i, j]))
    weight = term.sum(axis=1)
    alive = np.ones(total, bool)
    heap = [(-w, i) for i, w in enumerate(weight)]
    heapq.heapify(heap)
    for _ in range(total - count):
        while True:
            w, i = heapq.heappop(heap)
            if alive[i] and -w == weight[i]:
                break
        alive[i] = False
        for j, t in listed_by[i]:
            if alive[j]:
                weight[j] -= t
                heapq.heappush(heap, (-weight[j], j))
    return np.nonzero(alive)[0], r


def test_vectorised_elimination_spaces_samples_like_the_sequential_greedy():
    points = uneven_points(12_000)
    ours = eliminate(points, 1200, np.random.default_rng(0))
    keep, r = sequential_greedy(points, 1200)
    assert len(ours.keep) == len(np.unique(ours.keep)) == 1200
    mean, low = spacing(points, ours.keep, ours.r_max)
    ref_mean, ref_low = spacing(points, keep, r[keep])
    assert mean == pytest.approx(ref_mean, rel=0.03)
    assert low == pytest.approx(ref_low, rel=0.05)


def test_adaptive_elimination_is_blue_noise_and_keeps_the_density():
    """Kept samples are never as close as random ones get, and the dense half keeps its larger share."""
    points = uneven_points(20_000, seed=2)
    rng = np.random.default_rng(0)
    adaptive = eliminate(points, 2000, rng)
    uniform = eliminate(points, 2000, rng, mode="uniform")
    random = eliminate(points, 2000, rng, mode="none")
    assert spacing(points, adaptive.keep, adaptive.r_max)[1] > 4 * spacing(points, random.keep, random.r_max)[1]
    share = {name: (points[e.keep, 0] < 0.5).mean() for name, e in
             (("adaptive", adaptive), ("uniform", uniform), ("candidates", type(adaptive)(np.arange(20_000), None)))}
    assert share["adaptive"] == pytest.approx(share["candidates"], abs=0.03)
    assert share["uniform"] < share["adaptive"] - 0.05
    assert np.ptp(uniform.r_max) == 0.0


def test_elimination_of_coincident_candidates_terminates_with_finite_radii():
    points = np.concatenate([np.zeros((500, 3)), uneven_points(300)])
    result = eliminate(points, 100, np.random.default_rng(0))
    assert len(np.unique(result.keep)) == 100
    assert np.isfinite(result.r_max).all() and (result.r_max > 0).all()
    assert (np.abs(points[result.keep]).sum(axis=1) == 0).sum() <= 1  # one of the 500 copies at most


def grid_lights(spacing_=0.05, radius=0.1, normal=(0, 0, 1)):
    g = np.arange(0, 1 + 1e-9, spacing_)
    xy = np.stack(np.meshgrid(g, g), -1).reshape(-1, 2)
    n = len(xy)
    return PhotonLights(np.c_[xy, np.zeros(n)], np.tile(normal, (n, 1)), np.full(n, radius), np.zeros((n, 3)))


def test_shares_are_a_partition_of_unity_and_splitting_conserves_intensity():
    lights = grid_lights()
    rng = np.random.default_rng(0)
    points = np.c_[rng.random((5000, 2)), np.zeros(5000)]
    up = np.tile([0, 0, 1.0], (5000, 1))
    rows, light, share = lights.shares(points, up)
    assert np.allclose(np.bincount(rows, share, 5000), 1.0)
    assert (np.linalg.norm(points[rows] - lights.position[light], axis=1) <= lights.radius[light]).all()
    values = rng.random((5000, 3))
    assert np.allclose(lights.spread(points, up, values).sum(axis=0), values.sum(axis=0))
    assert lights.spread(points, -up, values).sum() == 0.0  # photons on the other side light nothing


def test_catchments_add_up_to_the_area_the_lights_cover():
    """A unit floor under a lattice of lights: the catchments sum to the floor's area (discs past its edges find
    no surface) and interior lights get spacing^2 each."""
    scene = plane_scene(size=0.5, center=(0.5, 0.5, 0.0))
    lights = grid_lights()
    tracer = Tracer(scene.triangles)
    area = catchment(lights, scene, tracer, 256, np.random.default_rng(0))
    tracer.close()
    assert area.sum() == pytest.approx(1.0, rel=0.01)
    inner = (np.abs(lights.position[:, :2] - 0.5) < 0.35).all(axis=1)
    assert area[inner].mean() == pytest.approx(0.05 ** 2, rel=0.02)


def test_catchment_of_lights_on_a_thin_strip_is_measured_again():
    """Lights on a 2 cm strip (a window frame's edge), each disc 40 cm across: a few of a light's 32 points land on
    the strip, and an area from them is up to 51 % off (so is the light's radiance I_j / A_j); the lights that few
    points found are measured again with 16 times as many, and every area is then within 15 % of the strip's part
    of the disc."""
    from vpl_addon.core.scene import Materials, Scene
    w, r, n = 0.02, 0.2, 200
    strip = np.array([[[-w / 2, -100, 0], [w / 2, -100, 0], [w / 2, 100, 0]],
                      [[-w / 2, -100, 0], [w / 2, 100, 0], [-w / 2, 100, 0]]], float)
    scene = Scene.build(strip, Materials.make([]), [], plane_scene().camera)
    x = (np.random.default_rng(5).random(n) - 0.5) * w
    lights = PhotonLights(np.c_[x, np.arange(n) * 0.5 - 50, np.zeros(n)], np.tile([0, 0, 1.0], (n, 1)),
                          np.full(n, r), np.zeros((n, 3)))
    tracer = Tracer(scene.triangles)
    area = catchment(lights, scene, tracer, 32, np.random.default_rng(0))
    tracer.close()
    assert np.abs(area / (w * 2 * np.sqrt(r * r - x * x)) - 1).max() < 0.15


def test_photon_lights_reproduce_the_radiance_of_a_lit_floor():
    """A point light between a grey floor and a ceiling the camera looks up at: the candidates land on the floor
    (the camera's BSDF rays bounce down from the ceiling), and with one bounce their radiance L_j = I_j / A_j is
    the floor's reflected radiance, albedo E / pi with E = P cos / (4 pi d^2)."""
    from vpl_addon.core.camera import Camera, view_window
    from vpl_addon.core.scene import Scene
    lamp = PointLight("lamp", [0.0, 0.0, 1.0], [400.0] * 3)
    quad = np.array([[[-2, -2, 0], [2, -2, 0], [2, 2, 0]], [[-2, -2, 0], [2, 2, 0], [-2, 2, 0]]], float)
    up = np.diag([1.0, -1.0, -1.0, 1.0])
    up[:3, 3] = [0, 0, 1.5]
    camera = Camera(up, 32, 32, view_window(32, 32, orthographic=True, ortho_scale=3.0), orthographic=True)
    floor = plane_scene()
    scene = Scene.build(np.concatenate([quad, quad + [0, 0, 2]]), floor.materials, [lamp], camera, max_bounces=1)
    tracer = Tracer(scene.triangles)
    context = MethodContext(scene, tracer, LightSet(scene), np.random.default_rng(0), max_bounces=1)
    lights, info = place("vbnl", context, MethodSettings(vpls=512, vbnl=VBNLSettings(photons=1 << 19)))
    tracer.close()
    assert info["vpls"] == 512 and info["light_paths"] == 1 << 19
    assert np.abs(lights.position[:, 2]).max() < 1e-6  # every candidate kept is on the floor
    d2 = np.sum((lights.position - lamp.position) ** 2, axis=1)
    expected = 0.8 / np.pi * 400.0 / (4 * np.pi * d2) / np.sqrt(d2)
    inner = np.abs(lights.position[:, :2]).max(axis=1) < 1.5
    assert np.median(lights.radiance[inner, 0] / expected[inner]) == pytest.approx(1.0, abs=0.05)
    assert np.isfinite(lights.radiance).all() and (lights.radiance >= 0).all()
