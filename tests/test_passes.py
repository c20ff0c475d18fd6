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
