"""Russian roulette on camera paths continued past their first hit (``paths.vertices.roulette``): unbiased, and the
reason a scene coated everywhere (the Principled BSDF's default dielectric layer, as in the living room) does not
continue every path through its 4 % coat to the bounce limit."""
import numpy as np
import pytest

from vpl_addon.core.scene import Materials
from vpl_addon.lights.direct import direct_light
from vpl_addon.methods import MethodSettings
from vpl_addon.methods.vbnl import VBNLSettings, virtual_light_sampling
from vpl_addon.methods.vbnl.virtual_light_sampling import SamplingSettings
from vpl_addon.paths import vertices
from vpl_addon.paths.vertices import roulette
from vpl_addon.render import RenderSettings, render

from stress.stress_scenes import room


def test_roulette_keeps_the_expected_throughput():
    rng = np.random.default_rng(0)
    weight = rng.random((200_000, 3)) * np.array([0.05, 0.3, 1.5])
    weight[:1000] = 0.0
    weight[1000:1010, 1] = np.nan
    rows, boost = roulette(weight, rng)
    q = np.minimum(np.sqrt(np.nanmax(weight, axis=1)), 1.0)
    q[:1010] = 0.0
    assert not np.isin(np.arange(1010), rows).any()  # nothing, or no number, stops
    assert np.isin(np.nonzero(q >= 1.0)[0], rows).all()  # a bright path always goes on, unscaled
    assert np.all(boost[q[rows] >= 1.0] == 1.0)
    assert len(rows) == pytest.approx(q[1010:].sum(), rel=0.01)
    kept = (weight[rows] * boost[:, None]).sum(axis=0)
    assert kept == pytest.approx(weight[1010:].sum(axis=0), rel=0.01)  # the expected throughput is unchanged


def test_a_faint_coat_stops_paths_long_before_the_bounce_limit(monkeypatch):
    """vbnl's camera paths in a room coated everywhere: every hit has the coat's lobe, which its extension always
    follows (the photon lights hold none of its light). Without roulette every path went on to the bounce limit,
    so the gather's rays grew with it (5.8x from 2 to 8 bounces here, 1.1x with roulette); the light stays what
    every path gives."""
    coated = Materials.make([{"name": "coated", "base_color": (0.8, 0.8, 0.8), "roughness": 0.3,
                              "specular": 0.5, "ior": 1.5}])
    settings = RenderSettings(samples=4, light_samples=1, method="vbnl", seed=1, passes=("Diffuse Indirect",),
                              placement=MethodSettings(vbnl=VBNLSettings(photons=8192,
                                                                         sampling=SamplingSettings(samples=4))))
    rays = {}
    for bounces in (2, 8):
        result = render(room(materials=coated, res=32, max_bounces=bounces), settings)
        assert np.isfinite(result.passes["Diffuse Indirect"]).all()
        rays[bounces] = result.rays
    assert rays[8] < 1.6 * rays[2]
    light = result.passes["Diffuse Indirect"].mean()

    def every_path(weight, rng, u=None):
        rows = np.nonzero(weight.max(axis=1) > 0.0)[0]
        return rows, np.ones(len(rows))
    monkeypatch.setattr(virtual_light_sampling, "roulette", every_path)
    monkeypatch.setattr(vertices, "roulette", every_path)
    assert light == pytest.approx(render(room(materials=coated, res=32, max_bounces=8), settings)
                                  .passes["Diffuse Indirect"].mean(), rel=0.03)


def test_a_rough_coat_takes_fewer_light_samples_for_the_same_light(monkeypatch):
    """At the vertices of a rough coat (``Surface.rough_coat``) the camera paths' next-event estimation takes
    ``COAT_LIGHT_SAMPLES`` (2) light samples, fewer than a metal's ``GLOSSY_LIGHT_SAMPLES`` (4), for the same
    light."""
    assert vertices.COAT_LIGHT_SAMPLES < vertices.GLOSSY_LIGHT_SAMPLES
    coated = Materials.make([{"name": "coated", "base_color": (0.8, 0.8, 0.8), "roughness": 0.8,
                              "specular": 0.5, "ior": 1.5}])
    settings = RenderSettings(samples=4, light_samples=1, method="vbnl", seed=1, passes=("Diffuse Indirect",),
                              placement=MethodSettings(vbnl=VBNLSettings(photons=8192,
                                                                         sampling=SamplingSettings(samples=4))))
    asked = []

    def counted(surface, lights, tracer, samples, rng, **kwargs):  # the real next-event estimation, its samples kept
        asked.append(samples)
        return direct_light(surface, lights, tracer, samples, rng, **kwargs)
    monkeypatch.setattr(vertices, "direct_light", counted)
    light, coat, metal = {}, vertices.COAT_LIGHT_SAMPLES, vertices.GLOSSY_LIGHT_SAMPLES
    for samples in (coat, metal):
        monkeypatch.setattr(vertices, "COAT_LIGHT_SAMPLES", samples)
        asked.clear()
        light[samples] = render(room(materials=coated, res=32, max_bounces=4), settings).passes["Diffuse Indirect"]
        assert asked and set(asked) == {samples}  # every vertex of the coated room is a rough coat's
    assert light[coat].mean() == pytest.approx(light[metal].mean(), rel=0.01)
