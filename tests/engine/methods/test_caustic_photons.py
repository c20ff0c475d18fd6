"""Caustic photons aimed at the sharp glossy surfaces (``methods.vbnl.caustic_photons``), without Blender: a small metal
plate under a low sun over a wide floor, which few of the sun's scene-wide light paths meet."""
import numpy as np
import pytest

from vpl_addon.core.camera import Camera, view_window
from vpl_addon.core.scene import Materials, Scene, TextureMap
from vpl_addon.core.tracer import Tracer
from vpl_addon.lights.light_set import LightSet
from vpl_addon.lights.sun import SunLight
from vpl_addon.materials.textures import lookup, lowest
from vpl_addon.methods.vbnl.caustic_photons import aimed_lights, distant_caustics, sharp_bounds, trace_caustic_photons
from vpl_addon.paths.light_paths import SHARP, trace_paths

PATHS = 1 << 16


def plate_scene(roughness=0.5 * SHARP, roof=False, glass=False, maps=None, textures=()):
    """A 0.4 m metal plate (``roughness``) tilted toward a low sun, 0.4-0.8 m over a 4 m floor; ``roof``: a
    slab at 3 m between them and the sun (40 m wide: the sun is 17 degrees high)."""
    normal = np.array([-2.0, 0.0, -1.0]) / np.sqrt(5.0)
    side, up = np.array([0.0, 0.2, 0.0]), 0.2 * np.array([-1.0, 0.0, 2.0]) / np.sqrt(5.0)
    centre = np.array([0.5, 0.0, 0.6])
    a, b, c, d = centre - side - up, centre + side - up, centre + side + up, centre - side + up
    plate = [[a, b, c], [a, c, d]] if np.cross(b - a, c - a) @ normal > 0 else [[a, c, b], [a, d, c]]
    quads = [[[-2, -2, 0], [2, -2, 0], [2, 2, 0]], [[-2, -2, 0], [2, 2, 0], [-2, 2, 0]], *plate]
    material = [1, 1, 2, 2]
    if roof:
        quads += [[[-20, -20, 3], [20, 20, 3], [20, -20, 3]], [[-20, -20, 3], [-20, 20, 3], [20, 20, 3]]]
        material += [1, 1]
    metal = {"name": "metal", "base_color": (0.95, 0.9, 0.8), "metallic": 0.0 if glass else 1.0,
             "roughness": roughness, "transmission": 1.0 if glass else 0.0, "maps": maps or {}}
    materials = Materials.make([{"name": "white", "base_color": (0.8, 0.8, 0.8)}, metal])
    cam = Camera(np.eye(4), 8, 8, view_window(8, 8, orthographic=True, ortho_scale=3.0), orthographic=True)
    uvs = np.zeros((len(quads), 3, 2))
    return Scene.build(np.array(quads, float), materials, [SunLight("sun", [1.0, 0.0, -0.3], [3.0] * 3)], cam,
                       material=material, uvs=uvs, textures=list(textures))


def test_aimed_paths_carry_the_distant_lights_caustic_in_a_hundred_times_the_photons():
    """The same caustic light in total as the sun's own light paths (which 4x as many paths estimate to about
    3 %), in about (floor's disc / plate's disc) times the photons per path; the plate's sphere holds its corners."""
    scene = plate_scene()
    lights, tracer = LightSet(scene), Tracer(scene.triangles)
    centre, radius = sharp_bounds(scene)
    corners = scene.triangles[2:].reshape(-1, 3)
    assert np.linalg.norm(corners - centre, axis=1).max() == pytest.approx(radius) and radius < 0.3
    own = trace_paths(scene, tracer, lights, 4 * PATHS, np.random.default_rng(0), 8)
    aimed = trace_caustic_photons(scene, tracer, aimed_lights(scene, lights), PATHS, np.random.default_rng(1))
    assert aimed.caustic.all(axis=1).all() and not aimed.intensity.any()  # caustic photons alone
    theirs, ours = own.caustic.sum(axis=0) / (4 * PATHS), aimed.caustic.sum(axis=0) / PATHS
    np.testing.assert_allclose(ours, theirs, rtol=0.1)
    assert len(aimed) > 20 * own.caustic.any(axis=1).sum() / 4  # measured: 103 times
    assert aimed_lights(scene, lights, share=1.0 / 16) is not None and aimed_lights(scene, lights, 1.0 / 64) is None


def test_light_paths_leave_aimed_lights_caustics_to_the_aimed_paths():
    """With the sun's caustics aimed, its own light paths leave none, and the same VPLs otherwise."""
    scene = plate_scene()
    lights, tracer = LightSet(scene), Tracer(scene.triangles)
    caustics = distant_caustics(lights, aimed_lights(scene, lights))
    assert not caustics.any()
    both = [trace_paths(scene, tracer, lights, PATHS, np.random.default_rng(2), 8, caustics=c) for c in
            (None, caustics)]
    assert both[0].caustic.any() and not both[1].caustic.any()
    np.testing.assert_array_equal(both[0].intensity, both[1].intensity)
    assert distant_caustics(lights, None) is None


def test_aimed_paths_start_outside_the_scene_so_a_roof_shades_the_plate():
    """A roof between the sun and the plate: no caustic photon, though the aimed paths start at the plate's disc."""
    scene = plate_scene(roof=True)
    lights = LightSet(scene)
    aimed = trace_caustic_photons(scene, Tracer(scene.triangles), aimed_lights(scene, lights), PATHS,
                                  np.random.default_rng(3))
    assert len(aimed) == 0


@pytest.mark.parametrize("case", ["rough", "glass", "rough map"])
def test_no_sharp_surface_no_aimed_lights(case):
    """A plate of Roughness above SHARP, a glass pane (thin glass: no glossy lobe the paths take) or a roughness map
    whose least texel is above SHARP gives nothing to aim at; a map reaching below it does."""
    if case == "rough map":
        image = np.full((4, 4, 4), 0.5, np.float32)
        maps = {"roughness": TextureMap(0, channel=1)}
        assert sharp_bounds(plate_scene(roughness=0.5, maps=maps, textures=[image])) is None
        image[1, 2, 1] = 0.5 * SHARP
        assert sharp_bounds(plate_scene(roughness=0.5, maps=maps, textures=[image])) is not None
        return
    scene = plate_scene(roughness=2.0 * SHARP) if case == "rough" else plate_scene(glass=True)
    assert sharp_bounds(scene) is None and aimed_lights(scene, LightSet(scene)) is None


def test_the_lowest_value_of_a_map_bounds_every_lookup():
    """``lowest``: a roughness map's least texel times its factor, the luminance of each channel's least for a
    colour, 0 with a colour attribute or a cutoff; no lookup anywhere falls below it."""
    rng = np.random.default_rng(3)
    image = np.concatenate([rng.uniform(0.25, 0.85, (16, 16, 3)), np.ones((16, 16, 1))], axis=2).astype(np.float32)
    uv = rng.random((5000, 2))
    for tmap in (TextureMap(0, channel=1, factor=(0.5, 0.5, 0.5)), TextureMap(0), TextureMap(0, srgb=True)):
        bound = lowest(tmap, [image])
        assert lookup(tmap, [image], uv, scalar=True).min() >= bound - 1e-7
        assert bound > 0.0
    assert lowest(TextureMap(0, channel=1, factor=(0.5, 0.5, 0.5)), [image]) == pytest.approx(0.5 * image[..., 1].min())
    assert lowest(TextureMap(0, vertex=True), [image]) == 0.0
    assert lowest(TextureMap(0, channel=1, cutoff=0.5), [image]) == 0.0
