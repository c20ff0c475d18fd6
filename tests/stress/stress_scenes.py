"""Builders shared by the stress suite (scenes made in code, no binary fixtures) and the tally printed at the end of
the run by ``tests/conftest.py``: how many hostile scenes were rendered and how many bad values came out (must be 0).
"""
from __future__ import annotations

import numpy as np

import vpl_addon.methods
from vpl_addon.core import passes as P
from vpl_addon.core.camera import Camera, view_window
from vpl_addon.core.scene import Materials, Scene
from vpl_addon.gather.summing import GatherSettings
from vpl_addon.lights import PointLight
from vpl_addon.methods import MethodSettings
from vpl_addon.methods.smc import SMCSettings
from vpl_addon.methods.vbnl import VBNLSettings
from vpl_addon.methods.vbnl.virtual_light_sampling import SamplingSettings
from vpl_addon.render import RenderSettings

# every method that exists, so a method that lands later is stressed without touching this suite
METHODS = ("none", *vpl_addon.methods.METHODS)
ALL_PASSES = P.ALL + P.DATA + tuple(f"{kind}00" for kind in P.CRYPTOMATTE)

# filled by the tests, printed by tests/conftest.py: distinct hostile scenes, renders, bad values seen
RESULTS = {"scenes": set(), "renders": 0, "bad_values": 0}

WHITE = Materials.make([{"name": "white", "base_color": (0.8, 0.8, 0.8)}])
ALBEDO_ONE = Materials.make([{"name": "one", "base_color": (1.0, 1.0, 1.0)}])
BLACK = Materials.make([{"name": "black", "base_color": (0.0, 0.0, 0.0)}])


def bad_values(result) -> int:
    """Non-finite values over all passes of a RenderResult, and negative ones where a pass cannot have them."""
    return sum(int((~np.isfinite(img)).sum() + (0 if name in P.SIGNED else (img < 0).sum()))
               for name, img in result.passes.items())


def tally(scene_name: str, result) -> int:
    """Count a hostile render for the end-of-run summary; returns its number of bad values."""
    bad = bad_values(result)
    RESULTS["scenes"].add(scene_name)
    RESULTS["renders"] += 1
    RESULTS["bad_values"] += bad
    return bad


def budget(vpls: int) -> MethodSettings:
    """A light budget with vbnl's photons and gather samples cut to the stress suite's scale."""
    return MethodSettings(vpls=vpls, vbnl=VBNLSettings(photons=4096, sampling=SamplingSettings(samples=2)),
                          smc=SMCSettings(warmup=8, radiosity_samples=4, camera_points=256))


def small_settings(method: str, **overrides) -> RenderSettings:
    """The stress suite's budget: few samples, few VPLs, every pass."""
    values = dict(samples=4, light_samples=2, method=method, indirect_samples=1,
                  placement=budget(64),
                  gather=GatherSettings(interleave=2), passes=ALL_PASSES)
    values.update(overrides)
    return RenderSettings(**values)


def look_at(eye, target, res=16, lens=20.0, height=None):
    eye, target = np.asarray(eye, float), np.asarray(target, float)
    back = eye - target
    back /= np.linalg.norm(back)
    right = np.cross([0, 0, 1.0], back) if abs(back[2]) < 0.999 else np.array([1.0, 0, 0])
    right /= np.linalg.norm(right)
    up = np.cross(back, right)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = right, up, back, eye
    height = res if height is None else height
    return Camera(m, res, height, view_window(res, height, orthographic=False, lens=lens), clip_start=1e-6)


def box(lo, hi, inward=True):
    """12 triangles of an axis-aligned box, facing in (a room) or out (a block)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    c = np.array([[x, y, z] for z in (lo[2], hi[2]) for y in (lo[1], hi[1]) for x in (lo[0], hi[0])])
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    tris = []
    for a, b, cc, d in quads:
        tris += [(a, b, cc), (a, cc, d)] if not inward else [(a, cc, b), (a, d, cc)]
    return c[np.array(tris)]


def room(scale=1.0, offset=(0, 0, 0), lights=None, materials=WHITE, world=(0, 0, 0), eye=None, res=16, camera=None,
         max_bounces=8, power=100.0):
    """A closed 2 m room (scaled and moved), camera inside, a point light under the ceiling."""
    off = np.asarray(offset, float)
    tri = box([-1, -1, 0], [1, 1, 2]) * scale + off
    lights = [PointLight("lamp", off + np.array([0, 0, 1.8]) * scale, [power * scale ** 2] * 3)] \
        if lights is None else lights
    cam = camera or look_at(off + np.array(eye or [0.5, -0.9, 1.0]) * scale, off + np.array([0, 0.5, 0.6]) * scale,
                            res)
    return Scene.build(tri, materials, lights, cam, material=np.ones(len(tri), int), world=world,
                       max_bounces=max_bounces)


def with_triangles(scene, extra, material=1, materials=None):
    """The scene plus more triangles (of one material id), everything else unchanged."""
    tri = np.concatenate([scene.triangles, np.asarray(extra, float).reshape(-1, 3, 3)])
    mat = np.concatenate([scene.material, np.full(len(tri) - len(scene.triangles), material)])
    return Scene.build(tri, materials or scene.materials, scene.lights, scene.camera, material=mat,
                       world=scene.world, textures=scene.textures, max_bounces=scene.max_bounces)
