"""Virtual Blue Noise Lighting without Blender: sample elimination, photon lights and splitting, the sampled gather."""
import heapq
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
from scipy.spatial import cKDTree

from conftest import plane_scene
from vpl_addon.core.color import LUMINANCE
from vpl_addon.core.tracer import Tracer
from vpl_addon.gather.virtual_lights import VirtualLights
from vpl_addon.lights import LightSet, PointLight
from vpl_addon.methods import MethodContext, MethodSettings, place
from vpl_addon.methods.vbnl import PATHS_PER_BATCH, VBNLSettings, catchment, open_reach, photon_batches, split_photons
from vpl_addon.methods.vbnl import photon_lights
from vpl_addon.methods.vbnl.photon_lights import SLAB, PhotonLights, Splitting
from vpl_addon.methods.vbnl import sample_elimination
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


def test_elimination_removes_candidates_in_the_sequential_greedy_order():
    """The compiled heap elimination keeps exactly the candidates the reference keeps, so it spaces them alike."""
    points = uneven_points(12_000)
    ours = eliminate(points, 1200, np.random.default_rng(0))
    keep, r = sequential_greedy(points, 1200)
    assert np.array_equal(np.sort(ours.keep), keep)
    assert np.allclose(ours.r_max[np.argsort(ours.keep)], r[keep])


def test_elimination_in_slices_keeps_the_same_candidates_and_can_be_stopped(monkeypatch):
    """Queried and removed ``STEP`` candidates at a time with a ``checkpoint`` between slices (where the viewport
    stops it), the elimination keeps what it keeps in one go; a checkpoint that raises ends it."""
    points = uneven_points(12_000)
    whole = eliminate(points, 1200, np.random.default_rng(0))
    monkeypatch.setattr(sample_elimination, "STEP", 1000)
    calls = []
    sliced = eliminate(points, 1200, np.random.default_rng(0), checkpoint=lambda: calls.append(1))
    assert np.array_equal(sliced.keep, whole.keep) and np.array_equal(sliced.r_max, whole.r_max)
    assert len(calls) == 12 + 11  # 12 slices of the query, 10,800 removals in 11

    def stop():
        raise InterruptedError
    with pytest.raises(InterruptedError):
        eliminate(points, 1200, np.random.default_rng(0), checkpoint=stop)


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


def spread(lights, points, normals, values, group=None, groups=1, pool=None, workers=1, lids=None):
    """(N, groups, C) the values of one batch of points shared among the lights (``Splitting``)."""
    splitting = Splitting(lights, groups, values.shape[1], pool, workers)
    splitting.add(points, normals, values, group, lids)
    return splitting.total()


def test_shares_are_a_partition_of_unity_and_splitting_conserves_intensity():
    lights = grid_lights()
    rng = np.random.default_rng(0)
    points = np.c_[rng.random((5000, 2)), np.zeros(5000)]
    up = np.tile([0, 0, 1.0], (5000, 1))
    rows, light, share = lights.shares(points, up)
    assert np.allclose(np.bincount(rows, share, 5000), 1.0)
    assert (np.linalg.norm(points[rows] - lights.position[light], axis=1) <= lights.radius[light]).all()
    values = rng.random((5000, 3))
    assert np.allclose(spread(lights, points, up, values).sum(axis=0), values.sum(axis=0))
    assert spread(lights, points, -up, values).sum() == 0.0  # photons on the other side light nothing


def box_lights(count, rng):
    """Lights on the six faces of the unit cube, facing in, radii from 0.05 to 0.2 and one of 0.9."""
    face = rng.integers(0, 6, count)
    position = rng.random((count, 3))
    position[np.arange(count), face // 2] = face % 2
    normal = np.zeros((count, 3))
    normal[np.arange(count), face // 2] = 1 - 2 * (face % 2)
    radius = 0.05 + 0.15 * rng.random(count)
    radius[0] = 0.9
    return PhotonLights(position, normal, radius, np.zeros((count, 3)))


def points_near_box_faces(count, rng):
    """Points on the cube's faces, up to 0.5 mm off them (inside and outside the slabs of ``box_lights``' lights,
    0.25 to 1 mm at ``SLAB`` 0.005), and their inward normals (the first 100 flipped)."""
    face = rng.integers(0, 6, count)
    points = rng.random((count, 3))
    points[np.arange(count), face // 2] = face % 2 + (rng.random(count) - 0.5) * 0.001
    normals = np.zeros((count, 3))
    normals[np.arange(count), face // 2] = 1 - 2 * (face % 2)
    normals[:100] *= -1
    return points, normals


def all_pairs_shares(lights, points, normals):
    """The definition of ``PhotonLights.shares`` over every (point, light) pair, sorted by point and light."""
    offset = points[:, None, :] - lights.position[None]
    dist = np.linalg.norm(offset, axis=2)
    slab = np.abs(np.einsum("pnj,nj->pn", offset, lights.normal))
    inside = (dist <= lights.radius) & (normals @ lights.normal.T > 0) & (slab <= SLAB * lights.radius)
    rows, light = np.nonzero(inside)
    w = np.maximum(1 - (dist[rows, light] / lights.radius[light]) ** 2, 1e-12)
    return rows, light, w / np.bincount(rows, w, len(points))[rows]


def test_shares_from_the_light_grid_are_those_of_every_pair():
    rng = np.random.default_rng(3)
    lights = box_lights(600, rng)
    points, normals = points_near_box_faces(20_000, rng)
    rows, light, share = lights.shares(points, normals)
    ref_rows, ref_light, ref_share = all_pairs_shares(lights, points, normals)
    order = np.lexsort((light, rows))
    assert np.array_equal(rows, ref_rows) and np.array_equal(light[order], ref_light)
    assert np.allclose(share[order], ref_share, rtol=1e-9, atol=1e-13)
    of_light_0 = lights.share_of(points, normals, np.zeros(len(points), np.int64))
    assert np.allclose(of_light_0, np.bincount(ref_rows, ref_share * (ref_light == 0), len(points)), rtol=1e-9,
                       atol=1e-13)


@pytest.mark.parametrize("sorted_from", [photon_lights.SORTED_FROM, 0])
def test_photon_splitting_on_threads_sums_the_shared_values_by_light_and_group(sorted_from, monkeypatch):
    """In the points' order and in the order of their grid blocks (``SORTED_FROM`` lights, here 0), on one thread
    and on three, batch after batch into the same sums."""
    monkeypatch.setattr(photon_lights, "SORTED_FROM", sorted_from)
    rng = np.random.default_rng(4)
    lights = box_lights(300, rng)
    points, normals = points_near_box_faces(10_000, rng)
    values, group = rng.random((10_000, 3)), rng.integers(0, 4, 10_000)
    rows, light, share = all_pairs_shares(lights, points, normals)
    slot = light * 4 + group[rows]
    expected = np.stack([np.bincount(slot, share * values[rows, c], 300 * 4) for c in range(3)], axis=1)
    with ThreadPoolExecutor(2) as pool:
        in_batches = Splitting(lights, 4, 3, pool, 3)
        for part in np.array_split(np.arange(10_000), 7):
            in_batches.add(points[part], normals[part], values[part], group[part])
        for split in (spread(lights, points, normals, values, group, 4),
                      spread(lights, points, normals, values, group, 4, pool, 3), in_batches.total()):
            assert np.allclose(split, expected.reshape(300, 4, 3), rtol=1e-9, atol=1e-13)


def test_photons_held_and_split_a_number_at_a_time_are_split_as_one_batch(monkeypatch):
    """Above ``SORTED_FROM`` lights the placement holds batches until it has ``SORTED_POINTS`` photons (here 0
    lights and 2,500 photons; 10 batches of 1,000): every photon is split once, the last held ones too."""
    monkeypatch.setattr(photon_lights, "SORTED_FROM", 0)
    monkeypatch.setattr(photon_lights, "SORTED_POINTS", 2500)
    rng = np.random.default_rng(5)
    lights = box_lights(300, rng)
    points, normals = points_near_box_faces(10_000, rng)
    values, bounce = rng.random((10_000, 3)), rng.integers(1, 5, 10_000)
    caustic = np.where((rng.random(10_000) < 0.2)[:, None], 0.5 * values, 0.0)  # a fifth came over glossy lobes
    batches = [VirtualLights(points[part], normals[part], values[part], bounce[part].astype(np.int32),
                             np.zeros(len(part), np.int8), part, caustic[part])
               for part in np.array_split(np.arange(10_000), 10)]
    tracer = Tracer(plane_scene().triangles)
    split, halves = split_photons(lights, iter(batches), 4, tracer)
    lids = photon_lights.lid_heights(tracer, points, normals, photon_lights.LID * lights.radius.max())
    tracer.close()
    assert np.isfinite(lids).any()  # the floor is over some of them: they go to no light in both
    assert np.allclose(split[:, :4], spread(lights, points, normals, values, bounce - 1, 4, lids=lids), rtol=1e-9,
                       atol=1e-13)
    assert split[:, :4].sum() > 0.5 * values.sum()
    # the caustic photons once more, by their caustic light, in the group after the last bounce
    assert np.allclose(split[:, 4], spread(lights, points, normals, caustic, np.zeros(10_000, np.int64), 1,
                                           lids=lids)[:, 0], rtol=1e-9, atol=1e-13)
    assert split[:, 4].sum() > 0.5 * caustic.sum() > 0.0
    # the photons of odd paths (here photon i ends path i): their luminance and its first moment by the kernels
    moments = np.c_[values @ LUMINANCE, (values @ LUMINANCE)[:, None] * points]
    odd = Splitting(lights, 1, 3, raw_groups=1, raw_channels=4)
    odd.add(points[1::2], normals[1::2], values[1::2], lids=lids[1::2], raw=moments[1::2])
    assert np.allclose(halves[:, 1], odd.raw_total()[:, 0], rtol=1e-9, atol=1e-13)
    assert np.allclose(halves.sum(axis=1)[:, 0] > 0, split.sum(axis=(1, 2)) > 0)


def test_raw_values_are_weighted_by_the_kernel_of_every_covering_light():
    """Two lights 0.1 apart, radius 0.2, and a point between them at 0.03 from the first: its value is shared
    (weights 1 - d^2 / r^2 normalised over the two) and its raw value weighted by each kernel as it is."""
    lights = PhotonLights(np.array([[0.0, 0, 0], [0.1, 0, 0]]), np.tile([0, 0, 1.0], (2, 1)), np.full(2, 0.2),
                          np.zeros((2, 3)))
    splitting = Splitting(lights, 1, 1, raw_groups=2, raw_channels=1)
    splitting.add(np.array([[0.03, 0, 0]]), np.array([[0, 0, 1.0]]), np.ones((1, 1)), raw=np.full((1, 1), 2.0),
                  raw_group=np.ones(1, np.int64))
    k = 1.0 - np.array([0.03, 0.07]) ** 2 / 0.04
    assert splitting.total()[:, 0, 0] == pytest.approx(k / k.sum())
    assert splitting.raw_total()[:, 1, 0] == pytest.approx(2.0 * k) and not splitting.raw_total()[:, 0].any()


def test_photon_batches_are_the_same_on_any_number_of_threads():
    """Each batch draws from its own seed: traced on one thread or on two at once (as the placement does once its
    lights exist), the photons are the same, batch by batch."""
    scene = plane_scene(lights=[PointLight("lamp", [0.0, 0.0, 1.0], [100.0] * 3)])
    tracer = Tracer(scene.triangles)
    context = MethodContext(scene, tracer, LightSet(scene), np.random.default_rng(0), max_bounces=2)
    runs = []
    for threads in (1, 2):
        with ThreadPoolExecutor(threads) as executor:
            runs.append(list(photon_batches(context, 3 * PATHS_PER_BATCH // 2, (5, 6), executor)))
    tracer.close()
    assert [len(b) for b in runs[0]] == [len(b) for b in runs[1]] and len(runs[0]) == 2
    for one, two in zip(*runs):
        assert len(one) > 1000 and np.array_equal(one.position, two.position)
        assert np.array_equal(one.intensity, two.intensity)


def test_catchments_add_up_to_the_area_the_lights_cover():
    """A unit floor under a lattice of lights: the catchments sum to the floor's area (discs past its edges find
    no surface) and interior lights get spacing^2 each."""
    scene = plane_scene(size=0.5, center=(0.5, 0.5, 0.0))
    lights = grid_lights()
    tracer = Tracer(scene.triangles)
    area = catchment(lights, scene, tracer, 256, np.random.default_rng(0)).area
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
    area = catchment(lights, scene, tracer, 32, np.random.default_rng(0)).area
    tracer.close()
    assert np.abs(area / (w * 2 * np.sqrt(r * r - x * x)) - 1).max() < 0.15


def floor_and_wall(x0, thickness=0.04, height=1.0, under=True):
    """A 2 m square floor (z = 0, facing up) with a wall standing on it across the floor, from x = x0 on; without
    the floor under the wall if not ``under``."""
    from vpl_addon.core.scene import Materials, Scene
    floor = np.array([[[-1, -1, 0], [1, -1, 0], [1, 1, 0]], [[-1, -1, 0], [1, 1, 0], [-1, 1, 0]]], float)
    if not under:
        floor = np.concatenate([_rect([-1, -1, 0], [x0 + 1, 0, 0], [0, 2, 0]),
                                _rect([x0 + thickness, -1, 0], [1 - x0 - thickness, 0, 0], [0, 2, 0])])
    corners = np.array([[x, y, z] for x in (x0, x0 + thickness) for y in (-1, 1) for z in (0, height)], float)
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (1, 5, 7, 3), (2, 3, 7, 6)]  # the sides, ends and top
    halves = [(f[0], f[1], f[2]) for f in faces] + [(f[0], f[2], f[3]) for f in faces]
    wall = np.array([[corners[a], corners[b], corners[c]] for a, b, c in halves])
    return Scene.build(np.concatenate([floor, wall]), Materials.make([]), [], plane_scene().camera)


def linear_reconstruction(lights, points):
    """(P,) the luminance the lights give the floor points: sum_j s_j L_j (1 + gamma_j . (y - c_j))."""
    rows, light, share = lights.shares(points, np.tile([0, 0, 1.0], (len(points), 1)))
    slope, centre = lights.linear
    factor = np.maximum(1.0 + ((points[rows] - centre[light]) * slope[light]).sum(axis=1), 0.0)
    return np.bincount(rows, share * factor * (lights.radiance[light] @ LUMINANCE), len(points))


def test_slopes_take_the_light_of_the_open_floor_out_of_the_corner():
    """Floor lights beside a thin wall that stands on the floor, the floor's radiance 1 + 2 |x| (darker toward
    the wall at x = 0), photons spread evenly with that radiance: a light cut by the wall averages the floor on the
    open side only, so the lights' means alone put the foot of the wall 6 % too bright. With the fitted slopes
    (``fit_slopes``) the error at the foot is less than half that, the slopes follow the ramp away from the wall,
    and the floor's light is kept; the same lights over an evenly lit floor get no slope to speak of. What is left
    at the foot (2 % too dark) is the fit's sensitivity to its support: the closed-form kernel counts the floor
    under the wall, 1.4 % of the nearest lights' kernel where no photon lands, which tilts their slopes 10 % too
    steep. The catchment takes 1024 points here: with 32 (the placement's) or 128, a cut light's area is 13 % or
    5 % off, one light to the next, which a handful of lights along a wall does not average away."""
    from vpl_addon.methods.vbnl.photon_lights import fit_slopes
    scene = floor_and_wall(0.0, thickness=0.002)
    tracer = Tracer(scene.triangles)
    g = np.arange(-0.975, 0.0, 0.05)
    xy = np.stack(np.meshgrid(g, np.arange(-0.5, 0.51, 0.05)), -1).reshape(-1, 2)
    position, up = np.c_[xy, np.zeros(len(xy))], np.tile([0, 0, 1.0], (len(xy), 1))
    radius = np.full(len(xy), 0.1)
    reach = open_reach(position, up, radius, tracer)
    share = catchment(PhotonLights(position, up, radius, np.zeros((len(xy), 3)), reach=reach), scene, tracer, 1024,
                      np.random.default_rng(0))
    rng = np.random.default_rng(1)
    count, side = 3_000_000, (2.0, 1.4)  # photons over the floor with |y| < 0.7, on both sides of the wall
    p = np.c_[(rng.random(count) - 0.5) * side[0], (rng.random(count) - 0.5) * side[1], np.zeros(count)]
    p = p[(p[:, 0] < 0.0) | (p[:, 0] > 0.002)]

    def lit(radiance):
        """The lights, without and with slopes, for photons of the floor radiance ``radiance(x)``."""
        values = np.repeat((radiance(p[:, 0]) * side[0] * side[1] / count)[:, None], 3, axis=1)
        photons = VirtualLights(p, np.tile([0, 0, 1.0], (len(p), 1)), values, np.ones(len(p), np.int32),
                                np.zeros(len(p), np.int8), np.arange(len(p)))
        lights = PhotonLights(position, up, radius, np.zeros((len(xy), 3)), catchment=share.area,
                              centre=share.centre, reach=reach)
        by_bounce, halves = split_photons(lights, iter([photons]), 1, tracer)
        lights.intensity = by_bounce[:, 0]
        flat = PhotonLights(position, up, radius, lights.intensity, catchment=share.area, reach=reach)
        lights.slope = fit_slopes(position, up, radius, reach, share.flat, lights.radiance @ LUMINANCE, halves)
        return flat, lights

    _, even = lit(lambda x: np.ones_like(x))
    size = np.linalg.norm(even.slope, axis=1) * radius
    assert np.median(size) < 0.02 and np.quantile(size, 0.9) < 0.06

    def ramp(x):
        return 1.0 + 2.0 * np.abs(x)
    flat, lights = lit(ramp)
    tracer.close()
    inner = (xy[:, 0] < -0.2) & (xy[:, 0] > -0.8) & (np.abs(xy[:, 1]) < 0.3)
    truth = -2.0 / (lights.radiance[inner] @ LUMINANCE)  # d/dx of the radiance over the light's mean
    assert np.median(lights.slope[inner, 0] / truth) == pytest.approx(0.95, abs=0.07)  # shrunk a little by noise
    foot = np.c_[np.full(200, -0.01), np.linspace(-0.3, 0.3, 200), np.zeros(200)]
    without, fitted = (linear_reconstruction(m, foot).mean() / ramp(-0.01) for m in (flat, lights))
    assert without > 1.04 and abs(fitted - 1.0) < 0.5 * (without - 1.0)
    floor = np.c_[-rng.random(20_000) * 0.6 - 0.2, (rng.random(20_000) - 0.5) * 0.6, np.zeros(20_000)]
    assert linear_reconstruction(lights, floor).mean() == pytest.approx(ramp(floor[:, 0]).mean(), rel=0.01)


def test_a_wall_standing_on_the_floor_cuts_a_floor_lights_reach():
    """A floor light 10 cm from a 4 cm wall that stands on the floor, its disc 40 cm across: the floor behind the
    wall (another room) lies in its sphere, on its plane and faces its way, so without a reach it took that room's
    photons and lent it its light. With ``open_reach`` the disc stops at the wall: the light covers the floor on its
    side, not behind; a photon behind the wall goes to no light; its catchment is the floor on its side; a light away
    from the wall keeps its whole disc."""
    x0 = 0.1
    scene = floor_and_wall(x0)
    tracer = Tracer(scene.triangles)
    position, normal, radius = np.array([[0.0, 0, 0], [-0.6, 0, 0]]), np.tile([0, 0, 1.0], (2, 1)), np.full(2, 0.2)
    reach = open_reach(position, normal, radius, tracer)
    whole = PhotonLights(position, normal, radius, np.zeros((2, 3)))
    cut = PhotonLights(position, normal, radius, np.zeros((2, 3)), reach=reach)
    assert reach[0].min() == pytest.approx(x0, rel=0.02) and np.all(reach[1] == 0.2)
    up = np.tile([0, 0, 1.0], (3, 1))
    near, behind, far = [0.05, 0.02, 0], [0.17, 0.02, 0], [-0.6, 0.1, 0]
    points = np.array([near, behind, far])
    assert np.all(whole.share_of(points, up, np.zeros(3, np.int64))[:2] == 1.0)  # its only light, behind as well
    assert list(cut.share_of(points, up, np.zeros(3, np.int64))[:2] > 0) == [True, False]
    assert cut.share_of(points, up, np.ones(3, np.int64))[2] == 1.0
    split = Splitting(cut, 1, 3)
    split.add(points[:2], up[:2], np.ones((2, 3)))
    assert split.total()[0, 0] == pytest.approx([1.0] * 3)  # the photon behind the wall went to no light
    area = catchment(cut, scene, tracer, 256, np.random.default_rng(1)).area
    tracer.close()
    side = 0.2 ** 2 * np.arccos(0.1 / 0.2) - 0.1 * np.sqrt(0.2 ** 2 - 0.1 ** 2)  # the disc's segment past x = 0.1
    assert area[0] == pytest.approx(np.pi * 0.04 - side, rel=0.05)
    assert area[1] == pytest.approx(np.pi * 0.04, rel=0.02)


def _rect(corner, e1, e2):
    """Two triangles of the parallelogram from ``corner`` along e1 and e2, facing e1 x e2."""
    a = np.asarray(corner, float)
    b, c, d = a + e1, a + np.add(e1, e2), a + e2
    return np.array([[a, b, c], [a, c, d]])


def _ceiling_and_panel(gap=1e-3):
    """A 2 m ceiling at z = 2 facing down, and a 40 x 40 cm panel hung ``gap`` under it, facing down, at x 0.05-0.45."""
    return _rect([-1, -1, 2], [0, 2, 0], [2, 0, 0]), _rect([0.05, -0.2, 2 - gap], [0, 0.4, 0], [0.4, 0, 0])


def test_surface_under_a_lid_is_no_lights():
    """A ceiling light beside a panel hung 1 mm under the ceiling (as a glowing panel is modelled): the ceiling over
    the panel lies in its sphere, on its plane and faces its way, but the room does not see it, and the panel's back
    lights it. A photon there goes to no light; one beside the panel or on the panel's face (within the light's
    slab) goes to the light; the catchment leaves out the covered ceiling, for which the panel's face stands in as
    the room sees it."""
    from vpl_addon.core.scene import Materials, Scene
    ceiling, panel = _ceiling_and_panel()
    scene = Scene.build(np.concatenate([ceiling, panel]), Materials.make([]), [], plane_scene().camera)
    tracer = Tracer(scene.triangles)
    down = np.array([[0, 0, -1.0]])
    light = PhotonLights(np.array([[0.0, 0, 2]]), down, np.array([0.4]), np.zeros((1, 3)))  # slab 2 mm
    points = np.array([[0.15, 0, 2.0], [-0.1, 0, 2.0], [0.15, 0, 2.0 - 1e-3]])  # over the panel, beside it, on it
    normals = np.repeat(down, 3, axis=0)
    lids = photon_lights.lid_heights(tracer, points, normals, 1.0)
    assert lids[0] == pytest.approx(1e-3, abs=1e-4) and np.all(lids[1:] == np.inf)
    assert np.all(light.share_of(points, normals, np.zeros(3, np.int64)) == 1.0)  # no lid: all three are its
    split = Splitting(light, 1, 3)
    split.add(points, normals, np.ones((3, 3)), lids=lids)
    assert split.total()[0, 0] == pytest.approx([2.0] * 3)  # the photon over the panel went to no light
    area = catchment(light, scene, tracer, 1024, np.random.default_rng(1)).area
    tracer.close()
    assert area[0] == pytest.approx(np.pi * 0.16, rel=0.03)  # the ceiling beside the panel, and the panel's face


def test_a_glowing_panel_under_the_ceiling_lights_the_room_as_bidir_finds():
    """A closed 2 m room lit by a glowing panel 1 mm under its ceiling (Blender's emission leaves both sides): half
    the panel's light is trapped between its back and the ceiling. vbnl's lights beside the panel took the photons
    trapped there and lent their light to the room: Diffuse Indirect 2.2 times Cycles' in the imported USD Cornell
    box. Without the photons under the lid it agrees with bidir, whose lights stay where the photons land."""
    from vpl_addon.core.camera import Camera, view_window
    from vpl_addon.core.scene import Materials, Scene
    from vpl_addon.render import RenderSettings, render
    ceiling, panel = _ceiling_and_panel()
    x, y, z = np.eye(3) * 2
    walls = [_rect([-1, -1, 0], x, y), ceiling, _rect([-1, -1, 0], y, z), _rect([1, -1, 0], z, y),
             _rect([-1, -1, 0], z, x), _rect([-1, 1, 0], x, z)]
    materials = Materials.make([{"name": "white", "base_color": (0.7, 0.7, 0.7)},
                                {"name": "glow", "emission": (10.0, 10.0, 10.0)}])
    look = np.eye(4)
    look[:3, 3] = [0, 0, 1.5]  # straight down at the floor
    camera = Camera(look, 24, 24, view_window(24, 24, orthographic=True, ortho_scale=1.8), orthographic=True)
    scene = Scene.build(np.concatenate(walls + [panel]), materials, [], camera, material=[1] * 12 + [2] * 2,
                        max_bounces=4)
    means = {}
    for method in ("vbnl", "bidir"):
        out = render(scene, RenderSettings(samples=4, method=method, placement=MethodSettings(vpls=1024),
                                           passes=("Diffuse Indirect", "Diffuse Color"))).passes
        means[method] = out["Diffuse Indirect"][..., :3].mean()
    assert means["vbnl"] == pytest.approx(means["bidir"], rel=0.1), means


def lit_floor(lamp, max_bounces=1):
    """A grey floor and a ceiling 2 m above it, a camera between them looking up at the ceiling, and ``lamp``."""
    from vpl_addon.core.camera import Camera, view_window
    from vpl_addon.core.scene import Scene
    quad = np.array([[[-2, -2, 0], [2, -2, 0], [2, 2, 0]], [[-2, -2, 0], [2, 2, 0], [-2, 2, 0]]], float)
    up = np.diag([1.0, -1.0, -1.0, 1.0])
    up[:3, 3] = [0, 0, 1.5]
    camera = Camera(up, 32, 32, view_window(32, 32, orthographic=True, ortho_scale=3.0), orthographic=True)
    return Scene.build(np.concatenate([quad, quad + [0, 0, 2]]), plane_scene().materials, [lamp], camera,
                       max_bounces=max_bounces)


def test_photon_lights_reproduce_the_radiance_of_a_lit_floor():
    """A point light between a grey floor and a ceiling the camera looks up at: the candidates land on the floor
    (the camera's BSDF rays bounce down from the ceiling), and with one bounce their radiance L_j = I_j / A_j is
    the floor's reflected radiance, albedo E / pi with E = P cos / (4 pi d^2)."""
    lamp = PointLight("lamp", [0.0, 0.0, 1.0], [400.0] * 3)
    scene = lit_floor(lamp)
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


@pytest.mark.parametrize("samples, paths", [(8, 2048), (64, 5000)])
def test_automatic_light_paths_are_a_quarter_of_the_camera_samples(samples, paths, monkeypatch):
    """Light Paths 0 (the default): a render traces pixels x samples / 4 light paths within ``AUTO_PATHS`` (lowered
    here to 1000-5000 to keep the test small: 32 x 32 pixels x 8 samples / 4 = 2048, x 64 capped at 5000); the
    viewport's passes start from the fewest; a count that is set is traced as it is."""
    import vpl_addon.methods.vbnl as V
    from vpl_addon.render import RenderSettings, render
    monkeypatch.setattr(V, "AUTO_PATHS", (1000, 5000))
    scene = lit_floor(PointLight("lamp", [0.0, 0.0, 1.0], [100.0] * 3))
    settings = RenderSettings(samples=samples, light_samples=1, method="vbnl", placement=MethodSettings(vpls=64))
    assert settings.placement.vbnl.photons == 0
    assert render(scene, settings).info["light_paths"] == paths
    assert VBNLSettings().light_paths(0) == 1000 and VBNLSettings(photons=7).light_paths(10 ** 9) == 7


def test_light_gathered_through_coloured_glass_takes_its_colour():
    """The lit floor with a pane of tint (0.3, 0.6, 1) at 1.2 m, between the lamp and the camera's ceiling: the
    ceiling's indirect light comes from the floor's lights through the pane, so the gather's light and BSDF samples
    (``bounce_tinted``) carry its colour (with grey samples, which cross the pane by its luminance, the pass came
    out grey)."""
    from vpl_addon.core.scene import Materials, Scene
    from vpl_addon.render import RenderSettings, render
    tint = np.array([0.3, 0.6, 1.0])
    room = lit_floor(PointLight("lamp", [0.0, 0.0, 1.0], [400.0] * 3))
    pane = room.triangles[:2] + [0.0, 0.0, 1.2]
    materials = Materials.make([{"name": "grey"}, {"name": "pane", "transmission": 1.0, "base_color": tuple(tint)}])
    scene = Scene.build(np.concatenate([room.triangles, pane]), materials, room.lights, room.camera,
                        material=[1, 1, 1, 1, 2, 2], max_bounces=1)
    indirect = render(scene, RenderSettings(samples=16, method="vbnl", passes=("Combined", "Diffuse Indirect"),
                                            placement=MethodSettings(vpls=512))).passes["Diffuse Indirect"]
    colour = indirect.reshape(-1, 3).mean(axis=0)
    assert colour[2] > 0.0 and np.allclose(colour / colour[2], tint, atol=0.03)


@pytest.mark.parametrize("threads", [1, 2])
def test_the_placement_traces_its_photons_on_one_thread_or_more(threads):
    """One tracing thread while the candidates are found, every thread after: a tracer of one thread has no more
    to open (the semaphore refuses to release none)."""
    scene = lit_floor(PointLight("lamp", [0.0, 0.0, 1.0], [100.0] * 3), max_bounces=2)
    tracer = Tracer(scene.triangles, threads=threads)
    context = MethodContext(scene, tracer, LightSet(scene), np.random.default_rng(0), max_bounces=2)
    lights, info = place("vbnl", context, MethodSettings(vpls=64, vbnl=VBNLSettings(photons=3 * PATHS_PER_BATCH)))
    tracer.close()
    assert info["vpls"] == 64 and info["light_paths"] == 3 * PATHS_PER_BATCH
    assert np.isfinite(lights.intensity).all() and lights.intensity.sum() > 0.0


def test_fewer_candidates_than_pixels_come_from_the_whole_image():
    """A camera between a floor and a low ceiling, looking up: each candidate lands on the floor near the pixel
    whose camera path found it. With a quarter as many candidates as pixels they come from all over the image;
    taking the first found in pixel order had kept the top quarter of its rows."""
    from vpl_addon.core.camera import Camera, view_window
    from vpl_addon.core.scene import Scene
    from vpl_addon.methods.vbnl import candidates
    quad = np.array([[[-2, -2, 0], [2, -2, 0], [2, 2, 0]], [[-2, -2, 0], [2, 2, 0], [-2, 2, 0]]], float)
    up = np.diag([1.0, -1.0, -1.0, 1.0])
    up[:3, 3] = [0, 0, 0.1]
    camera = Camera(up, 64, 64, view_window(64, 64, orthographic=True, ortho_scale=3.0), orthographic=True,
                    clip_start=1e-3)
    scene = Scene.build(np.concatenate([quad, quad + [0, 0, 0.2]]), plane_scene().materials, [], camera)
    tracer = Tracer(scene.triangles)
    position, _ = candidates(scene, tracer, 1024, np.random.default_rng(0))
    tracer.close()
    assert len(position) == 1024 and np.abs(position[:, 2]).max() < 1e-6
    for axis in (0, 1):
        assert 0.4 < np.mean(position[:, axis] > 0.0) < 0.6


def test_lights_are_placed_where_they_were_when_the_view_is_the_same():
    """vbnl's candidates and catchments draw from the camera's numbers (``MethodContext.camera_rng``, the same in
    every frame of a sequence) and only its photons from the frame's (``rng``): two frames with their own numbers
    and the camera's place their lights at the same points with the same catchments, and only the lights' light
    differs; with the frame's numbers for everything the points differ (a new draw in every frame: one of the three
    causes of a denoised sequence's flicker)."""
    scene = lit_floor(PointLight("lamp", [0.0, 0.0, 1.0], [100.0] * 3), max_bounces=2)
    tracer = Tracer(scene.triangles)
    settings = MethodSettings(vpls=64, vbnl=VBNLSettings(photons=8192))
    placed = [place("vbnl", MethodContext(scene, tracer, LightSet(scene), np.random.default_rng(frame), 2, camera),
                    settings)[0]
              for frame, camera in ((1, np.random.default_rng(9)), (2, np.random.default_rng(9)), (2, None))]
    tracer.close()
    np.testing.assert_array_equal(placed[0].position, placed[1].position)
    np.testing.assert_array_equal(placed[0].catchment, placed[1].catchment)
    assert not np.array_equal(placed[0].intensity, placed[1].intensity)
    assert not np.array_equal(placed[0].position, placed[2].position)


@pytest.mark.parametrize("light_held", [0.0, 1.0])
def test_the_extension_takes_what_the_covering_lights_leave_whatever_light_they_hold(light_held):
    """A BSDF sample's hit covered by one light whose footprint is wide enough (w_v = 1): the extended path takes
    nothing (1 - mean w_v = 0), whether the light holds light or, by the photons' chance, none. Weighed by the
    lights' radiance, a dark light's hit was extended in full, and the light such lights hold on average was
    counted twice (a room lit through a door left ajar: Diffuse Indirect 1.22x Cycles')."""
    from vpl_addon.methods.vbnl.virtual_light_sampling import _add_samples
    one = np.ones(1)
    out = np.zeros((1, 3))
    mean_share = _add_samples(out, np.zeros(1, np.int64), np.zeros(1, np.int64), np.ones((1, 3)),
                              np.full(1, -1, np.int64), np.zeros(1), one / np.pi, np.zeros((1, 3)),
                              np.array([[0.0, 0.0, 1.0]]), np.array([[0.0, 0.0, 1.0]]), np.array([[0.0, 0.0, -1.0]]),
                              np.zeros((1, 3)), np.zeros(1, np.int64), np.zeros(1, np.int64), one,
                              np.array([[0.0, 0.0, 1.0]]), np.array([[0.0, 0.0, -1.0]]), np.full(1, 0.1), one,
                              np.full((1, 3), light_held), np.full(1, 1e6), 40.0, 40.0, True, np.zeros((1, 3)),
                              np.zeros((1, 3)))
    assert mean_share[0] == 1.0
    assert (out[0, 0] > 0.0) == (light_held > 0.0)  # the lights' part: their light (by MIS, the BSDF sample's share)
