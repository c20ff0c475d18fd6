"""Image textures on material inputs (engine side): lookups with Blender's extension and interpolation modes, the
value an input takes from a map (channel, factor, luminance, UV transform), normal maps in tangent space, and broken
maps that fall back to the input's value."""
import math

import numpy as np
import pytest

from vpl_addon.core.camera import Camera, view_window
from vpl_addon.core.scene import Materials, Scene, TextureMap
from vpl_addon.core.tracer import Tracer
from vpl_addon.materials.surface import shade
from vpl_addon.materials.textures import lookup, sample_bilinear

CAM = Camera(np.eye(4), 8, 8, view_window(8, 8, orthographic=False))
QUAD = np.array([[[0, 0, 0], [1, 0, 0], [1, 1, 0]], [[0, 0, 0], [1, 1, 0], [0, 1, 0]]], float)
QUAD_UV = np.array([[[0, 0], [1, 0], [1, 1]], [[0, 0], [1, 1], [0, 1]]], float)


def shaded(scene, xy, down=(0.0, 0.0, -1.0)):
    """The surface found by rays from above at points ``xy`` of the unit quad."""
    origins = np.column_stack([xy, np.full(len(xy), 1.0)])
    dirs = np.tile(np.asarray(down, float), (len(xy), 1))
    hits = Tracer(scene.triangles).intersect(origins, dirs)
    assert hits.hit.all()
    return shade(scene, dirs, hits, np.arange(len(xy)))


def test_bilinear_texture_lookup_repeats_and_interpolates():
    tex = np.zeros((2, 2, 3), np.float32)
    tex[0, 0] = 1.0  # bottom-left texel
    assert np.allclose(sample_bilinear(tex, np.array([[0.25, 0.25]])), 1.0)  # its centre
    assert np.allclose(sample_bilinear(tex, np.array([[1.25, -0.75]])), 1.0)  # repeated
    assert np.allclose(sample_bilinear(tex, np.array([[0.5, 0.25]])), 0.5)  # halfway to the next texel


def test_extension_and_interpolation_modes():
    tex = np.zeros((2, 2, 3), np.float32)
    tex[0, 0] = 1.0  # bottom-left texel
    uv = np.array([[-0.25, 0.25], [0.1, 0.1], [0.5, 0.25]])
    assert np.allclose(sample_bilinear(tex, uv[:1], "EXTEND"), 1.0)  # the edge texel goes on
    assert np.allclose(sample_bilinear(tex, uv[:1], "REPEAT"), 0.0)  # the right column comes round
    assert np.allclose(sample_bilinear(tex, uv[1:2], "CLIP"), 1.0 * (0.7 * 0.7))  # fades into black outside
    assert np.allclose(sample_bilinear(tex, uv[2:], closest=True), 0.0)  # the texel to the right, not a blend
    assert np.allclose(sample_bilinear(tex, np.array([[0.49, 0.25]]), closest=True), 1.0)


def test_a_map_gives_a_channel_a_factor_or_the_luminance_through_its_uv_transform():
    tex = np.zeros((1, 2, 4), np.float32)
    tex[0, 0] = [0.2, 0.4, 0.6, 0.5]
    tex[0, 1] = [1.0, 1.0, 1.0, 1.0]
    left = np.array([[0.25, 0.5]])
    assert lookup(TextureMap(0, 1, (0.5, 0.5, 0.5)), [tex], left, scalar=True) == pytest.approx(0.2)  # G x 0.5
    assert lookup(TextureMap(0, 3), [tex], left, scalar=True) == pytest.approx(0.5)  # the alpha
    assert lookup(TextureMap(0), [tex], left, scalar=True) == pytest.approx(0.2126 * 0.2 + 0.7152 * 0.4 +
                                                                            0.0722 * 0.6)
    assert np.allclose(lookup(TextureMap(0, 2), [tex], left, scalar=False), 0.6)  # a float into a colour: grey
    assert np.allclose(lookup(TextureMap(0, -1, (1, 2, 0)), [tex], left, scalar=False), [0.2, 0.8, 0])
    shifted = TextureMap(0, uv=(1.0, 0.0, 0.5, 0.0, 1.0, 0.0))  # u + 0.5: the right texel
    assert np.allclose(lookup(shifted, [tex], left, scalar=False), 1.0)


def test_textured_roughness_metallic_and_base_colour_reach_the_surface():
    image = np.zeros((1, 2, 3), np.float32)
    image[0, 0] = [0.9, 0.25, 1.0]  # glTF metallic-roughness: G roughness, B metallic
    image[0, 1] = [0.9, 0.75, 0.0]
    colour = np.full((1, 1, 3), 0.5, np.float32)
    mat = Materials.make([{"name": "gltf", "roughness": 1.0, "metallic": 0.0,
                           "maps": {"roughness": TextureMap(0, 1), "metallic": TextureMap(0, 2),
                                    "base_color": TextureMap(1, -1, (1.0, 0.5, 0.0))}}])
    scene = Scene.build(QUAD, mat, [], CAM, uvs=QUAD_UV, material=[1, 1], textures=[image, colour])
    s = shaded(scene, np.array([[0.25, 0.6], [0.75, 0.6]]))
    assert np.allclose(s.roughness, [0.25, 0.75], atol=1e-6)
    assert np.allclose(s.metallic, [1.0, 0.0], atol=1e-6)
    assert np.allclose(s.specular, [[0.5, 0.25, 0.0]] * 2)  # the metal's F0 is the textured base colour
    # the metal's metallic comes out of float32 filtering as 1 - 6e-8 on some CPUs: albedo 1e-8, not 0
    assert np.allclose(s.albedo[1], [0.5, 0.25, 0.0]) and np.allclose(s.albedo[0], 0.0, atol=1e-6)


@pytest.mark.parametrize("mirrored", [False, True])
def test_a_normal_map_tilts_the_shading_normal_toward_the_tangent(mirrored):
    angle = math.radians(30)
    texel = np.array([0.5 + 0.5 * math.sin(angle), 0.5, 0.5 + 0.5 * math.cos(angle)], np.float32)
    uvs = QUAD_UV.copy()
    if mirrored:
        uvs[..., 0] = 1.0 - uvs[..., 0]  # u runs along -x: the tangent points to -x
    rows = []
    for strength in (1.0, 0.0, 0.5):
        rows.append({"name": f"bumpy {strength}", "maps": {"normal": TextureMap(0, strength=strength)}})
    normals = []
    for i in range(3):
        scene = Scene.build(QUAD, Materials.make(rows), [], CAM, uvs=uvs, material=[i + 1] * 2,
                            textures=[np.tile(texel, (1, 1, 1))])
        normals.append(shaded(scene, np.array([[0.6, 0.3]])).shading_normal[0])
    side = -1.0 if mirrored else 1.0
    assert np.allclose(normals[0], [side * math.sin(angle), 0.0, math.cos(angle)], atol=1e-5)
    assert np.allclose(normals[1], [0.0, 0.0, 1.0], atol=1e-6)  # strength 0: the plain normal
    half = np.array([side * math.sin(angle), 0.0, 1 + math.cos(angle)])  # N + (N' - N) / 2, up to length
    assert np.allclose(normals[2], half / np.linalg.norm(half), atol=1e-5)


def test_a_normal_map_seen_from_behind_is_turned_with_the_surface():
    angle = math.radians(20)
    texel = np.array([0.5 + 0.5 * math.sin(angle), 0.5, 0.5 + 0.5 * math.cos(angle)], np.float32)
    scene = Scene.build(QUAD, Materials.make([{"name": "n", "maps": {"normal": TextureMap(0)}}]), [], CAM,
                        uvs=QUAD_UV, material=[1, 1], textures=[np.tile(texel, (1, 1, 1))])
    origins = np.array([[0.6, 0.3, -1.0]])
    dirs = np.array([[0.0, 0.0, 1.0]])
    hits = Tracer(scene.triangles).intersect(origins, dirs)
    s = shade(scene, dirs, hits, np.arange(1))
    assert np.allclose(s.shading_normal[0], [-math.sin(angle), 0.0, -math.cos(angle)], atol=1e-5)
    assert np.allclose(s.geometric_normal[0], [0, 0, -1])


def test_given_tangents_are_used_and_bad_ones_are_made_from_uvs():
    given = np.zeros((2, 3, 4))
    given[..., :3] = [0.0, 1.0, 0.0]  # a tangent along +y, as a mesh's own tangents may say
    given[..., 3] = 1.0
    given[1] = np.nan  # the second triangle's are broken: made from its UVs (+x)
    scene = Scene.build(QUAD, Materials.make([{"name": "n", "maps": {"normal": TextureMap(0)}}]), [], CAM,
                        uvs=QUAD_UV, material=[1, 1], textures=[np.ones((1, 1, 3), np.float32)],
                        tangents=given)
    assert np.allclose(scene.tangents[0, :, :3], [0, 1, 0]) and np.allclose(scene.tangents[1, :, :3], [1, 0, 0])
    assert np.isfinite(scene.tangents).all()


def test_broken_maps_leave_the_input_its_value():
    rows = [{"name": "missing image", "roughness": 0.3, "maps": {"roughness": TextureMap(5, 1)}},
            {"name": "no alpha channel", "roughness": 0.4, "maps": {"roughness": TextureMap(0, 3)}},
            {"name": "empty image", "roughness": 0.6, "maps": {"roughness": TextureMap(1, 0)}}]
    nan_image = np.array([[[np.nan, np.inf, -1.0]]], np.float32)
    scene = Scene.build(np.concatenate([QUAD, QUAD + [0, 0, -1]]), Materials.make(rows), [], CAM,
                        uvs=np.concatenate([QUAD_UV] * 2), material=[1, 2, 3, 3],
                        textures=[nan_image, np.zeros((0, 0, 3), np.float32)])
    assert (scene.materials.mapped("roughness")[1:] == -1).all()
    assert np.isfinite(scene.textures[0]).all() and (scene.textures[0] >= 0).all()
    with pytest.raises(ValueError, match="no input 'sheen'"):
        Materials.make([{"name": "x", "maps": {"sheen": TextureMap(0)}}])


def test_an_emission_map_lights_the_scene_with_its_mean_over_each_triangle():
    from vpl_addon.lights.emissive import EmissiveTriangles
    half = np.array([[[0.0, 0.0, 0.0], [4.0, 4.0, 4.0]]], np.float32)  # u < 0.5 dark, u > 0.5 glows
    rows = [{"name": "glow", "emission": (9.0, 9.0, 9.0), "maps": {"emission": TextureMap(0, closest=True)}}]
    light = EmissiveTriangles.from_scene(Scene.build(QUAD, Materials.make(rows), [], CAM, uvs=QUAD_UV,
                                                     material=[1, 1], textures=[half]))
    # below the diagonal three quarters of the triangle has u > 0.5, above it one quarter
    assert np.allclose(light.radiance[:, 0], [4.0 * 0.75, 4.0 * 0.25], atol=0.5)
    dark = Scene.build(QUAD, Materials.make(rows), [], CAM, uvs=QUAD_UV, material=[1, 1], textures=[half * 0.0])
    assert EmissiveTriangles.from_scene(dark) is None  # a black texture is no light, whatever the colour's value
