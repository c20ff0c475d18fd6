"""No square blocks in the light passes (issue 70), without Blender: a white floor under a low sun, with a small
rough metal plate standing over it that throws the sun's light down onto the floor. A camera path from the floor
that finds the plate, and at the plate the sun, is a rare bright sample (a caustic, as in Cycles' own paths); the
gather's filter, which evens out the interleaving over 2t x 2t windows, once spread each such sample over a flat
square of that size. The floor gets no other indirect light (its own VPLs cannot light it), so such a square
stands out on a black ground. The same caustic's samples are what Clamp Indirect, as in Cycles, cuts down."""
import numpy as np
import pytest

from vpl_addon.core.camera import Camera, view_window
from vpl_addon.core.scene import Materials, Scene
from vpl_addon.evaluation.flat_blocks import flat_blocks
from vpl_addon.lights.sun import SunLight
from vpl_addon.methods import METHODS
from vpl_addon.paths.light_paths import SHARP
from vpl_addon.render import RenderSettings, render

LIGHT_PASSES = ("Diffuse Direct", "Diffuse Indirect", "Glossy Direct", "Glossy Indirect", "Combined")
SIZE = 48


def _plate_over_a_floor(roughness: float = 0.3, far: float = 20.0) -> Scene:
    """The plate (``roughness``) over a floor 2 ``far`` wide, seen from above."""
    half = 0.2
    normal = np.array([-2.0, 0.0, -1.0]) / np.sqrt(5.0)  # toward the low sun and down to the floor
    side, up = np.array([0.0, half, 0.0]), half * np.array([-1.0, 0.0, 2.0]) / np.sqrt(5.0)
    centre = np.array([0.5, 0.0, 0.6])
    a, b, c, d = centre - side - up, centre + side - up, centre + side + up, centre - side + up
    plate = [[a, b, c], [a, c, d]] if np.cross(b - a, c - a) @ normal > 0 else [[a, c, b], [a, d, c]]
    tri = np.array([[[-far, -far, 0], [far, -far, 0], [far, far, 0]],
                    [[-far, -far, 0], [far, far, 0], [-far, far, 0]], *plate], float)
    materials = Materials.make([{"name": "white", "base_color": (0.8, 0.8, 0.8)},
                                {"name": "metal", "base_color": (0.95, 0.9, 0.8), "metallic": 1.0,
                                 "roughness": roughness}])
    look = np.eye(4)
    look[:3, 3] = [0.0, 0.0, 4.0]  # straight down at the floor around the plate
    cam = Camera(look, SIZE, SIZE, view_window(SIZE, SIZE, orthographic=True, ortho_scale=3.0), orthographic=True)
    sun = SunLight("sun", [1.0, 0.0, -0.3], [3.0] * 3)
    return Scene.build(tri, materials, [sun], cam, material=[1, 1, 2, 2])


@pytest.mark.parametrize("method", list(METHODS))
def test_no_light_pass_holds_a_flat_square(method):
    """At the defaults (the filter on, not denoised), every light pass of every method: no flat 2t x 2t square,
    and the caustic's bright samples are there (pixels of the floor's Diffuse Indirect at ten times its mean)."""
    settings = RenderSettings(samples=16, method=method, seed=1, passes=LIGHT_PASSES)
    passes = render(_plate_over_a_floor(), settings).passes
    side = 2 * settings.gather.interleave
    blocks = {name: len(flat_blocks(passes[name], side)) for name in LIGHT_PASSES}
    assert not any(blocks.values()), blocks
    indirect = passes["Diffuse Indirect"][..., :3].mean(axis=-1)
    assert (indirect > 10.0 * indirect.mean()).sum() >= 3


@pytest.mark.parametrize("method", ["ir", "vbnl"])
def test_clamp_indirect_bounds_each_sample_and_is_off_by_default(method):
    """Clamp Indirect at 0.5: no pixel of the unfiltered Diffuse Indirect (a mean of its samples) above it, the
    caustic's light cut down and the rest kept; at 0 (the default) and above every sample, the image unclamped."""
    scene = _plate_over_a_floor()

    def indirect(limit):
        settings = RenderSettings(samples=16, method=method, seed=1, passes=("Diffuse Indirect",))
        settings.gather.filter = False
        settings.gather.clamp_indirect = limit
        return render(scene, settings).passes["Diffuse Indirect"][..., :3]
    free, clamped, loose = indirect(0.0), indirect(0.5), indirect(1e6)
    assert RenderSettings().gather.clamp_indirect == 0.0
    assert free.max() > 2.0  # the caustic, four times the limit and more
    assert clamped.max() <= 0.5 * (1 + 1e-6) and np.isfinite(clamped).all()
    dim = free.max(axis=-1) < 0.01  # pixels whose every sample is far below the limit
    np.testing.assert_array_equal(clamped[dim], free[dim])
    np.testing.assert_array_equal(loose, free)


def test_vbnl_takes_the_caustic_from_its_photons():
    """A sharp plate's caustic on a small floor (Roughness just below ``light_paths.SHARP``, 2^20 light paths) from
    vbnl's photons (``virtual_light_sampling._caustic_light``) and from its paths alone (``caustic_photons`` off),
    4 seeds each at 16 samples: the same light in the mean (measured 0.0097 against 0.0102; the paths' own mean
    0.0113 at 128 samples), and a third of the pixel-to-pixel noise (the mean step between neighbours over the
    mean: 0.69 against 1.86 on average over the seeds), its brightest pixel 58-255 times the mean against 750-1094.
    Points between the lights' spheres keep the paths, and their rare bright samples."""
    scene = _plate_over_a_floor(0.95 * SHARP, far=2.0)

    def floor(photons: bool, seed: int) -> np.ndarray:
        settings = RenderSettings(samples=16, method="vbnl", seed=seed, passes=("Diffuse Indirect",))
        settings.gather.filter = False
        settings.placement.vbnl.photons = 1 << 20
        settings.placement.vbnl.sampling.caustic_photons = photons
        return render(scene, settings).passes["Diffuse Indirect"][..., :3].mean(axis=-1).astype(np.float64)

    def noise(image):
        return np.abs(np.diff(image, axis=1)).mean() / image.mean()

    assert RenderSettings().placement.vbnl.sampling.caustic_photons
    photons, paths = ([floor(flag, seed) for seed in range(4)] for flag in (True, False))
    mean_photons, mean_paths = np.mean([f.mean() for f in photons]), np.mean([f.mean() for f in paths])
    assert abs(mean_photons / mean_paths - 1.0) < 0.15, (mean_photons, mean_paths)
    assert np.mean([noise(f) for f in photons]) < 0.5 * np.mean([noise(f) for f in paths])
    assert max(f.max() / f.mean() for f in photons) < 0.5 * min(f.max() / f.mean() for f in paths)
