"""The denoiser in the engine (issue 23), without Blender: its progress and ESC reach into OIDN's filter runs, guides
of many samples go to it as clean, and a system without OIDN gets one warning and the picture as rendered."""
import sys
from dataclasses import replace

import numpy as np
import pytest

from conftest import plane_scene
from vpl_addon.core import passes as P
from vpl_addon.core.denoise import CLEAN_GUIDES, denoise
from vpl_addon.lights import PointLight
from vpl_addon.render import Cancelled, RenderSettings, render

SETTINGS = RenderSettings(method="none", samples=2, light_samples=1, passes=(P.COMBINED, P.NOISY_IMAGE),
                          denoise=True, seed=3)


def _lit():
    """A floor under a point light, 48 x 48 pixels of noisy direct light."""
    return plane_scene([PointLight("lamp", [1.0, 0.0, 2.0], [200.0] * 3, radius=0.5)], res=48)


@pytest.mark.parametrize("prefilter", ["ACCURATE", "FAST"])
def test_progress_reaches_into_the_denoiser(prefilter):
    """OIDN's own progress (Accurate: its three runs, the two guides, then the colour; Fast: one run) arrives as
    "denoising" between 0 and 1, rising, and the picture comes out denoised."""
    heard = []
    result = render(_lit(), replace(SETTINGS, denoise_prefilter=prefilter),
                    lambda fraction, text: heard.append((text, fraction)))
    steps = [fraction for text, fraction in heard if text == "denoising"]
    assert len(steps) > 6 and steps[0] == 0.0 and 0.9 < steps[-1] <= 1.0
    assert steps == sorted(steps)
    assert sum(0.0 < f < 1.0 for f in steps) > 4  # from inside the filter runs, not only around them
    noisy, clean = result.passes[P.NOISY_IMAGE][..., :3], result.passes[P.COMBINED][..., :3]
    assert np.isfinite(clean).all() and np.abs(clean - noisy).mean() > 0.01 * noisy.mean()


@pytest.mark.parametrize("samples, runs_as", [(CLEAN_GUIDES - 1, "ACCURATE"), (CLEAN_GUIDES, "NONE")])
def test_accurate_takes_guides_of_many_samples_as_clean(samples, runs_as):
    """Accurate denoises the guides first below ``CLEAN_GUIDES`` camera samples per pixel and hands them over as
    they are from there on (``prefilter_for``): the render's Combined is, to the bit, OIDN run that way on its Noisy
    Image and guides, and the two ways differ (so the check can fail)."""
    passes = (P.COMBINED, P.NOISY_IMAGE, P.DENOISING_ALBEDO, P.DENOISING_NORMAL)
    result = render(_lit(), replace(SETTINGS, samples=samples, passes=passes))
    images = [result.passes[name][..., :3] for name in passes[1:]]
    ways = {way: denoise(*images, prefilter=way) for way in ("ACCURATE", "NONE")}
    np.testing.assert_array_equal(result.passes[P.COMBINED][..., :3], ways[runs_as])
    assert np.abs(ways["ACCURATE"] - ways["NONE"]).max() > 0.0


def _corner():
    """A floor and a wall standing on it, lit by a point light beside the wall: light the wall throws onto the
    floor, 40 x 40 pixels seen from above."""
    from vpl_addon.core.scene import Materials, Scene
    floor = plane_scene(res=40)
    wall = np.array([[[0.5, -10, 0], [0.5, 10, 0], [0.5, 10, 3]], [[0.5, -10, 0], [0.5, 10, 3], [0.5, -10, 3]]])
    return Scene.build(np.concatenate([floor.triangles, wall]), Materials.make([]),
                       [PointLight("lamp", [0.2, 0.0, 0.6], [60.0] * 3, radius=0.05)], floor.camera)


@pytest.mark.parametrize("apart", [True, False])
def test_the_indirect_light_is_denoised_apart_from_the_rest(apart):
    """With Indirect Light Apart (the default) the render's Combined is, to the bit, OIDN on its Noisy Image less
    the indirect light (Diffuse Color x Diffuse Indirect) plus OIDN on the indirect light, with the same guides; off,
    OIDN on Noisy Image whole; the two differ (so the check can fail). OIDN's progress then spans four runs (the
    guides, the two parts) and still rises to the end."""
    passes = (P.COMBINED, P.NOISY_IMAGE, P.DENOISING_ALBEDO, P.DENOISING_NORMAL, P.DIFFUSE_COLOR, P.DIFFUSE_INDIRECT)
    settings = replace(SETTINGS, method="vbnl", samples=4, passes=passes, denoise_indirect_apart=apart)
    assert RenderSettings().denoise_indirect_apart
    heard = []
    result = render(_corner(), settings, lambda fraction, text: heard.append((text, fraction)))
    noisy, albedo, normal = (result.passes[name][..., :3] for name in passes[1:4])
    indirect = result.passes[P.DIFFUSE_COLOR][..., :3] * result.passes[P.DIFFUSE_INDIRECT][..., :3]
    assert indirect.mean() > 0.05 * noisy.mean()  # the floor has indirect light
    ways = {True: denoise(noisy, albedo, normal, apart=indirect), False: denoise(noisy, albedo, normal)}
    np.testing.assert_array_equal(result.passes[P.COMBINED][..., :3], ways[apart])
    assert np.abs(ways[True] - ways[False]).max() > 1e-3 * noisy.mean()
    steps = [fraction for text, fraction in heard if text == "denoising"]
    assert steps == sorted(steps) and 0.9 < steps[-1] <= 1.0


@pytest.mark.parametrize("stop_at", [0.0, 0.2, 0.8])
def test_esc_while_denoising_cancels(stop_at):
    """ESC before the denoiser, in the guides' prefiltering or in the colour's run stops the render (Cancelled),
    without OIDN finishing the run it was in."""
    heard = []

    def progress(fraction, text):
        heard.append((text, fraction))
        return not (text == "denoising" and fraction >= stop_at)
    with pytest.raises(Cancelled):
        render(_lit(), SETTINGS, progress)
    last = heard[-1]
    assert last[0] == "denoising" and stop_at <= last[1] < stop_at + 0.2


def test_denoising_settings_are_cycles_names():
    """A prefilter or quality that is not one of Cycles' names fails at once, naming the setting."""
    from vpl_addon.progressive import ViewportSettings
    with pytest.raises(ValueError, match="prefilter 'SLOW'"):
        RenderSettings(denoise_prefilter="SLOW")
    with pytest.raises(ValueError, match="quality 'high'"):
        ViewportSettings(denoise_quality="high")


def test_without_oidn_one_warning_and_the_picture_as_rendered(monkeypatch):
    """A system where OIDN cannot load (here: its module made unimportable) renders: one warning that names
    OpenImageDenoise, and Combined exactly as without denoising."""
    as_rendered = render(_lit(), replace(SETTINGS, denoise=False))
    monkeypatch.setitem(sys.modules, "pyoidn", None)
    result = render(_lit(), SETTINGS)
    assert len(result.warnings) == 1 and "OpenImageDenoise" in result.warnings[0], result.warnings
    np.testing.assert_array_equal(result.passes[P.COMBINED], as_rendered.passes[P.COMBINED])


def test_a_denoised_render_leaves_the_indirect_light_unfiltered_for_oidn(monkeypatch):
    """Before OIDN the gather's filter costs more than it removes (docs/decisions/0002-filter-before-oidn.md): a
    denoised render's indirect light is the unfiltered one; where OIDN cannot load, the picture stays as rendered, so
    it is filtered as without denoising."""
    from test_sequence import lamp_scene
    from vpl_addon.gather.summing import GatherSettings
    from vpl_addon.methods import MethodSettings
    settings = RenderSettings(method="ir", samples=2, light_samples=1, seed=3, denoise=True,
                              passes=(P.COMBINED, P.DIFFUSE_INDIRECT), placement=MethodSettings(vpls=256),
                              gather=GatherSettings(interleave=2))
    denoised = render(lamp_scene(), settings).passes[P.DIFFUSE_INDIRECT]
    unfiltered = render(lamp_scene(), replace(settings, denoise=False, gather=GatherSettings(interleave=2,
                                                                                             filter=False)))
    filtered = render(lamp_scene(), replace(settings, denoise=False)).passes[P.DIFFUSE_INDIRECT]
    assert denoised.max() > 0 and not np.array_equal(filtered, unfiltered.passes[P.DIFFUSE_INDIRECT])
    np.testing.assert_array_equal(denoised, unfiltered.passes[P.DIFFUSE_INDIRECT])
    monkeypatch.setitem(sys.modules, "pyoidn", None)
    np.testing.assert_array_equal(render(lamp_scene(), settings).passes[P.DIFFUSE_INDIRECT], filtered)
