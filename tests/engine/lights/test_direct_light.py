"""Direct light of every light type against closed-form irradiance on a plane (no Blender needed).

The camera looks straight down at a floor through a 2 cm window, so every pixel sees (almost) the point below the
light and ``Diffuse Direct`` must equal E / pi there."""
from dataclasses import replace

import numpy as np
import pytest

from conftest import plane_scene
from vpl_addon.core.scene import Materials, Scene
from vpl_addon.lights import AreaLight, EmissiveTriangles, PointLight, SpotLight, SunLight
from vpl_addon.render import RenderSettings, render

H = 1.0  # light height above the floor
SETTINGS = RenderSettings(samples=16, light_samples=16)


def diffuse_direct(scene, settings=SETTINGS):
    result = render(scene, settings)
    image = result.passes["Diffuse Direct"]
    assert np.isfinite(image).all() and (image >= 0).all()
    return float(image[..., 0].mean()), result


def rect_irradiance_below_center(L, a, b, h):
    """Irradiance under the centre of an a x b Lambertian rectangle of radiance L, parallel at height h."""
    def corner(x, y):
        A, B = x / h, y / h
        return 0.5 * (A / np.hypot(1, A) * np.arctan(B / np.hypot(1, A))
                      + B / np.hypot(1, B) * np.arctan(A / np.hypot(1, B)))
    return 4.0 * L * corner(a / 2, b / 2)


def test_point_light_is_power_over_four_pi():
    value, _ = diffuse_direct(plane_scene([PointLight("p", [0, 0, H], [100.0] * 3)], view=0.02))
    assert value == pytest.approx(100.0 / (4 * np.pi) / H ** 2 / np.pi, rel=2e-3)


def test_hard_sphere_light_matches_point_light_of_same_power():
    light = PointLight("p", [0, 0, H], [100.0] * 3, radius=0.3, soft_falloff=False)
    value, _ = diffuse_direct(plane_scene([light], view=0.02))
    assert value == pytest.approx(100.0 / (4 * np.pi) / H ** 2 / np.pi, rel=1e-2)


def test_soft_falloff_light_is_a_facing_disc():
    """Blender's default soft falloff, as measured in Cycles: P / (4 pi^2) cos / (d^2 + R^2)."""
    value, _ = diffuse_direct(plane_scene([PointLight("p", [0, 0, H], [100.0] * 3, radius=0.5)], view=0.02))
    assert value == pytest.approx(100.0 / (4 * np.pi ** 2) / (H ** 2 + 0.25), rel=1e-2)


def test_scaled_spot_has_an_elliptic_cone():
    """Scaling a spot's local x by 4 squeezes its cone along x: a point 40 degrees off axis along x is lit,
    the same angle along y is not."""
    basis = np.diag([4.0, 1.0, 1.0])
    spot = SpotLight("s", [0, 0, H], [100.0] * 3, direction=[0, 0, -1], spot_size=np.radians(60), spot_blend=0.0,
                     inverse_basis=np.linalg.inv(basis))
    off = np.tan(np.radians(40)) * H
    along_x = diffuse_direct(plane_scene([replace(spot, position=[-off, 0, H])], view=0.02))[0]
    along_y = diffuse_direct(plane_scene([replace(spot, position=[0, -off, H])], view=0.02))[0]
    assert along_x > 0.0 and along_y == 0.0


@pytest.mark.parametrize("spread", [np.radians(30), np.radians(90), np.pi])
def test_area_spread_profile_keeps_the_emitted_power(spread):
    light = AreaLight("a", [0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, -1], [1.0] * 3, spread=spread)
    phi = np.linspace(0, np.pi / 2, 200001)
    integrand = light.spread_profile(np.cos(phi)) * np.cos(phi) * np.sin(phi) * 2 * np.pi
    assert np.trapz(integrand, phi) == pytest.approx(np.pi, rel=1e-3)  # a Lambertian lobe integrates to pi


@pytest.mark.parametrize("size, blend, expected_fraction", [
    (np.radians(60), 0.0, 1.0),  # axis inside the cone: a full point light
    (np.radians(60), 0.5, 1.0),
])
def test_spot_light_on_axis(size, blend, expected_fraction):
    spot = SpotLight("s", [0, 0, H], [100.0] * 3, direction=[0, 0, -1], spot_size=size, spot_blend=blend)
    value, _ = diffuse_direct(plane_scene([spot], view=0.02))
    assert value == pytest.approx(expected_fraction * 100.0 / (4 * np.pi) / np.pi, rel=2e-3)


def test_spot_light_cone_and_blend():
    """Aimed 40 degrees away: the floor below lies at 40 degrees off axis, outside a 60 degree cone and inside
    the smooth edge of a 90 degree cone with blend 1, where Cycles' smoothstep gives a known fraction."""
    tilt = np.radians(40)
    axis = [np.sin(tilt), 0, -np.cos(tilt)]
    outside = SpotLight("s", [0, 0, H], [100.0] * 3, direction=axis, spot_size=np.radians(60), spot_blend=0.0)
    assert diffuse_direct(plane_scene([outside], view=0.02))[0] == 0.0
    wide = SpotLight("s", [0, 0, H], [100.0] * 3, direction=axis, spot_size=np.radians(90), spot_blend=1.0)
    cos_half = np.cos(np.radians(45))
    x = (np.cos(tilt) - cos_half) / (1 - cos_half)
    fraction = x * x * (3 - 2 * x)
    assert diffuse_direct(plane_scene([wide], view=0.02))[0] == pytest.approx(
        fraction * 100.0 / (4 * np.pi) / np.pi, rel=5e-3)


@pytest.mark.parametrize("angle", [0.0, np.radians(10)])
def test_sun_gives_strength_times_cosine(angle):
    tilt = np.radians(30)
    sun = SunLight("sun", [np.sin(tilt), 0, -np.cos(tilt)], [3.0] * 3, angle=angle)
    value, _ = diffuse_direct(plane_scene([sun], view=0.02))
    assert value == pytest.approx(3.0 * np.cos(tilt) / np.pi, rel=2e-3)


@pytest.mark.parametrize("a, b", [(0.5, 0.5), (1.0, 0.25)])
def test_rectangle_area_light(a, b):
    light = AreaLight("a", [0, 0, H], [a, 0, 0], [0, b, 0], [0, 0, -1], [40.0] * 3)
    radiance = 40.0 / (np.pi * a * b)
    value, _ = diffuse_direct(plane_scene([light], view=0.02))
    assert value == pytest.approx(rect_irradiance_below_center(radiance, a, b, H) / np.pi, rel=1e-2)


def test_disk_area_light():
    d = 0.8
    light = AreaLight("a", [0, 0, H], [d, 0, 0], [0, d, 0], [0, 0, -1], [40.0] * 3, round=True)
    radiance = 40.0 / (np.pi * np.pi * d * d / 4)
    r = d / 2
    value, _ = diffuse_direct(plane_scene([light], view=0.02))
    assert value == pytest.approx(radiance * r * r / (H * H + r * r), rel=1e-2)


def test_several_lights_add_up():
    """Several local lights: each light sample picks one of them and the per-point work (the spherical rectangle's
    set-up) is done for the points that picked it; the sum must still be each light's own light added up."""
    lights = [AreaLight("left", [-0.6, 0, H], [0.5, 0, 0], [0, 0.3, 0], [0, 0, -1], [40.0] * 3),
              AreaLight("right", [0.8, 0.2, 0.7 * H], [0.2, 0, 0], [0, 0.6, 0], [0, 0, -1], [25.0] * 3),
              AreaLight("disk", [0, 0.5, H], [0.4, 0, 0], [0, 0.4, 0], [0, 0, -1], [30.0] * 3, round=True),
              PointLight("lamp", [0.3, -0.4, 1.5 * H], [60.0] * 3)]
    def image(scene_lights):  # a 3 m x 3 m patch of the floor: every pixel a different point
        return render(plane_scene(scene_lights, view=3.0, res=16), SETTINGS).passes["Diffuse Direct"][..., 0]
    alone = sum(image([light]) for light in lights)
    together = image(lights)
    assert np.isfinite(together).all() and alone.min() > 0.0
    assert np.abs(together - alone).mean() / alone.mean() < 0.02
    assert together.mean() == pytest.approx(alone.mean(), rel=1e-2)


def test_area_light_is_one_sided():
    light = AreaLight("a", [0, 0, H], [0.5, 0, 0], [0, 0.5, 0], [0, 0, 1], [40.0] * 3)
    assert diffuse_direct(plane_scene([light], view=0.02))[0] == 0.0


def test_emissive_triangles_emit_from_both_sides():
    """A glowing quad above the floor whose front faces up: the floor sees its back."""
    s = 0.25
    quad = np.array([[[-s, -s, H], [s, -s, H], [s, s, H]], [[-s, -s, H], [s, s, H], [-s, s, H]]], float)
    floor = plane_scene([], view=0.02, height=0.5)  # the camera sits between the floor and the quad
    materials = Materials.make([{"name": "glow", "base_color": (0, 0, 0), "emission": (2.0, 2.0, 2.0)}])
    tri = np.concatenate([floor.triangles, quad])
    scene = Scene.build(tri, materials, [], floor.camera, material=[0, 0, 1, 1])
    assert EmissiveTriangles.from_scene(scene) is not None
    value, _ = diffuse_direct(scene)
    assert value == pytest.approx(rect_irradiance_below_center(2.0, 2 * s, 2 * s, H) / np.pi, rel=1e-2)


def test_world_light_is_its_radiance():
    value, _ = diffuse_direct(plane_scene([], world=(0.7, 0.7, 0.7), view=0.5))
    assert value == pytest.approx(0.7, rel=1e-6)


def test_no_light_traces_no_shadow_rays_and_says_so():
    result = render(plane_scene([], res=16), SETTINGS)
    assert result.passes["Diffuse Direct"].max() == 0.0
    assert result.rays == 16 * 16 * SETTINGS.samples  # camera rays only
    assert any("no lights" in w for w in result.warnings)


def test_light_inside_closed_box_does_not_leak():
    """A point light under an upside-down box lying on the floor: the floor outside stays dark."""
    floor = plane_scene([], view=0.02)
    b = 0.3
    corners = np.array([[x, y, z] for z in (0.0, 0.6) for y in (-b, b) for x in (-b, b)], float) + [1.0, 0, 0]
    faces = [(4, 5, 7), (4, 7, 6), (0, 1, 5), (0, 5, 4), (2, 6, 7), (2, 7, 3), (0, 4, 6), (0, 6, 2), (1, 3, 7),
             (1, 7, 5)]  # no bottom: the floor closes it
    tri = np.concatenate([floor.triangles, corners[np.array(faces)]])
    scene = Scene.build(tri, Materials.make([]), [PointLight("p", [1.0, 0, 0.3], [1000.0] * 3)], floor.camera)
    assert diffuse_direct(scene)[0] == 0.0


@pytest.mark.parametrize("scale, center", [(1e-4, (0, 0, 0)), (1e4, (0, 0, 0)), (1.0, (1e5, -1e5, 1e5))])
def test_world_light_survives_extreme_scale_and_position(scale, center):
    """Shadow rays leaving the floor must not hit it, whatever the scale or distance from the origin."""
    value, _ = diffuse_direct(plane_scene([], world=(0.5, 0.5, 0.5), view=0.5, scale=scale, center=center))
    assert value == pytest.approx(0.5, rel=1e-6)


@pytest.mark.parametrize("scale", [1e-3, 1e3])
def test_point_light_scales_as_inverse_square(scale):
    light = PointLight("p", [0, 0, H * scale], [100.0] * 3)
    value, _ = diffuse_direct(plane_scene([light], view=0.02, scale=scale))
    assert value == pytest.approx(100.0 / (4 * np.pi) / (H * scale) ** 2 / np.pi, rel=2e-3)


def test_same_seed_same_image_other_seed_other_noise():
    light = AreaLight("a", [0, 0, H], [0.5, 0, 0], [0, 0.5, 0], [0, 0, -1], [40.0] * 3)
    scene = plane_scene([light], view=3.0, res=16)
    a = render(scene, RenderSettings(samples=4, light_samples=1, seed=1)).passes["Diffuse Direct"]
    b = render(scene, RenderSettings(samples=4, light_samples=1, seed=1)).passes["Diffuse Direct"]
    c = render(scene, RenderSettings(samples=4, light_samples=1, seed=2)).passes["Diffuse Direct"]
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)


def polygon_light(p, n, corners, radiance):
    """Lambert's formula: the light a white Lambertian surface at p (normal n) reflects from a Lambertian polygon
    of the given radiance wholly above its plane, (1/pi) x irradiance = L / (2 pi) |sum_i theta_i n . g_i|, with
    theta_i the angle between the directions to corners i and i+1 and g_i their unit cross product."""
    v = np.asarray(corners, float) - p
    total = 0.0
    for a, b in zip(v, np.roll(v, -1, axis=0)):
        g = np.cross(a, b)
        total += np.arctan2(np.linalg.norm(g), a @ b) * (g @ n) / np.linalg.norm(g)
    return radiance * abs(total) / (2.0 * np.pi)


PANEL = np.array([[[0, 0, 0], [1, 0, 0], [1, 1, 0]], [[0, 0, 0], [1, 1, 0], [0, 1, 0]]], float)  # 1 m square


@pytest.mark.parametrize("point, normal", [
    ((0.3, 0.3, -1e-3), (0, 0, 1)),  # 1 mm under the panel: the solid angle is 2 pi less 0.3 %
    ((0.3, 0.3, -1e-9), (0, 0, 1)),  # 1 nm under it, where Arvo's construction alone was 4 % off at 10 nm
    ((-0.005, 0.5, -0.01), (0, 0, 1)),  # on a wall 1 cm behind it, 5 mm out from its edge
    ((0.2, 0.7, -0.5), (0.6, 0, 0.8)),  # tilted
    ((2.0, 2.0, -1.0), (0, 0, 1)),  # off to the side
    ((0.5, 0.4, -300.0), (0, 0, 1)),  # far: 1e-5 sr
])
def test_emissive_triangles_sampled_by_solid_angle_match_lambert(point, normal):
    """Next-event samples of an emissive panel (two triangles) are unbiased wherever the point is, and bounded by
    L x 2 pi / p(triangle): no sample of a point near the panel is a 1/d^2 spike."""
    p, n = np.array(point, float), np.array(normal, float)
    light = EmissiveTriangles(PANEL, np.tile([0.0, 0.0, 1.0], (2, 1)), np.full((2, 3), 3.0))
    count = 200_000
    rng = np.random.default_rng(7)
    wi, dist, weight, _ = light.sample_incident(np.broadcast_to(p, (count, 3)), None, rng.random(count),
                                                rng.random(count))
    assert np.isfinite(weight).all() and weight.max() <= 3.0 * 2.0 * np.pi / 0.5
    hit = p + dist[:, None] * wi  # every direction finds the panel, at the distance given
    assert np.abs(hit[:, 2]).max() < 1e-9 and hit[:, :2].min() > -1e-9 and hit[:, :2].max() < 1.0 + 1e-9
    value = weight[:, 0] * np.maximum(wi @ n, 0.0) / np.pi
    expected = polygon_light(p, n, [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], 3.0)
    assert abs(value.mean() - expected) < max(4.0 * value.std() / np.sqrt(count), 1e-3 * expected)


def test_emissive_panel_rim_is_not_a_heavy_tail():
    """A render of a wall 1 cm behind a glowing panel takes 32 light samples a pixel at its edge: drawn by area on
    the panel, their mean had a median of 0.03x its expectation (rare 1/d^2 spikes carry it), which a denoiser
    removes as noise and leaves a dark rim. By solid angle the median is the mean."""
    light = EmissiveTriangles(PANEL, np.tile([0.0, 0.0, 1.0], (2, 1)), np.full((2, 3), 3.0))
    p, draws, per_pixel = np.array([-0.005, 0.5, -0.01]), 2000, 32
    rng = np.random.default_rng(8)
    wi, _, weight, _ = light.sample_incident(np.broadcast_to(p, (draws * per_pixel, 3)), None,
                                             rng.random(draws * per_pixel), rng.random(draws * per_pixel))
    pixels = (weight[:, 0] * np.maximum(wi[:, 2], 0.0) / np.pi).reshape(draws, per_pixel).mean(axis=1)
    assert np.median(pixels) > 0.95 * pixels.mean()
    square = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]
    assert pixels.mean() == pytest.approx(polygon_light(p, np.array([0, 0, 1.0]), square, 3.0), rel=5e-3)


def test_emissive_triangles_at_degenerate_points():
    """Points on a corner, on an edge, in the panel's plane beside it or inside it, and very far: finite samples,
    directions unit or zero (no light), weights at most L x 2 pi / p(triangle)."""
    light = EmissiveTriangles(PANEL, np.tile([0.0, 0.0, 1.0], (2, 1)), np.full((2, 3), 3.0))
    points = np.array([[0, 0, 0], [1, 1, 0], [0.5, 0, 0], [0.5, 0.5, 0], [2, 2, 0], [0.3, 0.6, 0], [0.3, 0.6, -1e-12],
                       [1e30, 0, 1]], float)
    count = 500
    rng = np.random.default_rng(9)
    p = np.repeat(points, count, axis=0)
    wi, dist, weight, _ = light.sample_incident(p, None, rng.random(len(p)), rng.random(len(p)))
    assert np.isfinite(wi).all() and np.isfinite(dist).all() and np.isfinite(weight).all()
    length = np.linalg.norm(wi, axis=1)
    assert np.all((np.abs(length - 1.0) < 1e-9) | ((length == 0.0) & (weight.max(axis=1) == 0.0)))
    assert weight.max() <= 3.0 * 2.0 * np.pi / 0.5 + 1e-9
    corners_and_edges = weight.reshape(len(points), count, 3)[:5]
    assert corners_and_edges.max() == 0.0  # the plane beside the panel and its own boundary see none of it
