"""The compiled kernels of the gathers and the filter (issue 26) against the formulas they evaluate, written out
plainly on small inputs: the rewrite must give the numbers the numpy passes gave (to rounding)."""
import numpy as np
import pytest

from vpl_addon.core.camera import Camera, view_window
from vpl_addon.core.scene import Materials, Scene
from vpl_addon.core.tracer import Tracer
from vpl_addon.gather import summing
from vpl_addon.gather.bilateral import BRIGHT, NORMAL_POWER, PLANE_SIGMA, bright_apart, deinterleave
from vpl_addon.gather.summing import GatherSettings, gather
from vpl_addon.gather.virtual_lights import VirtualLights
from vpl_addon.lights import LightSet, PointLight
from vpl_addon.materials.microfacet import GlossyLobe
from vpl_addon.materials.surface import Surface, diffuse_cosine
from vpl_addon.methods.vbnl.photon_lights import PhotonLights
from vpl_addon.methods.vbnl import virtual_light_sampling
from vpl_addon.methods.vbnl.virtual_light_sampling import SamplingSettings
from vpl_addon.methods.vbnl.morton import radix_tree
from vpl_addon.methods.vbnl.virtual_light_sampling import _descend, splits
from vpl_addon.methods.vbnl.virtual_light_sampling import gather as sampled_parts
from vpl_addon.paths import vertices
from vpl_addon.paths.gbuffer import GBuffer


def _sampled_gather(*args, **kwargs) -> np.ndarray:
    """The sampled gather's whole light: its two parts (over no metal, over metal) added."""
    near, further = sampled_parts(*args, **kwargs)
    return near + further


def guides(h, w, seed=0):
    """A small G-buffer with a depth step, a turn of the surface, jittered normals and holes."""
    rng = np.random.default_rng(seed)
    grid = np.stack(np.meshgrid(np.arange(w), np.arange(h)) + [np.zeros((h, w))], -1)
    position = 0.01 * grid + 0.002 * rng.normal(size=(h, w, 3))
    position[:, w // 2:, 2] += 0.3
    normal = rng.normal(size=(h, w, 3)) * 0.1 + [0.0, 0.0, 1.0]
    normal[h // 3:] = [1.0, 0.0, 0.0]
    normal /= np.linalg.norm(normal, axis=2, keepdims=True)
    valid = rng.random((h, w)) > 0.15
    footprint = 0.01 * (1.0 + rng.random((h, w)))
    return rng.random((h, w, 3)), position, normal, valid, footprint


def filtered_pixel(image, position, normal, valid, footprint, tile, y, x):
    """One pixel of the cross-bilateral filter, straight from its definition."""
    if not valid[y, x]:
        return image[y, x]
    h, w = valid.shape
    total, acc = 0.0, np.zeros(image.shape[2])
    for yy in range(y - tile, y + tile):
        for xx in range(x - tile, x + tile):
            if 0 <= yy < h and 0 <= xx < w and valid[yy, xx]:
                plane = normal[y, x] @ (position[yy, xx] - position[y, x]) / (PLANE_SIGMA * footprint[y, x])
                agree = np.clip(normal[y, x] @ normal[yy, xx], 0.0, 1.0) ** NORMAL_POWER
                total += np.exp(-plane * plane) * agree
                acc += np.exp(-plane * plane) * agree * image[yy, xx]
    return acc / total if total > 0.0 else image[y, x]


@pytest.mark.parametrize("threads", [1, 3])
@pytest.mark.parametrize("tile", [2, 4])
def test_filter_is_the_weighted_mean_of_its_window(tile, threads):
    """Every pixel of a 13 x 17 image (bands of rows on several threads or one) is the cross-bilateral mean."""
    inputs = guides(13, 17)
    out = deinterleave(*inputs, tile, threads=threads)
    expected = np.array([[filtered_pixel(*inputs, tile, y, x) for x in range(17)] for y in range(13)])
    np.testing.assert_allclose(out, expected, rtol=1e-9, atol=1e-12)


def test_filter_keeps_pixels_without_a_surface_or_weight():
    """Invalid pixels keep their value and give none; a pixel alone in its window keeps its own, and so does one
    that weighs every neighbour 0 (a zero normal: its samples' normals cancelled)."""
    image, position, normal, valid, footprint = guides(9, 9, seed=1)
    valid[:] = False
    valid[4, 4] = valid[0, 0] = valid[0, 1] = True
    normal[0, 0] = 0.0
    out = deinterleave(image, position, normal, valid, footprint, 4, threads=2)
    np.testing.assert_array_equal(out[[0, 4], [0, 4]], image[[0, 4], [0, 4]])
    np.testing.assert_array_equal(np.delete(out.reshape(81, 3), [0, 1, 40], axis=0),
                                  np.delete(image.reshape(81, 3), [0, 1, 40], axis=0))
    assert np.isfinite(out).all()


def test_filter_of_tile_one_is_the_image():
    image = guides(5, 6)[0]
    assert deinterleave(image, *guides(5, 6)[1:], 1) is image


def test_bright_apart_keeps_a_rare_sample_and_spreads_smooth_light():
    """A lone bright pixel on smooth light keeps its excess over BRIGHT times the light around it (so the filter
    spreads little of it); a smooth image, black pixels and its window's other pixels are all spread; the parts sum
    to the image."""
    rng = np.random.default_rng(3)
    image = rng.uniform(0.9, 1.1, (16, 20, 3))
    image[:, :3] = 0.0
    image[8, 10] = [500.0, 100.0, 0.0]
    spread, kept = bright_apart(image, 4)
    np.testing.assert_allclose(spread + kept, image)
    assert 0.9 * BRIGHT < spread[8, 10, 0] < 1.1 * BRIGHT  # BRIGHT times the window's background, about 1
    np.testing.assert_allclose(spread[8, 10] / spread[8, 10, 0], [1.0, 0.2, 0.0])  # its colour kept
    kept[8, 10] = 0.0
    assert not kept.any() and np.isfinite(spread).all()


def test_bright_apart_keeps_rare_samples_on_black_whole():
    """Three bright samples in one 8 x 8 window on black (a caustic's on a dark floor) are kept whole: their
    overlap leaves no faint square to spread. Interleaved light's tile pattern (one VPL subset of sixteen lit) is
    all spread, while a lone sample among it is kept."""
    image = np.zeros((24, 24, 3))
    for y, x in ((10, 10), (12, 14), (15, 11)):
        image[y, x] = 2.0
    spread, kept = bright_apart(image, 4)
    assert not spread.any() and (kept == image).all()
    pattern = np.zeros((24, 24, 3))
    pattern[1::4, 2::4] = 1.0
    spread, kept = bright_apart(pattern, 4, interleaved=True)
    assert not kept.any()
    pattern[9, 13] = 1.0  # of another subset, whose others are dark
    spread, kept = bright_apart(pattern, 4, interleaved=True)
    assert kept[9, 13, 0] == 1.0 and np.count_nonzero(kept) == 3


def block_room():
    """A floor with a box on it and a tilted board above: pairs of floor points and VPLs that the box hides."""
    floor = np.array([[[-3, -3, 0], [3, -3, 0], [3, 3, 0]], [[-3, -3, 0], [3, 3, 0], [-3, 3, 0]]], float)
    corners = np.array([[x, y, z] for x in (-0.3, 0.3) for y in (-0.3, 0.3) for z in (0.0, 0.6)])
    faces = [(0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1), (2, 3, 7), (2, 7, 6), (0, 2, 6),
             (0, 6, 4), (1, 5, 7), (1, 7, 3)]
    board = np.array([[[-2, -2, 2.0], [2, -2, 2.5], [2, 2, 2.5]], [[-2, -2, 2.0], [2, 2, 2.5], [-2, 2, 2.0]]])
    return np.concatenate([floor, corners[np.array(faces)], board])


def floor_points(count, rng):
    """Points on the floor around the box, a third of them with a normal map's bent shading normal."""
    position = np.c_[rng.uniform(-2.5, 2.5, (count, 2)), np.zeros(count)]
    up = np.tile([0.0, 0.0, 1.0], (count, 1))
    bent = up.copy()
    bent[::3] += np.c_[rng.normal(0.0, 0.3, (len(bent[::3]), 2)), np.zeros(len(bent[::3]))]
    bent /= np.linalg.norm(bent, axis=1, keepdims=True)
    k = count
    return Surface(position, up, bent, np.zeros(k, int), np.zeros(k, int), np.ones((k, 3)), np.ones(k), np.zeros(k),
                   np.zeros((k, 3)), np.ones((k, 3)), np.zeros((k, 3)), np.zeros((k, 3)), np.ones(k), -up, up)


def board_vpls(count, rng):
    """VPLs under the board and on the floor (facing up: they light nothing on the floor)."""
    position = np.c_[rng.uniform(-1.8, 1.8, (count, 2)), np.zeros(count)]
    position[:, 2] = np.where(np.arange(count) % 5 == 0, 0.0, 2.25 + 0.125 * position[:, 0] - 1e-3)
    normal = np.where((position[:, 2] > 0.0)[:, None], [0.0, 0.0, -1.0], [0.0, 0.0, 1.0])
    return VirtualLights(position, normal, rng.random((count, 3)), np.ones(count, np.int32),
                         np.zeros(count, np.int8), np.arange(count))


def pair_light(surface, vpls, tracer, d_min, i, j):
    """The light VPL j sends to point i, from the definition (``Tracer.visible`` for V)."""
    w = vpls.position[j] - surface.position[i]
    d = np.linalg.norm(w)
    w = w / d
    cos_x = diffuse_cosine(surface.shading_normal[i:i + 1], surface.smooth_normal[i:i + 1], w[None])[0]
    cos_v = -vpls.normal[j] @ w
    if not (cos_x > 0.0 and cos_v > 0.0 and surface.geometric_normal[i] @ w > 0.0):
        return np.zeros(3)
    seen = tracer.visible(surface.position[i:i + 1], surface.geometric_normal[i:i + 1], w[None], np.array([d]),
                          vpls.normal[j:j + 1])[0]
    return vpls.intensity[j] * cos_x * cos_v / (np.pi * max(d * d, d_min * d_min)) * seen


@pytest.mark.parametrize("interleave", [1, 2])
def test_summing_gather_is_the_sum_of_its_pairs(interleave):
    """The gather (exact, and interleaved: each point its tile position's subset, scaled to the whole set) adds up
    the pairs' light as defined, with the box's shadows, the bump term of bent normals and the clamp."""
    rng = np.random.default_rng(3)
    tracer = Tracer(block_room())
    points, vpls = floor_points(40, rng), board_vpls(30, rng)
    xy = rng.integers(0, 8, (40, 2))
    permutation = rng.permutation(30)
    d_min = 2.3  # nearer than this the geometry term is clamped (the board is 2 to 2.5 above the floor)
    out = gather(points, xy, vpls, tracer, GatherSettings(interleave=interleave), d_min, permutation)
    expected = np.zeros((40, 3))
    groups = interleave * interleave
    for i in range(40):
        g = (xy[i, 1] % interleave) * interleave + xy[i, 0] % interleave
        subset = permutation[g::groups]
        expected[i] = sum(pair_light(points, vpls, tracer, d_min, i, j) for j in subset) * 30 / len(subset)
    unshadowed = gather(points, xy, vpls, Tracer(np.zeros((0, 3, 3))), GatherSettings(interleave=interleave), d_min,
                        permutation)
    assert (out > 0).all() and (out < unshadowed - 0.01).any(axis=1).sum() >= 3  # lit; the box shadows
    np.testing.assert_allclose(out, expected, rtol=1e-9, atol=1e-15)


def test_pairs_sum_by_vpl_in_batches(monkeypatch):
    """``sum_pairs`` by VPL (bidir's camera power) over batches smaller than the pairs is the pairs' sum."""
    rng = np.random.default_rng(8)
    tracer = Tracer(block_room())
    points, vpls = floor_points(25, rng), board_vpls(12, rng)
    point_index, vpl_index = rng.integers(0, 25, 200), rng.integers(0, 12, 200)
    monkeypatch.setattr(summing, "PAIRS_PER_BATCH", 7)
    out = summing.sum_pairs(points, point_index, vpls, vpl_index, tracer, 0.1, vpl_index, 12)
    expected = np.zeros((12, 3))
    for i, j in zip(point_index, vpl_index):
        expected[j] += pair_light(points, vpls, tracer, 0.1, i, j)
    np.testing.assert_allclose(out, expected, rtol=1e-9, atol=1e-15)


def metal_plate_room(metallic=1.0):
    """A red floor and wall, a tilted metal plate and a lamp; 3 bounces (camera paths extend twice)."""
    floor = np.array([[[-3, -3, 0], [3, -3, 0], [3, 3, 0]], [[-3, -3, 0], [3, 3, 0], [-3, 3, 0]]], float)
    wall = np.array([[[-3, 2, 0], [3, 2, 0], [3, 2, 4]], [[-3, 2, 0], [3, 2, 4], [-3, 2, 4]]], float)
    plate = np.array([[[-1, -1, 0.5], [1, -1, 0.5], [1, 1, 0.8]], [[-1, -1, 0.5], [1, 1, 0.8], [-1, 1, 0.8]]])
    materials = Materials.make([{"name": "red", "base_color": (0.8, 0.2, 0.1)},
                                {"name": "metal", "base_color": (0.9, 0.7, 0.5), "metallic": metallic,
                                 "roughness": 0.3}])
    view = np.eye(4)
    view[:3, 3] = [0.0, -1.0, 3.0]
    camera = Camera(view, 12, 12, view_window(12, 12, orthographic=True, ortho_scale=5.0), orthographic=True,
                    clip_start=1e-3)
    return Scene.build(np.concatenate([floor, wall, plate]), materials,
                       [PointLight("lamp", [0.5, 0, 2.5], [300.0] * 3)], camera, material=[0, 0, 1, 1, 2, 2],
                       max_bounces=3)


def grid_lights(rng):
    """Photon lights on a grid on the floor and the wall, with random light of 1, 2 and 3 bounces."""
    grid = np.stack(np.meshgrid(np.linspace(-2.5, 2.5, 8), np.linspace(-2.5, 1.5, 7)), -1).reshape(-1, 2)
    on_wall = np.c_[grid[:, 0], np.full(len(grid), 2.0), grid[:, 1] + 2.5]
    position = np.concatenate([np.c_[grid, np.zeros(len(grid))], on_wall])
    normal = np.repeat([[0.0, 0.0, 1.0], [0.0, -1.0, 0.0]], len(grid), axis=0)
    by_bounce = np.cumsum(rng.random((len(position), 3, 3)), axis=1)
    return PhotonLights(position, normal, np.full(len(position), 0.8), by_bounce[:, -1],
                        catchment=rng.uniform(1.0, 2.0, len(position)), by_bounce=by_bounce)


def test_sampled_gather_gives_the_light_it_gave_before_its_kernels(monkeypatch):
    """The photon lights' gather (light and BSDF samples with MIS, camera paths extended through the diffuse part
    and through metal) for fixed lights, points and random numbers: the sums the numpy version gave (commit
    cafd915), for the diffuse lobe and the metallic one, recorded again when the light samples went from the cone
    of a light's sphere to its disc (that they stay unbiased is the test below; the cone gave 90.90, 86.60, 91.96
    and 2413 rays) and when a vertex's numbers were reordered to come in 2D pairs, the BSDF's first (the old order
    gave 96.47, 91.90, 96.84, 0.838 and 2173 rays with the code of the new order), and when Russian roulette's numbers
    came one for every extended vertex, as keyed numbers come (``sampling.PathNumbers``; the diffuse sums had been
    95.58, 87.56, 90.88 and 47215 weighted, and 2170 rays), and when the light's choice came to descend a tree with a
    number per level (``_descend``; 97.14, 88.54, 91.85, 47698, glossy 0.781, 0.667, 0.531 and 2177 rays; over 20
    seeds the diffuse and glossy sums agree with the old code's: 267 +- 4 against 266 +- 5, 1.69 +- 0.08 against
    1.85 +- 0.11), and when a metallic vertex's next-event samples went from 8 to 4 (``GLOSSY_LIGHT_SAMPLES``;
    97.34, 87.36, 92.48, 48768 and 2141 rays, now 2139; over 20 seeds 263 +- 5 against 265 +- 5, the glossy sums 1.693 +-
    0.080 both). Russian roulette came later than the rest: here every
    path with a throughput goes on, as it did then (``test_roulette`` tests the roulette)."""
    def every_path(weight, rng, u=None):
        rows = np.nonzero(weight.max(axis=1) > 0.0)[0]
        return rows, np.ones(len(rows))
    monkeypatch.setattr(virtual_light_sampling, "roulette", every_path)
    monkeypatch.setattr(vertices, "roulette", every_path)
    scene = metal_plate_room()
    tracer = Tracer(scene.triangles)
    lights = grid_lights(np.random.default_rng(2))
    sampling = SamplingSettings(n_min=0.5, n_max=3.0)  # sparse lights: some hits extend, some do not
    surface = GBuffer.build(scene, tracer, np.arange(144), 4, np.random.default_rng(3)).surface
    light_set = LightSet(scene)
    diffuse = _sampled_gather(surface, lights, scene, tracer, light_set, np.random.default_rng(4), sampling, 3)
    glossy = _sampled_gather(surface, lights, scene, tracer, light_set, np.random.default_rng(5), sampling, 3,
                            GlossyLobe.of(surface))
    # to 1e-6: numpy's float64 sines and cosines differ in their last bits between CPUs (AVX-512 or not), which
    # moves these sums by 6e-8 (recorded on an AVX-512 CPU; an AMD EPYC without it gives 97.335169...); every
    # change of the code recorded above moved them by 1e-3 or more
    np.testing.assert_allclose(diffuse.sum(axis=0), [97.37484899247264, 88.27370532170818, 92.89334123498713],
                               rtol=1e-6)
    assert (diffuse * np.arange(len(diffuse))[:, None]).sum() == pytest.approx(49264.18649558548, rel=1e-6)
    np.testing.assert_allclose(glossy.sum(axis=0), [0.8320080798107234, 0.6101019520334934, 0.47211111760220387],
                               rtol=1e-6)
    assert tracer.rays_traced == 2139  # light samples that see their disc edge-on are not traced


def test_light_samples_toward_the_discs_keep_the_gather_unbiased(monkeypatch):
    """The light samples (a point on the drawn light's disc) and the BSDF samples, weighed by MIS with the discs'
    pdf, estimate the same light as BSDF samples alone (light sampling off: every light's choice 0, so the BSDF
    samples keep their whole weight): one bounce from the lights, the sums of each point's 1024 estimates agree to
    the noise (about 0.6 %: 15727-15851 against 15683-15852 over four seeds; with 512 estimates a seed's draw was
    2.3 % off once), and the MIS estimate's relative spread is smaller (1.75 against 2.99; 2.14 with the cone of
    the light's sphere)."""
    scene = metal_plate_room()
    tracer = Tracer(scene.triangles)
    lights = grid_lights(np.random.default_rng(2))
    surface = GBuffer.build(scene, tracer, np.arange(144), 1, np.random.default_rng(3)).surface
    surface = surface.take(np.nonzero(~surface.glossy)[0])
    many = surface.take(np.repeat(np.arange(len(surface)), 1024))
    sampling = SamplingSettings(extension=False)
    light_set = LightSet(scene)
    both = _sampled_gather(many, lights, scene, tracer, light_set, np.random.default_rng(4), sampling, 1)
    estimate = virtual_light_sampling._estimate

    def bsdf_alone(v, out, lights, scene, tracer, light_set, numbers, rng, settings, radiance, choice, *rest):
        return estimate(v, out, lights, scene, tracer, light_set, numbers, rng, settings, radiance, 0.0 * choice,
                        rest[0], rest[1], 0.0, *rest[3:])
    monkeypatch.setattr(virtual_light_sampling, "_estimate", bsdf_alone)
    alone = _sampled_gather(many, lights, scene, tracer, light_set, np.random.default_rng(5), sampling, 1)
    per_point = [e.sum(axis=1).reshape(len(surface), -1) for e in (both, alone)]
    assert per_point[0].sum() == pytest.approx(per_point[1].sum(), rel=0.02)
    spread = [(p.std(axis=1) / np.maximum(p.mean(axis=1), 1e-12)).mean() for p in per_point]
    assert spread[0] < 0.7 * spread[1]


def test_a_pixels_sample_pairs_from_one_net_each_cut_its_noise():
    """The gather's pairs of one pixel drawn from scrambled nets (``pixel``: the BSDF's direction, the light's point,
    the light's choice, at every depth) estimate the same light as independent numbers, with a pixel's mean of 64
    pairs spread over seeds 2.35x less (0.077 against 0.181 of its value, 8 seeds; cornell_area's picture as
    rendered at 64 pairs: rMAE 0.063 -> 0.035)."""
    scene = metal_plate_room()
    tracer = Tracer(scene.triangles)
    lights = grid_lights(np.random.default_rng(2))
    surface = GBuffer.build(scene, tracer, np.arange(144), 1, np.random.default_rng(3)).surface
    surface = surface.take(np.nonzero(~surface.glossy)[0])
    pixel = np.repeat(np.arange(len(surface)), 64)
    sampling = SamplingSettings(n_min=0.5, n_max=3.0)  # some hits extend
    light_set = LightSet(scene)
    means = {}
    for nets in (True, False):
        means[nets] = np.array([_sampled_gather(surface.take(pixel), lights, scene, tracer, light_set,
                                               np.random.default_rng(seed), sampling, 3,
                                               pixel=pixel if nets else None).sum(axis=1).reshape(-1, 64).mean(axis=1)
                                for seed in range(4)])
    assert means[True].mean() == pytest.approx(means[False].mean(), rel=0.03)
    spread = {nets: (m.std(axis=0) / m.mean(axis=0)).mean() for nets, m in means.items()}
    assert spread[True] < 0.6 * spread[False]


def test_gather_batches_hold_at_most_their_budget_of_pairs(monkeypatch):
    """Every point meets its whole subset, no batch exceeds ``PAIRS_PER_BATCH`` pairs unless one point's subset
    does, and the gather in small batches is the gather in one."""
    monkeypatch.setattr(summing, "PAIRS_PER_BATCH", 10)
    points = [np.arange(0, 7), np.arange(7, 9), np.arange(9, 12)]
    subsets = [np.arange(3), np.arange(3, 15), np.array([15, 16])]
    batches = list(summing._batches(points, subsets))
    assert all(len(p) <= 10 or len(np.unique(p)) == 1 for p, _ in batches)
    pairs = sorted(zip(*(np.concatenate(column).tolist() for column in zip(*batches))))
    assert pairs == sorted((i, j) for pts, sub in zip(points, subsets) for i in pts for j in sub)
    rng = np.random.default_rng(5)
    tracer = Tracer(block_room())
    surface, vpls = floor_points(30, rng), board_vpls(40, rng)
    xy, permutation = rng.integers(0, 8, (30, 2)), rng.permutation(40)
    small = gather(surface, xy, vpls, tracer, GatherSettings(), 0.1, permutation)
    monkeypatch.setattr(summing, "PAIRS_PER_BATCH", 1 << 20)
    np.testing.assert_allclose(small, gather(surface, xy, vpls, tracer, GatherSettings(), 0.1, permutation),
                               rtol=1e-12)


def test_a_path_gathers_the_same_light_whatever_other_paths_are_traced_with_it():
    """A pixel's paths take numbers keyed by the path and its depth (``sampling.PathNumbers``), so a path's light
    does not depend on which other paths are traced with it: half the pixels gathered alone give the light they
    give among all. Numbers drawn one after another changed with any path that stopped or went on elsewhere (a
    Russian roulette decision that a 0.1 % change of a light's intensity flips): a frame of a sequence had all its
    noise drawn anew."""
    scene = metal_plate_room(metallic=0.0)  # a metallic vertex's numbers are not keyed
    tracer = Tracer(scene.triangles)
    lights = grid_lights(np.random.default_rng(2))
    surface = GBuffer.build(scene, tracer, np.arange(144), 1, np.random.default_rng(3)).surface
    pixel = np.repeat(np.arange(len(surface)), 16)
    half = np.nonzero(pixel % 2 == 0)[0]
    sampling = SamplingSettings(n_min=0.5, n_max=3.0)  # some hits extend, and go on by roulette
    light_set = LightSet(scene)
    every = _sampled_gather(surface.take(pixel), lights, scene, tracer, light_set, np.random.default_rng(5), sampling,
                           3, pixel=pixel)
    alone = _sampled_gather(surface.take(pixel[half]), lights, scene, tracer, light_set, np.random.default_rng(5),
                           sampling, 3, pixel=pixel[half])
    assert every[half].sum() > 0.0
    np.testing.assert_allclose(alone, every[half], rtol=1e-12, atol=1e-300)


def test_the_light_tree_draws_by_power_and_changes_few_draws_when_the_lights_change_a_little():
    """``virtual_light_sampling._descend`` draws light j with probability P_j / sum P (a light without power
    never), as inverting the cumulative power does. When every power changes by 1 % (independently), few draws
    change: 0.96 %, against a total variation between the two distributions of 0.40 % (the least any coupling of
    two draws can change), where inverting the cumulative power with one number changed 7.5 %; and a light taken
    away from the middle changes 0.1 % of the draws (the tree is split by the codes, not by counts)."""
    rng = np.random.default_rng(7)
    power = rng.random(1000) ** 4
    power[::7] = 0.0
    code = np.sort(rng.choice(1 << 40, 1000, replace=False)).astype(np.uint64)

    def cdf(p):
        return np.r_[0.0, np.cumsum(p / p.sum())]

    def descend(p, code, u):
        return _descend(*splits(cdf(p), *radix_tree(code)), u)
    u = rng.random((len(power).bit_length() + 4, 400_000))
    drawn = descend(power, code, u)
    share = np.bincount(drawn, minlength=len(power)) / u.shape[1]
    assert share[::7].sum() == 0.0
    expected = power / power.sum()
    assert np.abs(share - expected).sum() < 0.05  # the sampling noise of 400,000 draws is about 0.035
    assert np.abs(np.bincount(descend(power, code, u[:2]), minlength=len(power)) / u.shape[1]
                  - expected).sum() < 0.05  # two numbers, rescaled below: the same probabilities
    changed = power * (1.0 + 0.01 * rng.standard_normal(len(power)))
    again = descend(changed, code, u)
    variation = 0.5 * np.abs(changed / changed.sum() - expected).sum()
    assert (again != drawn).mean() < 3.0 * variation
    inverted = [np.minimum(np.searchsorted(cdf(p)[1:], u[0], side="right"), len(p) - 1) for p in (power, changed)]
    assert (inverted[0] != inverted[1]).mean() > 5.0 * (again != drawn).mean()
    kept = np.delete(np.arange(len(power)), 500)
    without = kept[descend(power[kept], code[kept], u)]
    assert (without != drawn).mean() < 0.005
    one = tuple(np.zeros(0, np.int64) for _ in range(5))
    assert _descend(*splits(np.array([0.0, 1.0]), *one), u[:1, :5]).tolist() == [0] * 5  # one light
    assert set(descend(np.array([0.0, 1.0]), np.zeros(2, np.uint64), u[:1]).tolist()) == {1}  # no power: never
