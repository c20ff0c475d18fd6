"""The metallic GGX lobe (``microfacet``) and the glossy passes, without Blender: the lobe's sampling against its
evaluation, its albedo tables against brute-force integration, and Glossy Direct / Glossy Color on a metal floor
under a sun against the closed form."""
from dataclasses import replace

import numpy as np
import pytest

from conftest import plane_scene
from vpl_addon.core.sampling import uniform_sphere
from vpl_addon.core.scene import Materials, Scene
from vpl_addon.core.tracer import Tracer
from vpl_addon.lights import SunLight
from vpl_addon.materials import microfacet as M
from vpl_addon.materials.surface import shade
from vpl_addon.paths.gbuffer import GBuffer
from vpl_addon.render import RenderSettings, glossy_samples, render

K = 200_000


def _lobe(roughness, mu, k=K):
    n = np.tile([0.0, 0.0, 1.0], (k, 1))
    v = np.tile([np.sqrt(1.0 - mu * mu), 0.0, mu], (k, 1))
    return n, v, np.full(k, float(M.alpha(roughness)))


@pytest.mark.parametrize("roughness, mu", [(0.3, 0.8), (0.3, 0.25), (0.7, 0.5)])
def test_sampling_matches_evaluation(roughness, mu):
    """value / pdf of a sampled direction is F G2/G1, and the pdf over all directions integrates to the sampled
    directions that stay above the surface."""
    rng = np.random.default_rng(0)
    n, v, a = _lobe(roughness, mu)
    f0, b = np.full((K, 3), 0.9), np.zeros((K, 3))
    l, g, h = M.sample(n, v, a, rng.random(K), rng.random(K))
    value, pdf = M.evaluate(n, v, l, a, f0, b)
    up = g > 0
    expected = M.fresnel(f0, b, np.sum(v * h, axis=1))[:, 0] * g
    np.testing.assert_allclose(value[up, 0] / pdf[up], expected[up], rtol=1e-9)
    k = 1_000_000
    n, v, a = _lobe(roughness, mu, k)
    u1, u2 = (np.arange(k) + rng.random(k)) / k, rng.random(k)  # stratified in cos theta
    _, pdf_uniform = M.evaluate(n, v, uniform_sphere(u1, u2), a, np.full((k, 3), 0.9), np.zeros((k, 3)))
    assert (pdf_uniform * 4 * np.pi).mean() == pytest.approx(up.mean(), rel=0.02)


@pytest.mark.parametrize("roughness, mu", [(0.3, 0.5), (0.6, 0.8), (1.0, 0.3)])
def test_albedo_table_is_the_integral_of_the_lobe(roughness, mu):
    """E(mu) of the table equals the lobe with F = 1 integrated over uniformly sampled directions."""
    rng = np.random.default_rng(1)
    n, v, a = _lobe(roughness, mu, 400_000)
    value, _ = M.evaluate(n, v, uniform_sphere(rng.random(len(n)), rng.random(len(n))), a, np.ones((len(n), 3)),
                          np.zeros((len(n), 3)))
    e_table = np.interp(mu, M.mu_grid(), M.albedo_table(roughness)[0])
    assert (value[:, 0] * 4 * np.pi).mean() == pytest.approx(e_table, rel=0.03)
    assert 0.0 < e_table <= 1.0


def test_lobe_is_reciprocal():
    rng = np.random.default_rng(2)
    k = 1000
    n = np.tile([0.0, 0.0, 1.0], (k, 1))
    v, l = (uniform_sphere(rng.random(k), rng.random(k)) for _ in range(2))
    v[:, 2], l[:, 2] = np.abs(v[:, 2]), np.abs(l[:, 2])
    a, f0, b = np.full(k, 0.2), np.full((k, 3), 0.5), np.zeros((k, 3))
    forward, _ = M.evaluate(n, v, l, a, f0, b)
    backward, _ = M.evaluate(n, l, v, a, f0, b)
    np.testing.assert_allclose(forward[:, 0] / l[:, 2], backward[:, 0] / v[:, 2], rtol=1e-9)


def test_f82_tint_sets_the_reflectance_at_one_seventh():
    f0 = np.array([[0.9, 0.6, 0.3]])
    tint = np.array([[0.5, 1.0, 0.8]])
    schlick_bar = M.schlick(f0, np.array([1 / 7]))
    np.testing.assert_allclose(M.fresnel(f0, M.f82_b(f0, tint), np.array([1 / 7])), tint * schlick_bar)
    mu = np.linspace(0, 1, 9)
    np.testing.assert_allclose(M.fresnel(np.repeat(f0, 9, 0), np.zeros((9, 3)), mu), M.schlick(np.repeat(f0, 9, 0), mu))


def test_glossy_color_of_a_smooth_metal_seen_head_on_is_its_base_color():
    rough = np.array([0.05])
    scale, color = M.compensation(rough, np.array([[0.9, 0.6, 0.3]]), np.zeros((1, 3)), np.array([1.0]))
    np.testing.assert_allclose(color, [[0.9, 0.6, 0.3]], rtol=0.02)
    assert (scale >= 1.0).all()


def _metal_floor(sun, roughness=0.4, color=(0.9, 0.7, 0.5)):
    floor = plane_scene([sun], view=0.02, materials=Materials.make([{"name": "metal", "base_color": color,
                                                                      "metallic": 1.0, "roughness": roughness}]))
    return Scene.build(floor.triangles, floor.materials, floor.lights, floor.camera, material=[1, 1])


def test_glossy_direct_of_a_metal_floor_under_a_sun():
    """Seen straight down, a metal floor lit by a sun 30 degrees off the vertical reflects strength x f cos x the
    compensation; Glossy Direct x Glossy Color holds that light, Combined too, and the diffuse passes are black."""
    tilt = np.radians(30)
    sun = SunLight("sun", [np.sin(tilt), 0, -np.cos(tilt)], [3.0] * 3)
    passes = ("Combined", "Diffuse Direct", "Glossy Direct", "Glossy Color")
    result = render(_metal_floor(sun), RenderSettings(samples=4, light_samples=1, method="none", passes=passes))
    n, v = np.array([[0.0, 0.0, 1.0]]), np.array([[0.0, 0.0, 1.0]])
    l = np.array([[np.sin(tilt), 0.0, np.cos(tilt)]])
    f0 = np.array([[0.9, 0.7, 0.5]])
    value, _ = M.evaluate(n, v, l, M.alpha(np.array([0.4])), f0, np.zeros((1, 3)))
    scale, color = M.compensation(np.array([0.4]), f0, np.zeros((1, 3)), np.array([1.0]))
    expected = 3.0 * value[0] * scale[0]
    light = result.passes["Glossy Direct"] * result.passes["Glossy Color"]
    np.testing.assert_allclose(light.mean(axis=(0, 1)), expected, rtol=1e-3)
    np.testing.assert_allclose(result.passes["Glossy Color"].mean(axis=(0, 1)), color[0], rtol=1e-3)
    np.testing.assert_allclose(result.passes["Combined"][..., :3].mean(axis=(0, 1)), expected, rtol=1e-3)
    assert result.passes["Diffuse Direct"].max() == 0.0


@pytest.mark.parametrize("roughness", [0.3, 0.05])
@pytest.mark.parametrize("shape", ["square", "disc", "emissive square", "emissive square, glowing floor"])
def test_glossy_direct_of_an_area_light_over_a_metal_floor(roughness, shape):
    """An area light (or an emissive mesh of its square) mirrored by a metal floor seen straight down: Glossy
    Direct x Glossy Color against the lobe integrated over the light on an 800 x 800 grid. At roughness 0.05 the
    lobe's peak lies inside the light's solid angle; light samples alone gave pixels 14 times the mean (a
    coefficient of variation of 2 over the pixels) and a mean 11-19 % off; with the lobe's own samples and MIS the
    pixels agree within a few per cent (the emissive mesh's too: ``EmissiveTriangles.mis``, also when the floor
    glows faintly itself, so that its points lie on the light's own triangles)."""
    from vpl_addon.lights import AreaLight
    height, size, power, f0 = 1.0, 0.3, 10.0, (0.9, 0.7, 0.5)
    round_ = shape == "disc"
    light = AreaLight("a", [0.1, 0.05, height], [size, 0, 0], [0, size, 0], [0, 0, -1], [power] * 3, round=round_)
    floor = plane_scene([light], view=0.02, res=16)
    rows = [{"name": "metal", "base_color": f0, "metallic": 1.0, "roughness": roughness,
             "emission": (1e-6,) * 3 if shape.endswith("glowing floor") else (0.0,) * 3}]
    if shape.startswith("emissive square"):  # the same square as two triangles glowing with the area light's radiance
        x0, x1, y0, y1 = 0.1 - size / 2, 0.1 + size / 2, 0.05 - size / 2, 0.05 + size / 2
        panel = np.array([[[x0, y0, height], [x1, y1, height], [x1, y0, height]],
                          [[x0, y0, height], [x0, y1, height], [x1, y1, height]]])
        rows.append({"name": "glow", "emission": (power / (np.pi * size * size),) * 3})
        camera = replace(floor.camera, clip_start=4.5)  # from under the panel
        scene = Scene.build(np.concatenate([floor.triangles, panel]), Materials.make(rows), [], camera,
                            material=[1, 1, 2, 2])
    else:
        scene = Scene.build(floor.triangles, Materials.make(rows), floor.lights, floor.camera, material=[1, 1])
    out = render(scene, RenderSettings(samples=16, light_samples=4, method="none",
                                       passes=("Glossy Direct", "Glossy Color"))).passes
    light_out = (out["Glossy Direct"] * out["Glossy Color"])[..., 0]

    g = (np.arange(800) + 0.5) / 800 - 0.5
    a, b = (x.ravel() for x in np.meshgrid(g, g))
    on = 4.0 * (a * a + b * b) <= 1.0 if round_ else np.ones(a.size, bool)
    q = np.c_[0.1 + a * size, 0.05 + b * size, np.full(a.size, height)][on]
    d2 = (q * q).sum(axis=1)
    up = np.tile([0.0, 0.0, 1.0], (len(q), 1))
    value, _ = M.evaluate(up, up, q / np.sqrt(d2)[:, None], np.full(len(q), float(M.alpha(np.array([roughness]))[0])),
                          np.tile(f0, (len(q), 1)), np.zeros((len(q), 3)))
    scale = M.compensation(np.array([roughness]), np.array([f0]), np.zeros((1, 3)), np.array([1.0]))[0][0, 0]
    solid = height / np.sqrt(d2) / d2 * (size / 800) ** 2  # cos at the light / d^2 x the cell's area
    expected = (value[:, 0] * solid).sum() * power / (np.pi * light.area) * scale
    assert light_out.mean() == pytest.approx(expected, rel=0.015)
    assert light_out.std() / light_out.mean() < 0.1


def test_glossy_direct_of_an_area_light_over_a_rough_coat_by_light_samples_alone():
    """A black Principled floor with the default Specular (IOR 1.5) at roughness 0.6, under a 2 m area light 0.5 m
    above it, seen straight down: its lobe is a rough coat (``Surface.rough_coat``), whose light comes from light
    samples alone, without the lobe's samples and MIS. Glossy Direct x Glossy Color against the coat's lobe
    (compensated, Fresnel at v.h) integrated over the light on a 400 x 400 grid: the mean within 1.5 %, the pixels
    within 10 % of it. With the MIS weights kept and the lobe's samples dropped the mean came out 0.0125 for 0.0240."""
    from vpl_addon.lights import AreaLight
    height, size, power, roughness = 0.5, 2.0, 10.0, 0.6
    light = AreaLight("a", [0.3, 0.1, height], [size, 0, 0], [0, size, 0], [0, 0, -1], [power] * 3)
    floor = plane_scene([light], view=0.02, res=16)
    materials = Materials.make([{"name": "coat", "base_color": (0.0, 0.0, 0.0), "specular": 0.5,
                                 "roughness": roughness}])
    scene = Scene.build(floor.triangles, materials, floor.lights, floor.camera, material=[1, 1])
    out = render(scene, RenderSettings(samples=16, light_samples=4, method="none",
                                       passes=("Glossy Direct", "Glossy Color"))).passes
    light_out = (out["Glossy Direct"] * out["Glossy Color"])[..., 0]

    g = (np.arange(400) + 0.5) / 400 - 0.5
    a, b = (x.ravel() for x in np.meshgrid(g, g))
    q = np.c_[0.3 + a * size, 0.1 + b * size, np.full(a.size, height)]
    d2 = (q * q).sum(axis=1)
    down = np.array([[0.0, 0.0, -1.0]])  # the floor's centre as the camera finds it, seen from straight above
    tracer = Tracer(scene.triangles, threads=1)
    point = shade(scene, down, tracer.intersect(np.array([[0.0, 0.0, 1.0]]), down), np.array([0]))
    tracer.close()
    assert point.rough_coat.all()
    lobe = M.GlossyLobe.of(point)
    value, _ = lobe.evaluate(q / np.sqrt(d2)[:, None], np.zeros(len(q), np.int64))
    solid = height / np.sqrt(d2) / d2 * (size / 400) ** 2  # cos at the light / d^2 x the cell's area
    expected = (value[:, 0] * solid).sum() * power / (np.pi * light.area)
    assert light_out.mean() == pytest.approx(expected, rel=0.015)
    assert light_out.std() / light_out.mean() < 0.1


def _uv_sphere(center, radius, rings=32, segments=64):
    """(T,3,3) triangles of a UV sphere (quads split in two, a fan at each pole), as Blender's UV sphere."""
    theta = np.linspace(0.0, np.pi, rings + 1)
    phi = np.linspace(0.0, 2.0 * np.pi, segments + 1)
    t, f = np.meshgrid(theta, phi, indexing="ij")
    v = np.stack([np.sin(t) * np.cos(f), np.sin(t) * np.sin(f), np.cos(t)], axis=-1) * radius + center
    a, b, c, d = v[:-1, :-1], v[:-1, 1:], v[1:, 1:], v[1:, :-1]
    tris = np.concatenate([np.stack([a, c, b], -2)[1:], np.stack([a, d, c], -2)[:-1]])
    return tris.reshape(-1, 3, 3)


def test_glossy_direct_of_a_glowing_sphere_seen_in_a_metal_floor():
    """A glowing mesh sphere mirrored by a smooth metal floor (roughness 0.1, as the plates of Veach's MIS scene)
    seen at 70 degrees from its normal: Glossy Direct x Glossy Color against the lobe integrated over the directions
    that find the sphere's triangles (a 1000 x 1000 grid over a cone about the sphere). A second glowing sphere 30 m
    away, under the floor, makes the emitters' own BVH 30 m wide, so the rays it traces for the lobe's samples leave
    the floor pushed 2.4e-4 m off it: their distance to the sphere, taken from that pushed origin, put the shadow ray's
    end inside the sphere wherever its surface faced up: the rim's highlight came out 0.066 for 4.87 (veach_mis: the
    reflections' lower rims dark by half)."""
    radius, theta, power = 0.2, np.radians(70.0), 10.0
    view = np.array([np.sin(theta), 0.0, np.cos(theta)])  # toward the camera
    # 1 m along the mirror direction, and 0.9 radii below it: the lobe's rays meet the sphere's upper rim
    center = np.array([-np.sin(theta), 0.0, np.cos(theta)]) - 0.9 * radius * np.array([np.cos(theta), 0.0,
                                                                                         np.sin(theta)])
    sphere = np.concatenate([_uv_sphere(center, radius), _uv_sphere(np.array([30.0, 0.0, -5.0]), radius, 8, 16)])
    floor = plane_scene([], view=0.01, res=16)
    to_world = np.eye(4)
    to_world[:3, 0], to_world[:3, 1], to_world[:3, 2] = (0.0, 1.0, 0.0), np.cross(view, [0.0, 1.0, 0.0]), view
    to_world[:3, 3] = 5.0 * view
    camera = replace(floor.camera, to_world=to_world)
    glow = power / (4.0 * np.pi * np.pi * radius * radius)
    f0 = (0.9, 0.7, 0.5)
    rows = [{"name": "metal", "base_color": f0, "metallic": 1.0, "roughness": 0.1},
            {"name": "glow", "emission": (glow,) * 3}]
    scene = Scene.build(np.concatenate([floor.triangles, sphere]), Materials.make(rows), [], camera,
                        material=[1, 1] + [2] * len(sphere))
    out = render(scene, RenderSettings(samples=16, light_samples=4, method="none",
                                       passes=("Glossy Direct", "Glossy Color"))).passes
    light_out = (out["Glossy Direct"] * out["Glossy Color"])[..., 0]

    # directions from the floor's centre, uniform in solid angle over a cone a little wider than the sphere
    axis = center / np.linalg.norm(center)
    cos_max = np.cos(np.arcsin(1.02 * radius / np.linalg.norm(center)))
    g = (np.arange(1000) + 0.5) / 1000
    u, v = (x.ravel() for x in np.meshgrid(g, g))
    z = 1.0 - u * (1.0 - cos_max)
    s = np.sqrt(1.0 - z * z)
    e1 = np.array([0.0, 1.0, 0.0])
    e2 = np.cross(axis, e1)
    dirs = (s * np.cos(2 * np.pi * v))[:, None] * e1 + (s * np.sin(2 * np.pi * v))[:, None] * e2 + z[:, None] * axis
    dirs = dirs[Tracer(sphere).intersect(np.zeros_like(dirs), dirs).hit]
    k = len(dirs)
    value, _ = M.evaluate(np.tile([0.0, 0.0, 1.0], (k, 1)), np.tile(view, (k, 1)), dirs,
                          np.full(k, float(M.alpha(np.array([0.1]))[0])), np.tile(f0, (k, 1)), np.zeros((k, 3)))
    scale = M.compensation(np.array([0.1]), np.array([f0]), np.zeros((1, 3)), np.array([view[2]]))[0][0, 0]
    expected = value[:, 0].sum() * 2.0 * np.pi * (1.0 - cos_max) / u.size * glow * scale
    assert light_out.mean() == pytest.approx(expected, rel=0.02)


@pytest.mark.parametrize("roughness", [0.3, 0.05])
def test_glossy_direct_of_the_world_over_a_metal_floor(roughness):
    """A constant world over a metal floor: the light the lobe reflects is the world's radiance times the lobe's
    albedo, so Glossy Direct (light over Glossy Color) is about the radiance. With cosine samples of the world alone
    a roughness-0.05 lobe gave a mean of 1.87 for 0.7 and a pixel CV of 9; MIS with the lobe's samples, 0.700 and
    0.01."""
    world = (0.7, 0.7, 0.7)
    floor = plane_scene([], world=world, view=0.02, res=16)
    materials = Materials.make([{"name": "metal", "base_color": (0.9, 0.7, 0.5), "metallic": 1.0,
                                 "roughness": roughness}])
    scene = Scene.build(floor.triangles, materials, [], floor.camera, material=[1, 1], world=world)
    direct = render(scene, RenderSettings(samples=16, light_samples=4, method="none",
                                          passes=("Glossy Direct", "Glossy Color"))).passes["Glossy Direct"][..., 0]
    assert direct.mean() == pytest.approx(0.7, rel=0.02)
    assert direct.std() / direct.mean() < 0.1


def test_diffuse_scenes_compute_nothing_glossy():
    """Without a metallic material the glossy passes are black and the glossy lobe is never built."""
    sun = SunLight("sun", [0, 0, -1], [3.0] * 3)
    scene = plane_scene([sun], view=0.02)
    assert not scene.materials.glossy
    result = render(scene, RenderSettings(samples=2, light_samples=1, method="none",
                                          passes=("Combined", "Glossy Direct", "Glossy Color")))
    assert result.passes["Glossy Direct"].max() == 0.0 and result.passes["Glossy Color"].max() == 0.0


@pytest.mark.parametrize("colour", [(0.9, 0.5, 0.1), (0.02, 0.3, 1.0), (0.0, 0.0, 0.0)])
def test_glossy_bsdf_tint_gives_the_colour_as_mean_reflectance(colour):
    """Cycles' Glossy BSDF has no Fresnel; as a metallic lobe its F82 tint makes the Fresnel's cosine-weighted mean
    the colour (and it is the colour at normal incidence, F0)."""
    c = np.array(colour)
    tint = M.constant_reflectance_tint(c)
    mu = (np.arange(4096) + 0.5) / 4096
    f = M.fresnel(np.broadcast_to(c, (4096, 3)), M.f82_b(c, tint)[None], mu)
    assert np.allclose(2 * (mu[:, None] * f).mean(axis=0), np.maximum(c, 0.0044), atol=1e-4)  # black: a trace
    assert np.allclose(f[-1], c, atol=1e-3) and ((tint >= 0) & (tint <= 1)).all()


@pytest.mark.parametrize("metallic, roughness, fewest, most", [(0.0, 0.8, 2, 2), (0.0, 0.2, 16, 16),
                                                                (1.0, 0.8, 16, 16)])
def test_a_rough_clear_coat_gathers_few_glossy_samples_a_metal_or_sharp_lobe_all(metallic, roughness, fewest, most):
    """``render.glossy_samples`` on a floor's G-buffer: a Principled surface's rough dielectric layer seen head-on
    (Glossy Color 0.024 over a Diffuse Color of 0.49) asks for twice its share of 16 samples, 2; a sharper layer and
    a metal keep all 16."""
    floor = plane_scene(materials=Materials.make([{"name": "m", "base_color": (0.5, 0.5, 0.5), "specular": 0.5,
                                                   "metallic": metallic, "roughness": roughness}]))
    scene = Scene.build(floor.triangles, floor.materials, floor.lights, floor.camera, material=[1, 1])
    tracer = Tracer(scene.triangles, threads=1)
    gbuf = GBuffer.build(scene, tracer, scene.camera.frame_pixels(np.arange(64)), 16, np.random.default_rng(0))
    counts = glossy_samples(gbuf, gbuf.surface, M.GlossyLobe.of(gbuf.surface), 16)
    tracer.close()
    assert counts.shape == (64,)
    assert fewest <= counts.min() and counts.max() <= most


def test_compensation_reads_the_tables_at_nan_inputs_without_leaving_them():
    """``microfacet._add_lobe`` is compiled without bounds checks: a NaN roughness or view cosine reads the tables'
    first entries (roughness 0, mu 0, ``_tables_at``) instead of an index from floor(NaN)."""
    comp = M.compensation(np.array([np.nan, 0.0]), np.full((2, 3), 0.5), np.zeros((2, 3)), np.array([0.0, np.nan]))
    first = M.compensation(np.zeros(1), np.full((1, 3), 0.5), np.zeros((1, 3)), np.zeros(1))
    for got, want in zip(comp, first):
        np.testing.assert_array_equal(got, np.repeat(want, 2, axis=0))
