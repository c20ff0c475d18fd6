"""The light passes as Cycles defines them at pixels that see two surfaces (no Blender needed).

Cycles divides ``Diffuse Direct`` and ``Diffuse Indirect`` by ``Diffuse Color``: a pixel's pass is the sum of its
samples' light times albedo over the sum of their albedo, so a pixel half on a white floor and half on a black one
(or metal, or the background) holds the white floor's light, not half of it. The Cycles reference of veach_ajar
shows it at the edge of the walls and the metal floor (Diffuse Color 0.1, Diffuse Indirect the wall's)."""
import numpy as np
import pytest

from conftest import plane_scene
from vpl_addon.core import passes as P
from vpl_addon.core.scene import Materials, Scene
from vpl_addon.gather.summing import GatherSettings
from vpl_addon.lights import SunLight
from vpl_addon.methods import MethodSettings
from vpl_addon.render import RenderSettings, render

FOX = "The quick brown fox jumps over the lazy dog"  # MurmurHash3_x86_32 0x2e4ff723, a known vector
VIEW = 0.05  # 5 cm seen by 5 x 5 pixels: the light hardly changes from pixel to pixel


def split_floor_scene():
    """The floor white for x < 0 and black for x > 0 (the middle column of pixels sees both halves; the pixel
    filter reaches a little into the next columns, the outer ones see one half), a white wall
    at x = 1 that reflects a low sun onto it, and the camera straight above x = 0."""
    floor = plane_scene([SunLight("sun", [1.0, 0.3, -0.6], [3.0] * 3)], view=VIEW, res=5, height=1.0)
    s = 10.0
    halves = np.array([[[-s, -s, 0], [0, -s, 0], [0, s, 0]], [[-s, -s, 0], [0, s, 0], [-s, s, 0]],
                       [[0, -s, 0], [s, -s, 0], [s, s, 0]], [[0, -s, 0], [s, s, 0], [0, s, 0]]], float)
    wall = np.array([[[1, -s, 0], [1, s, 3], [1, s, 0]], [[1, -s, 0], [1, -s, 3], [1, s, 3]]], float)
    materials = Materials.make([{"name": "black", "base_color": (0.0, 0.0, 0.0)}])
    return Scene.build(np.concatenate([halves, wall]), materials, floor.lights, floor.camera,
                       material=[0, 0, 1, 1, 0, 0])


def test_light_passes_are_divided_by_the_diffuse_color():
    """``render`` divides every method's light the same way; ``ir`` with an exact gather is smooth enough to show
    it pixel by pixel."""
    settings = RenderSettings(samples=64, light_samples=4, method="ir", indirect_samples=64,
                              passes=(P.COMBINED, P.DIFFUSE_DIRECT, P.DIFFUSE_INDIRECT, P.DIFFUSE_COLOR),
                              placement=MethodSettings(vpls=1024), gather=GatherSettings(interleave=1, filter=False))
    out = render(split_floor_scene(), settings).passes
    color, direct, indirect = (out[n][..., 0] for n in (P.DIFFUSE_COLOR, P.DIFFUSE_DIRECT, P.DIFFUSE_INDIRECT))
    white, edge, black = (slice(None), 0), (slice(None), 2), (slice(None), 4)
    assert color[white] == pytest.approx(0.8) and color[black] == pytest.approx(0.0)
    assert 0.3 < color[edge].mean() < 0.5  # the middle column sees both halves
    assert (direct[black] == 0.0).all() and (indirect[black] == 0.0).all()  # no diffuse colour: 0, as in Cycles
    assert direct[edge].mean() == pytest.approx(direct[white].mean(), rel=0.02)  # not half of it
    assert indirect[white].min() > 0.0
    assert indirect[edge].mean() == pytest.approx(indirect[white].mean(), rel=0.02)
    # the passes still compose the image: (direct + indirect) x colour
    composed = (out[P.DIFFUSE_DIRECT] + out[P.DIFFUSE_INDIRECT]) * out[P.DIFFUSE_COLOR]
    assert np.allclose(out[P.COMBINED][..., :3], composed, rtol=1e-4, atol=1e-6)


@pytest.mark.parametrize("region", [None, (3, 5, 9, 7)])
def test_finished_rows_are_shown_once_in_order_as_the_final_combined(region):
    """Progressive display: ``shown`` gets bands of output rows, each once, top to bottom, as soon as their blocks
    are done; without indirect light (method none) a band is already the final Combined; with a render border the
    bands are the border's rows."""
    from dataclasses import replace
    scene = plane_scene([SunLight("sun", [0.3, 0.2, -1.0], [2.0] * 3)], world=(0.1, 0.2, 0.3), res=24, view=30.0)
    scene.camera = replace(scene.camera, region=region)
    bands = []
    settings = RenderSettings(samples=4, light_samples=1, method="none", block_pixels=10, film_transparent=False)
    final = render(scene, settings, shown=lambda row, band: bands.append((row, band.copy()))).passes[P.COMBINED]
    rows = [row for row, _ in bands]
    assert rows == sorted(rows) and len(bands) > 5
    shown = np.concatenate([band for _, band in bands])
    assert rows[0] == 0 and shown.shape == final.shape and np.array_equal(shown, final)


def test_cryptomatte_ids_ranks_and_manifest():
    """MurmurHash3 as the Cryptomatte specification and Cycles compute it (hashes of Cycles' own manifest of the
    Cornell box), floats never NaN, infinite or denormal, and per pixel the names by falling coverage."""
    from vpl_addon.core import cryptomatte
    assert [f"{cryptomatte.name_hash(n):08x}" for n in ("Floor", "TallBox", "default_surface", "", FOX)] == \
        ["6a2fb16e", "501aadcd", "78d05529", "00000000", "2e4ff723"]
    assert cryptomatte.header("ViewLayer.CryptoObject", ["Floor"])["cryptomatte/542cafa/manifest"] == \
        '{"Floor":"6a2fb16e"}'
    ids = cryptomatte.ids([str(i) for i in range(5000)])
    assert np.isfinite(ids).all() and (np.abs(ids) >= np.finfo(np.float32).tiny).all()
    pairs = cryptomatte.ranked(np.array([0, 0, 0, 1, 1, 1, 1]), np.array([2, 1, 1, 0, 2, 2, 0]), 0.25, 3, 2,
                               np.array([10.0, 11.0, 12.0]))
    assert pairs.tolist() == [[11.0, 0.5, 12.0, 0.25], [10.0, 0.5, 12.0, 0.5], [0.0, 0.0, 0.0, 0.0]]
