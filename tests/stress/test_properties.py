"""Properties every method must keep, checked on scenes drawn by hypothesis (issue 8, item 2): scale and
translation invariance, determinism for a fixed seed, energy below the furnace bound, clamping that only removes
light, and convergence with the VPL budget. Examples are few and derandomized so CI is reproducible."""
import functools

import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

from stress_scenes import budget, METHODS, box, look_at, room, small_settings, tally
from vpl_addon.core.scene import Materials, Scene
from vpl_addon.evaluation.metrics import errors
from vpl_addon.gather.summing import GatherSettings
from vpl_addon.lights import PointLight
from vpl_addon.render import render

VPL_METHODS = METHODS[1:]
# few derandomized examples and no shrinking (a failing render-heavy example took ten minutes to shrink)
NO_SHRINK = [Phase.explicit, Phase.generate]
FEW = settings(max_examples=4, deadline=None, derandomize=True, phases=NO_SHRINK,
               suppress_health_check=[HealthCheck.too_slow])

# a light somewhere in the room, not touching the walls
light_position = st.tuples(st.floats(-0.8, 0.8), st.floats(-0.8, 0.8), st.floats(0.2, 1.8))


def indirect(scene, method, seed=0, vpls=256, **overrides):
    values = dict(seed=seed, placement=budget(vpls), gather=GatherSettings())
    result = render(scene, small_settings(method, **{**values, **overrides}))
    return result.passes["Diffuse Indirect"]


@functools.lru_cache(maxsize=None)
def unit_room(method):
    """The unit room near the origin with seeds 0 and 1, and their rMAE: the method's own noise."""
    a, b = indirect(room(), method, 0), indirect(room(), method, 1)
    return a, errors(b, a)["rmae"]


@pytest.mark.parametrize("method", VPL_METHODS)
@FEW
@given(log_scale=st.floats(-4.0, 4.0))
def test_scale_invariance(method, log_scale):
    """The room scaled by s = 10^k (light power by s^2, so radiance is unchanged) renders the image of the unit room
    within the method's noise: rMAE below 1.5x its seed-to-seed rMAE."""
    s = 10.0 ** log_scale
    base, noise = unit_room(method)
    assert errors(indirect(room(scale=s), method), base)["rmae"] < 1.5 * noise


@pytest.mark.parametrize("method", VPL_METHODS)
@FEW
@given(offset=st.tuples(*[st.floats(-1e5, 1e5)] * 3))
def test_translation_invariance(method, offset):
    """The room moved anywhere within 100 km of the origin renders the image of the room at the origin within the
    method's noise."""
    base, noise = unit_room(method)
    assert errors(indirect(room(offset=offset), method), base)["rmae"] < 1.5 * noise


@FEW
@given(method=st.sampled_from(METHODS), seed=st.integers(0, 2 ** 31 - 1), light=light_position)
def test_fixed_seed_gives_bitwise_identical_passes(method, seed, light):
    """Two renders with the same seed are bitwise identical in every pass, even with the pixels split into blocks
    that run concurrently; another seed gives another image."""
    scene = room(lights=[PointLight("lamp", light, [100.0] * 3)])

    def passes(s):
        result = render(scene, small_settings(method, seed=s, block_pixels=48))
        return result.passes
    first, again, other = passes(seed), passes(seed), passes(seed + 1)
    assert all(np.array_equal(first[name], again[name]) for name in first)
    assert not np.array_equal(first["Combined"], other["Combined"])


@FEW
@given(method=st.sampled_from(VPL_METHODS), albedo=st.floats(0.0, 1.0), bounces=st.integers(1, 4),
       size=st.tuples(st.floats(0.2, 5.0), st.floats(0.2, 5.0), st.floats(0.2, 5.0)))
def test_energy_never_above_the_furnace_bound(method, albedo, bounces, size):
    """A closed box of any proportions whose walls emit Le = 1 and reflect albedo a: the mean Diffuse Indirect of
    four seeds never exceeds the analytic a + ... + a^B (10 % for noise), nor Diffuse Direct the emitted Le. One
    render of 256 VPLs is too noisy for that margin in a thin box (ir in a 0.24 x 1.59 x 2.81 box, a = 0.56, three
    bounces: 0.85-1.23 of the bound over six seeds, 1.00 at 4096 VPLs); four of 1024 stay within 2 % of it."""
    glowing = Materials.make([{"name": "glowing", "base_color": (albedo,) * 3, "emission": (1.0, 1.0, 1.0)}])
    stretch = np.asarray(size) / 2.0
    scene = Scene.build(box([-1, -1, 0], [1, 1, 2]) * stretch, glowing, [],
                        look_at(np.array([0.5, -0.9, 1.0]) * stretch, np.array([0, 0.5, 0.6]) * stretch),
                        material=np.ones(12, int), max_bounces=bounces)
    results = [render(scene, small_settings(method, placement=budget(1024), seed=seed)) for seed in range(4)]
    assert sum(tally("furnace of random proportions", result) for result in results) == 0
    bound = sum(albedo ** k for k in range(1, bounces + 1))
    assert np.mean([result.passes["Diffuse Indirect"].mean() for result in results]) <= 1.1 * bound + 1e-6
    assert max(result.passes["Diffuse Direct"].mean() for result in results) <= 1.1


@FEW
@given(light=st.tuples(st.floats(-0.999, 0.999), st.floats(-0.999, 0.999), st.floats(0.001, 1.999)),
       clamps=st.lists(st.floats(0.0, 4.0), min_size=2, max_size=2, unique=True).map(sorted))
def test_clamping_only_removes_light(light, clamps):
    """Geometry-term clamping at any distance, with the light anywhere (even touching a wall): no pixel is
    negative or non-finite, and a larger clamp never adds light to any pixel (same VPLs, same filter weights)."""
    scene = room(lights=[PointLight("lamp", light, [100.0] * 3)])
    weak, strong = (indirect(scene, "ir", gather=GatherSettings(clamp=c)) for c in clamps)
    for image in (weak, strong):
        assert np.isfinite(image).all() and (image >= 0).all()
    assert (strong <= weak * (1 + 1e-5) + 1e-12).all()


# VPL budgets to compare: 16, 64, 256, except for ir, which returns every VPL of at least 64 light paths (about
# 250 in this room), so that below 256 its error cannot fall. Measured when this test was written (reported to the
# lead): bidir's error stops falling past about 256 VPLs here (rMAE 0.07-0.09 against ir with 16384 VPLs at 256,
# 1024 and 2048), and vbnl's is lower with 4 lights than with 16 (0.06 against 0.15).
BUDGETS = {"ir": (256, 1024, 4096)}


@pytest.mark.parametrize("method", VPL_METHODS)
@settings(max_examples=2, deadline=None, derandomize=True, phases=NO_SHRINK)
@given(light=light_position)
def test_error_falls_as_the_budget_grows(method, light):
    """The error against 16384 VPLs (ir with the same seed, so the same camera samples), averaged over four seeds,
    falls as the VPL budget grows: to below 70 % over a 16x budget, and no 4x step makes it worse."""
    scene = room(lights=[PointLight("lamp", light, [100.0] * 3)])
    seeds = range(4)
    references = [indirect(scene, "ir", seed, vpls=16384) for seed in seeds]
    error = [np.mean([errors(indirect(scene, method, seed, vpls), references[seed])["rmae"] for seed in seeds])
             for vpls in BUDGETS.get(method, (16, 64, 256))]
    assert error[-1] < 0.7 * error[0] and all(b < 1.05 * a for a, b in zip(error, error[1:])), error
