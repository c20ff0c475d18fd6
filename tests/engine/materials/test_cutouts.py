"""Alpha cut-outs (``materials.cutouts``): every ray the tracer answers goes through the holes of a material's Alpha,
stochastically where it is between 0 and 1, and a clip threshold makes a map's alpha 0 or 1."""
import numpy as np
import pytest

from vpl_addon.core.camera import Camera, view_window
from vpl_addon.core.color import luminance
from vpl_addon.core.scene import Materials, Scene, TextureMap
from vpl_addon.core.tracer import CUTOUT_LAYERS, Tracer
from vpl_addon.lights import LightSet
from vpl_addon.lights.direct import diffuse_direct
from vpl_addon.lights.sun import SunLight
from vpl_addon.materials.cutouts import cutouts
from vpl_addon.materials.surface import shade
from vpl_addon.materials.textures import lookup

CAM = Camera(np.eye(4), 8, 8, view_window(8, 8, orthographic=False))
QUAD = np.array([[[0, 0, 0], [1, 0, 0], [1, 1, 0]], [[0, 0, 0], [1, 1, 0], [0, 1, 0]]], float)
QUAD_UV = np.array([[[0, 0], [1, 0], [1, 1]], [[0, 0], [1, 1], [0, 1]]], float)
SUN = SunLight("sun", [0.0, 0.0, -1.0], [2.0] * 3)
# a 2x1 alpha image: the left half (u < 0.5) opaque, the right half a hole
HALF = np.array([[[1.0, 1.0, 1.0, 1.0], [1.0, 1.0, 1.0, 0.0]]], np.float32)


def fence_scene(fence: dict, layers: int = 1):
    """A white floor (z = 0) under ``layers`` fence quads (z = 0.5, 0.6, ...) of material ``fence``."""
    tri = [QUAD] + [QUAD + [0.0, 0.0, 0.5 + 0.1 * i] for i in range(layers)]
    rows = [{"name": "floor", "base_color": (1, 1, 1)}, dict(fence, name="fence")]
    return Scene.build(np.concatenate(tri), Materials.make(rows), [SUN], CAM, uvs=np.tile(QUAD_UV, (layers + 1, 1, 1)),
                       material=[1, 1] + [2, 2] * layers, textures=[HALF])


def tracer_of(scene, seed=0):
    return Tracer(scene.triangles, threads=1, cutouts=cutouts(scene), seed=seed)


def floor_light(scene, xy, samples=64):
    """Diffuse Direct on the floor at points ``xy``, found by rays from below (they see the floor's underside
    turned toward them, so shade them from above instead)."""
    tracer = tracer_of(scene)
    origins = np.column_stack([xy, np.full(len(xy), 0.25)])
    down = np.tile([0.0, 0.0, -1.0], (len(xy), 1))
    hits = tracer.intersect(origins, down)
    assert (hits.prim < 2).all()  # the floor
    surface = shade(scene, down, hits, np.arange(len(xy)))
    return diffuse_direct(surface, LightSet(scene), tracer, samples, np.random.default_rng(3))[:, 0]


def test_an_opaque_scene_has_no_cutouts():
    assert cutouts(fence_scene({"base_color": (1, 1, 1)})) is None


def test_the_shadow_of_an_alpha_map_is_cut_where_the_map_is_clear():
    scene = fence_scene({"maps": {"alpha": TextureMap(0, channel=3, closest=True)}})
    xy = np.array([[0.2, 0.3], [0.3, 0.7], [0.7, 0.3], [0.8, 0.8]])
    light = floor_light(scene, xy)
    assert np.allclose(light[:2], 0.0)  # under the opaque half
    assert np.allclose(light[2:], 2.0 / np.pi)  # under the hole: the full sun


def test_camera_rays_see_through_the_hole_and_stop_on_the_fence():
    scene = fence_scene({"maps": {"alpha": TextureMap(0, channel=3, closest=True)}})
    xy = np.array([[0.25, 0.5], [0.75, 0.5]])
    hits = tracer_of(scene).intersect(np.column_stack([xy, [2.0, 2.0]]), np.tile([0.0, 0.0, -1.0], (2, 1)))
    assert hits.prim[0] >= 2 and np.isclose(hits.t[0], 1.5)  # the fence
    assert hits.prim[1] < 2 and np.isclose(hits.t[1], 2.0, atol=1e-4)  # the floor, through the hole


def test_partial_alpha_lets_through_its_share_of_light_and_of_rays():
    scene = fence_scene({"alpha": 0.25})
    light = floor_light(scene, np.full((200, 2), 0.5), samples=64)
    assert abs(light.mean() / (2.0 / np.pi) - 0.75) < 0.02  # 12800 shadow rays: 0.4 % sd
    k = 20000
    tracer = tracer_of(fence_scene({"alpha": 0.5}, layers=3), seed=1)
    hits = tracer.intersect(np.tile([0.5, 0.5, 2.0], (k, 1)), np.tile([0.0, 0.0, -1.0], (k, 1)))
    assert abs((hits.prim < 2).mean() - 0.125) < 0.01  # through three halves
    assert abs(tracer.occluded(np.tile([0.5, 0.5, 0.01], (k, 1)), np.tile([0.0, 0.0, 1.0], (k, 1)),
                               np.full(k, 10.0)).mean() - 0.875) < 0.01


def test_a_shadow_ray_that_a_solid_surface_blocks_is_not_traced_again_through_the_cutouts():
    """Occlusion asks the BVH of the triangles without holes first (``Tracer._parts``): a ray blocked there is
    blocked, and only the rays it lets through and a cut-out blocks are walked through the layers. Rays down through
    three half-clear fences onto the floor cost one ray each (the walk for every blocked ray cost 2-4 more); rays up
    from the floor between the fences are still blocked by the stack half the time, ray by ray."""
    k = 4000
    tracer = tracer_of(fence_scene({"alpha": 0.5}, layers=3), seed=2)
    down = tracer.occluded(np.tile([0.5, 0.5, 2.0], (k, 1)), np.tile([0.0, 0.0, -1.0], (k, 1)), np.full(k, 10.0))
    assert down.all() and tracer.rays_traced == k
    up = tracer.occluded(np.tile([0.5, 0.5, 0.01], (k, 1)), np.tile([0.0, 0.0, 1.0], (k, 1)), np.full(k, 10.0))
    assert abs(up.mean() - 0.875) < 0.02


def test_occlusion_follows_cutouts_that_change_without_the_triangles():
    """A sequence's frame may change alpha without moving a triangle (``SequenceState`` hands the tracer the new
    ``cutouts``): the BVHs of the scene's solid and holed parts are made again for it. Here the floor becomes a hole
    and the fence solid: rays up through the floor stopping short of the fence were blocked, now they pass."""
    tri = np.concatenate([QUAD, QUAD + [0.0, 0.0, 0.5]])

    def scene(floor: dict, fence: dict):
        return Scene.build(tri, Materials.make([dict(floor, name="floor"), dict(fence, name="fence")]), [SUN], CAM,
                           material=[1, 1, 2, 2])
    tracer = tracer_of(scene({}, {"alpha": 0.0}))
    origins, up, short = np.tile([0.5, 0.5, -0.5], (8, 1)), np.tile([0.0, 0.0, 1.0], (8, 1)), np.full(8, 0.8)
    assert tracer.occluded(origins, up, short).all()
    tracer.cutouts = cutouts(scene({"alpha": 0.0}, {}))
    assert not tracer.occluded(origins, up, short).any()
    assert tracer.occluded(origins, up, np.full(8, 1.5)).all()  # the fence, solid now


def test_a_fully_clear_stack_deeper_than_the_layer_limit_stops_the_ray_at_the_limit():
    scene = fence_scene({"alpha": 0.0}, layers=CUTOUT_LAYERS + 2)
    hits = tracer_of(scene).intersect(np.array([[0.5, 0.5, 10.0]]), np.array([[0.0, 0.0, -1.0]]))
    assert hits.hit[0] and hits.prim[0] >= 2 and np.isfinite(hits.t).all()


def test_alpha_clip_makes_the_map_zero_or_one():
    ramp = np.linspace(0.0, 1.0, 11, dtype=np.float32)[None, :, None].repeat(4, axis=2)
    uv = np.column_stack([np.linspace(0.01, 0.99, 50), np.full(50, 0.5)])
    clipped = lookup(TextureMap(0, channel=3, factor=(0.8, 0.8, 0.8), cutoff=0.5), [ramp], uv, scalar=True)
    plain = lookup(TextureMap(0, channel=3, factor=(0.8, 0.8, 0.8)), [ramp], uv, scalar=True)
    assert set(np.unique(clipped)) == {0.0, 1.0}
    assert np.array_equal(clipped, (plain >= 0.5).astype(float))  # the factor applies before the threshold


@pytest.mark.parametrize("bad", [np.nan, -3.0, 7.0])
def test_bad_alpha_values_are_read_as_opacity_in_0_1(bad):
    image = np.full((1, 1, 4), bad, np.float32)
    scene = Scene.build(np.concatenate([QUAD, QUAD + [0, 0, 0.5]]),
                        Materials.make([{"name": "f"}, {"name": "x", "maps": {"alpha": TextureMap(0, channel=3)}}]),
                        [SUN], CAM, uvs=np.tile(QUAD_UV, (2, 1, 1)), material=[1, 1, 2, 2], textures=[image])
    found = cutouts(scene)
    opacity = found.opacity(np.array([2, 3]), np.array([0.3, 0.3]), np.array([0.3, 0.3]))
    assert np.isfinite(opacity).all() and ((opacity >= 0) & (opacity <= 1)).all()


def test_glass_passes_one_minus_fresnel_straight_through_and_its_light_is_reported_apart():
    from vpl_addon.lights.direct import direct_light
    from vpl_addon.materials.microfacet import dielectric_fresnel
    scene = fence_scene({"transmission": 1.0, "ior": 1.5, "base_color": (1.0, 1.0, 1.0)})
    tracer = tracer_of(scene)
    xy = np.full((400, 2), 0.5)
    down = np.tile([0.0, 0.0, -1.0], (len(xy), 1))
    hits = tracer.intersect(np.column_stack([xy, np.full(len(xy), 0.25)]), down)
    floor = shade(scene, down, hits, np.arange(len(xy)))
    through = np.zeros((len(xy), 3))
    direct, _ = direct_light(floor, LightSet(scene), tracer, 16, np.random.default_rng(4), through=through)
    assert np.allclose(direct, 0.0)  # Cycles' shadow rays stop at glass: none of it is direct light
    expected = (1.0 - dielectric_fresnel(np.array([1.0]), np.array([1.5]))[0]) * 2.0 / np.pi
    assert abs(through.mean() / expected - 1.0) < 0.01  # 6400 rays at 4 % stopped: 0.25 % sd
    # a camera ray that stops at the pane sees a white mirror: no diffuse colour, all reflection
    k = 4000
    from_above = np.tile([0.3, 0.6, 2.0], (k, 1))
    hits = tracer.intersect(from_above, np.tile([0.0, 0.0, -1.0], (k, 1)))
    on_pane = np.nonzero(hits.prim >= 2)[0]
    assert abs(len(on_pane) / k - 0.04) < 0.01
    pane = shade(scene, np.tile([0.0, 0.0, -1.0], (k, 1)), hits, on_pane)
    assert np.allclose(pane.albedo, 0.0) and np.allclose(pane.metallic, 1.0) and np.allclose(pane.specular, 1.0)


def test_a_seed_gives_one_image_however_the_threads_run():
    from dataclasses import replace

    from vpl_addon.core import passes as P
    from vpl_addon.render import RenderSettings, render
    above = np.eye(4)
    above[:3, 3] = (0.5, 0.5, 3.0)  # looking down -Z at the fence and the floor
    scene = replace(fence_scene({"alpha": 0.5}), camera=Camera(above, 24, 24, view_window(24, 24, orthographic=False)))
    images = [render(scene, RenderSettings(samples=4, light_samples=2, method="none", seed=seed, block_pixels=64,
                                           passes=(P.COMBINED, P.DIFFUSE_DIRECT))).passes[P.DIFFUSE_DIRECT]
              for seed in (0, 0, 1)]
    assert np.array_equal(images[0], images[1]) and not np.array_equal(images[0], images[2])


def slab_scene(top: float, bottom: float | None, roughness: float = 0.0):
    """A white floor (z = 0) under a glass sheet (of ``roughness``) at z = ``top`` facing up and, given ``bottom``,
    a second one at z = ``bottom`` facing down: the two faces of a slab, as a solid's outward winding makes them."""
    big = QUAD * [8.0, 8.0, 1.0] - [4.0, 4.0, 0.0]
    faces = [big, big + [0.0, 0.0, top]]
    if bottom is not None:
        faces.append(big[:, ::-1] + [0.0, 0.0, bottom])  # reversed corners: the normal points down
    rows = [{"name": "floor", "base_color": (1, 1, 1)},
            {"name": "glass", "transmission": 1.0, "ior": 1.5, "base_color": (1, 1, 1), "roughness": roughness}]
    return Scene.build(np.concatenate(faces), Materials.make(rows), [SUN], CAM,
                       material=[1, 1] + [2, 2] * (len(faces) - 1))


def test_camera_rays_refract_through_glass_as_snell_says_and_leave_a_slab_parallel_and_shifted():
    theta = np.radians(30.0)
    k = 2000
    origins = np.tile([0.0, 0.0, 2.0], (k, 1))
    d = np.tile([np.sin(theta), 0.0, -np.cos(theta)], (k, 1))
    inside = np.arcsin(np.sin(theta) / 1.5)
    # one face: the ray goes on inside the glass at Snell's angle
    tracer = tracer_of(slab_scene(0.7, None))
    hits, heading, _ = tracer.intersect_bent(origins, d)
    down = np.nonzero((hits.prim >= 0) & (hits.prim < 2))[0]  # on the floor (a few stop at the face as a mirror)
    assert len(down) > 0.9 * k
    assert np.allclose(heading[down], [np.sin(inside), 0.0, -np.cos(inside)], atol=1e-9)
    # two faces: out again parallel to the camera's ray, shifted toward the normal by the slab's thickness
    tracer = tracer_of(slab_scene(0.7, 0.5))
    hits, heading, _ = tracer.intersect_bent(origins, d)
    down = np.nonzero((hits.prim >= 0) & (hits.prim < 2))[0]
    assert abs(len(down) / k - (1.0 - 0.0419) ** 2) < 0.02  # Fresnel at 30 degrees and at its refracted angle
    assert np.allclose(heading[down], d[0], atol=1e-9)
    floor = shade(slab_scene(0.7, 0.5), heading, hits, down).position
    # (but for the 0.2 % that the faces reflect inside twice, three crossings) the offsets off each face: 1e-4
    once = np.isclose(floor[:, 0], 1.8 * np.tan(theta) + 0.2 * np.tan(inside), atol=1e-3)
    twice = np.isclose(floor[:, 0], 1.8 * np.tan(theta) + 0.6 * np.tan(inside), atol=1e-3)
    assert (once | twice).all() and once.mean() > 0.99
    assert np.allclose(hits.t[down[once]], 1.8 / np.cos(theta) + 0.2 / np.cos(inside), atol=1e-3)
    # rough glass scatters the rays about Snell's direction
    tracer = tracer_of(slab_scene(0.7, None, roughness=0.4))
    hits, heading, _ = tracer.intersect_bent(origins, d)
    down = np.nonzero(hits.prim >= 0)[0]
    spread = np.degrees(np.arccos(np.clip(heading[down] @ [np.sin(inside), 0.0, -np.cos(inside)], -1.0, 1.0)))
    assert len(down) > 0.85 * k and np.median(spread) > 1.0 and np.median(spread) < 15.0
    # the thin sheet's rays (shadow rays, light paths) still go straight through
    straight = tracer.intersect(origins, d)
    assert np.allclose(shade(slab_scene(0.7, 0.5), d, straight, np.nonzero(straight.prim < 2)[0]).position[:, 0],
                       2.0 * np.tan(theta), atol=1e-3)


def test_from_inside_glass_past_the_critical_angle_a_ray_reflects_and_stays_inside():
    tracer = tracer_of(slab_scene(0.7, None))
    steep = np.radians(50.0)  # above asin(1 / 1.5) = 41.8 degrees
    k = 500
    origins = np.tile([0.0, 0.0, 0.3], (k, 1))  # under the face, inside the glass it bounds
    hits, heading, _ = tracer.intersect_bent(origins, np.tile([np.sin(steep), 0.0, np.cos(steep)], (k, 1)))
    assert ((hits.prim >= 0) & (hits.prim < 2)).all()  # every ray turns back down to the floor
    assert np.allclose(heading, [np.sin(steep), 0.0, -np.cos(steep)])
    assert np.allclose(hits.t, 0.4 / np.cos(steep) + 0.7 / np.cos(steep), atol=1e-3)


def test_coloured_glass_colours_the_light_of_every_kind_of_ray_that_crosses_it():
    """A pane of tint (0.2, 0.5, 1) (the colour one crossing leaves, ``Materials.base_color`` of glass) over the
    floor: the sun's light under it, the camera's rays through two such panes, the photons that land under it and
    the gather's light from a VPL above it all come out in the pane's colour, 1 - F of the light crossing it."""
    from vpl_addon.gather.summing import sum_pairs
    from vpl_addon.gather.virtual_lights import STANDARD, VirtualLights
    from vpl_addon.lights.direct import direct_light
    from vpl_addon.materials.microfacet import dielectric_fresnel
    from vpl_addon.paths.light_paths import trace_paths
    tint = np.array([0.2, 0.5, 1.0])
    clear = 1.0 - dielectric_fresnel(np.array([1.0]), np.array([1.5]))[0]
    glass = {"transmission": 1.0, "ior": 1.5, "base_color": tuple(tint)}
    scene = fence_scene(glass)
    tracer = tracer_of(scene)
    xy = np.full((400, 2), 0.5)
    down = np.tile([0.0, 0.0, -1.0], (len(xy), 1))
    floor = shade(scene, down, tracer.intersect(np.column_stack([xy, np.full(len(xy), 0.25)]), down),
                  np.arange(len(xy)))
    through = np.zeros((len(xy), 3))
    direct_light(floor, LightSet(scene), tracer, 16, np.random.default_rng(4), through=through)
    assert np.allclose(through.mean(axis=0) / (clear * tint * 2.0 / np.pi), 1.0, atol=0.01)
    # the camera's rays carry the colour of both panes; a ray not asked for colour passes by the tint's luminance
    k = 20000
    stack = fence_scene(glass, layers=2)
    origins, d = np.tile([0.5, 0.5, 2.0], (k, 1)), np.tile([0.0, 0.0, -1.0], (k, 1))
    hits, _, _ = tracer_of(stack).intersect_bent(origins, d)
    on_floor = hits.prim < 2
    assert abs(on_floor.mean() - clear ** 2) < 0.01 and np.allclose(hits.tint[on_floor], tint ** 2)
    assert np.allclose(hits.tint[hits.prim >= 4], 1.0)  # stopped at the first pane (z = 0.6): not through it
    assert np.allclose(hits.tint[(hits.prim >= 2) & (hits.prim < 4)], tint)  # at the second, through the first
    grey = tracer_of(stack).intersect(origins, d)
    assert grey.tint is None and abs((grey.prim < 2).mean() - (clear * luminance(tint)) ** 2) < 0.01
    # photons from the sun: the lights they leave on the floor are the pane's colour
    vpls = trace_paths(scene, tracer, LightSet(scene), 4000, np.random.default_rng(5), 1)
    under = np.nonzero((np.abs(vpls.position[:, 2]) < 1e-6) & (np.abs(vpls.position[:, :2] - 0.5).max(axis=1) < 0.5))
    assert len(under[0]) > 100
    assert np.allclose(vpls.intensity[under] / vpls.intensity[under][:, 2:], tint)
    # the gather: a VPL above the pane lights the floor below through it
    light = VirtualLights(np.array([[0.5, 0.5, 1.0]]), np.array([[0.0, 0.0, -1.0]]), np.ones((1, 3)),
                          np.ones(1, np.int32), np.full(1, STANDARD, np.int8), np.zeros(1, np.int64))
    pairs = sum_pairs(floor, np.arange(len(xy)), light, np.zeros(len(xy), np.int64), tracer, 0.0,
                      np.zeros(len(xy), np.int64), 1)[0]
    assert np.allclose(pairs / (len(xy) * clear * tint / np.pi), 1.0, atol=0.05)


def test_the_g_buffer_shades_and_looks_up_the_world_along_the_refracted_rays():
    """``camera_hits`` with the lights the camera sees (as ``GBuffer.build`` calls it) hands on the directions the
    rays have past the glass: a surface behind glass is shaded, and the world seen through it looked up, along them
    (Snell's law at a face of z = 0.7: the tangential part over the IOR)."""
    from vpl_addon.paths.gbuffer import camera_hits
    above = np.eye(4)
    above[:3, 3] = (0.0, 0.0, 2.0)
    cam = Camera(above, 8, 8, view_window(8, 8, orthographic=False))
    px, py = np.repeat(np.array([0.5, 2.5, 7.5]), 200), np.repeat(np.array([0.5, 6.0, 4.0]), 200)
    heading, hits, _, _ = camera_hits(cam, tracer_of(slab_scene(0.7, None)), px, py, lights=[])
    _, d, _ = cam.rays(px, py)
    floor = np.nonzero(hits.prim < 2)[0]
    assert len(floor) > 0.9 * len(px) and np.abs(d[floor, :2]).max() > 0.2
    assert np.allclose(heading[floor, :2], d[floor, :2] / 1.5, atol=1e-9)


def test_glass_that_absorbs_reflects_fresnel_and_no_more():
    """A pane of tint (0.3, 0.6, 0.9) seen at 30 degrees: a camera ray stops at it with probability 1 - (1 - F) 0.9,
    and what stops sees its mirror, which must reflect F (Cycles' glass reflects F; the rest of what does not cross
    is absorbed): the stopped rays carry F / (1 - T), so the pane reflects F on average and passes (1 - F) tint."""
    from vpl_addon.materials.microfacet import dielectric_fresnel
    tint = np.array([0.3, 0.6, 0.9])
    theta = np.radians(30.0)
    fresnel = dielectric_fresnel(np.array([np.cos(theta)]), np.array([1.5]))[0]
    k = 40000
    tracer = tracer_of(fence_scene({"transmission": 1.0, "ior": 1.5, "base_color": tuple(tint), "roughness": 0.0}))
    hits, _, _ = tracer.intersect_bent(np.tile([0.2, 0.5, 1.0], (k, 1)),
                                       np.tile([np.sin(theta), 0.0, -np.cos(theta)], (k, 1)))
    on_pane = hits.prim >= 2
    stop = 1.0 - (1.0 - fresnel) * 0.9
    assert abs(on_pane.mean() - stop) < 4.0 * np.sqrt(stop * (1.0 - stop) / k)
    assert np.allclose(hits.tint[on_pane], fresnel / stop)  # each stop: F / (1 - T), below 1
    reflected, passed = ((hits.tint * where[:, None]).mean(axis=0) for where in (on_pane, ~on_pane))
    spread = 4.0 * np.sqrt(stop * (1.0 - stop) / k)
    assert np.allclose(reflected, fresnel, atol=spread * fresnel / stop)
    assert np.allclose(passed, (1.0 - fresnel) * tint, atol=spread)
