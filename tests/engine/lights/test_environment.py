"""The world as an environment map (``lights/environment.py``), without Blender: its sampling density is a density
of the directions it draws, direct light under it matches the map integrated texel by texel, its light paths carry
its power, and broken maps are made harmless."""
import dataclasses

import numpy as np
import pytest

from conftest import plane_scene
from vpl_addon.core.sampling import uniform_sphere
from vpl_addon.core.scene import Environment, Scene
from vpl_addon.lights import EnvironmentLight, LightSet
from vpl_addon.render import RenderSettings, render


def sky(h=32, w=64, sun=(0.30, 0.80), sun_radiance=400.0):
    """A dim blue gradient with a small bright 'sun' of a few texels at image coordinates ``sun`` (u, v)."""
    v = (np.arange(h) + 0.5) / h
    image = np.zeros((h, w, 3))
    image[:] = (np.array([0.2, 0.3, 0.6]) * (0.3 + v)[:, None])[:, None, :]
    row, col = int(sun[1] * h), int(sun[0] * w)
    image[row:row + 2, col:col + 2] = sun_radiance
    return image


def directions_of_texels(h, w, sub=4):
    """Centres of sub x sub cells in every texel, with their solid angles: quadrature over the sphere."""
    u = (np.arange(w * sub) + 0.5) / (w * sub)
    v = (np.arange(h * sub) + 0.5) / (h * sub)
    uu, vv = np.meshgrid(u, v)
    theta, phi = np.pi * (1 - vv.ravel()), 2 * np.pi * (0.5 - uu.ravel())
    d = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], axis=1)
    return d, np.sin(theta) * (np.pi / (h * sub)) * (2 * np.pi / (w * sub))


def test_the_pdf_is_a_density_and_the_samples_follow_it():
    light = EnvironmentLight(sky())
    rng = np.random.default_rng(1)
    d, area = directions_of_texels(32, 64, 8)
    assert (light.pdf(d) * area).sum() == pytest.approx(1.0, abs=1e-3)  # integrates to 1 over the sphere
    d = uniform_sphere(rng.random(100_000), rng.random(100_000))
    assert light.pdf(d).min() > 0.0
    w = light.sample(rng.random(200_000), rng.random(200_000))
    assert np.allclose(np.linalg.norm(w, axis=1), 1.0)
    # the share of samples within 0.3 rad of the sun is the pdf's integral there
    theta, phi = np.pi * (1 - 0.8 - 1 / 32), 2 * np.pi * (0.5 - 0.3 - 1 / 64)
    sun = np.array([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)])
    expected = (light.pdf(d2 := directions_of_texels(32, 64, 8)[0]) * area)[(d2 @ sun) > np.cos(0.3)].sum()
    assert expected > 0.5  # the sun draws most samples
    assert ((w @ sun) > np.cos(0.3)).mean() == pytest.approx(expected, rel=0.02)


@pytest.mark.parametrize("rotated", [False, True])
def test_direct_light_under_the_map_is_the_map_integrated(rotated):
    """An open floor facing +Z: Diffuse Direct = 1/pi * integral over the upper hemisphere of L cos, by quadrature
    over the map's texels (the sun's texels make most of it). Rotated about a tilted axis, the same map lights the
    floor as the map's directions rotated."""
    image = sky()
    rotation = np.eye(3)
    if rotated:
        a = 0.4
        rotation = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
    scene = dataclasses.replace(plane_scene(res=16), environment=Environment.checked(image, rotation))
    out = render(scene, RenderSettings(samples=16, light_samples=16, method="none"))
    got = out.passes["Diffuse Direct"][..., :3].reshape(-1, 3).mean(axis=0)
    d, area = directions_of_texels(*image.shape[:2])
    light = EnvironmentLight(image, rotation)
    world_dirs = d @ rotation  # map directions back to the world
    cos = np.maximum(world_dirs[:, 2], 0.0)
    expected = (light.radiance(world_dirs) * (cos * area)[:, None]).sum(axis=0) / np.pi
    assert got == pytest.approx(expected, rel=0.02)


def test_the_map_is_read_only_for_the_samples_its_light_reaches(monkeypatch):
    """Under a wide roof (behind the camera) the map's light samples are nearly all blocked: their directions are
    drawn, but the map is looked up (L / pdf) only for those whose shadow ray got out, and the floor gets the light
    of those alone, finite and positive."""
    roof = np.array([[[-500, -500, 6], [500, 500, 6], [500, -500, 6]], [[-500, -500, 6], [-500, 500, 6],
                                                                        [500, 500, 6]]], float)
    floor = plane_scene(res=16)
    scene = Scene.build(np.concatenate([floor.triangles, roof]), floor.materials, [], floor.camera,
                        environment=Environment.checked(sky(sun=(0.3, 0.97))))
    counted = {"drawn": 0, "looked up": 0}
    draw, look = EnvironmentLight.sample, EnvironmentLight._look

    def drawn(self, u1, u2):
        counted["drawn"] += len(u1)
        return draw(self, u1, u2)

    def looked(self, w):
        counted["looked up"] += len(w)
        return look(self, w)
    monkeypatch.setattr(EnvironmentLight, "sample", drawn)
    monkeypatch.setattr(EnvironmentLight, "_look", looked)
    out = render(scene, RenderSettings(samples=4, light_samples=4, method="none"))
    direct = out.passes["Diffuse Direct"][..., :3]
    assert counted["drawn"] >= 16 * 16 * 4 * 4
    assert 0 < counted["looked up"] < 0.05 * counted["drawn"]
    assert np.isfinite(direct).all() and direct.min() >= 0.0 and direct.max() > 0.0


def test_light_paths_carry_the_power_through_the_scene_disc():
    light = EnvironmentLight(sky())
    rng = np.random.default_rng(2)
    origins, dirs, power = light.emit(400_000, rng, np.zeros(3), 2.0)
    d, area = directions_of_texels(32, 64)
    total = (light.radiance(d) * area[:, None]).sum(axis=0) * np.pi * 4.0  # L over the sphere x disc area
    assert power.mean(axis=0) == pytest.approx(total, rel=0.03)
    assert np.allclose(np.einsum("ij,ij->i", origins, dirs), -4.0)  # discs 2 R upstream, facing the travel


def test_a_constant_world_keeps_its_cosine_sampling_and_broken_maps_light_nothing():
    scene = plane_scene(world=(1.0, 1.0, 1.0))
    assert type(LightSet(scene).world).__name__ == "WorldLight"  # a constant world needs no importance map
    assert Environment.checked(np.zeros((0, 4, 3))) is None
    assert Environment.checked(np.full((4, 8, 3), np.nan)) is None
    env = Environment.checked(np.where(np.arange(8)[None, :, None] % 2, np.inf, 1.0) * np.ones((4, 8, 3)),
                              rotation=np.full((3, 3), np.nan))
    assert np.isfinite(env.image).all() and np.array_equal(env.rotation, np.eye(3))
    out = render(dataclasses.replace(plane_scene(res=8), environment=env),
                 RenderSettings(samples=4, light_samples=4, method="ir"))
    for image in out.passes.values():
        assert np.isfinite(image).all() and image.min() >= 0.0


def test_the_guide_table_finds_the_texel_a_search_of_the_whole_row_finds():
    """``EnvironmentLight.sample`` looks for a column only between two guide entries: the directions are the
    inverse CDF's (a row by the marginal, then a column by the row's conditional CDF, searched whole here)."""
    light = EnvironmentLight(sky())
    rng = np.random.default_rng(2)
    u1, u2 = rng.random(50_000), rng.random(50_000)
    u2[:64] = np.arange(64) / 64  # on the guide's own steps
    h, w = light.texel_prob.shape
    rows = light.texel_prob.sum(axis=1)
    row = np.minimum(np.searchsorted(np.cumsum(rows), u1 * rows.sum(), side="right"), h - 1)
    cdf = np.cumsum(light.texel_prob[row], axis=1) / rows[row, None]
    col = np.minimum((cdf <= u2[:, None]).sum(axis=1), w - 1)
    d = light.sample(u1, u2) @ light.rotation.T
    found_col = np.floor((0.5 - np.arctan2(d[:, 1], d[:, 0]) / (2 * np.pi)) % 1.0 * w).astype(int)
    found_row = np.floor((1.0 - np.arccos(np.clip(d[:, 2], -1, 1)) / np.pi) * h).astype(int)
    assert (found_row == row).mean() > 0.999 and (found_col == col).mean() > 0.999  # texel edges may round over


def test_a_one_texel_sun_keeps_its_samples_in_its_texel_with_a_bounded_ratio():
    """``_reach``: a texel's weight mixes the lookup's light over it with the brightest of its neighbours. With the
    neighbourhood's maximum alone, a sun of one texel had a ninth of the samples meant for it (10 % in its texel)
    and the estimate's largest ratio was 9.5x its mean."""
    h, w = 64, 128
    image = np.full((h, w, 3), 0.1)
    image[40, 30] = 1e4
    light = EnvironmentLight(image)
    rng = np.random.default_rng(0)
    d = light.sample(rng.random(200_000), rng.random(200_000))
    radiance, pdf = light._look(d)
    u = (0.5 - np.arctan2(d[:, 1], d[:, 0]) / (2 * np.pi)) % 1.0
    v = 1.0 - np.arccos(np.clip(d[:, 2], -1.0, 1.0)) / np.pi
    assert np.mean(((v * h).astype(int) == 40) & ((u * w).astype(int) == 30)) > 0.25
    ratio = radiance[:, 0] / pdf
    assert ratio.max() < 6.0 * ratio.mean()
