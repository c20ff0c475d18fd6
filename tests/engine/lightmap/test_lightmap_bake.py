"""The lightmap bake without Blender: finite, non-negative texels in every pass, no light through a closed wall,
the ring around each island filled, the UV map's coverage, the VPLs shared by all objects, placed by the texels for
methods that place by the view."""
import numpy as np
import pytest

from rooms import box_faces, scene_of
from vpl_addon.core.camera import Camera, view_window
from vpl_addon.lightmap import BAKE_PASSES, LightmapSettings, bake
from vpl_addon.lightmap.dilation import dilate
from vpl_addon.lightmap.texels import rasterise
from vpl_addon.lights import PointLight
from vpl_addon.methods import MethodSettings

ROOM = ((-1.0, -1.0, 0.0), (1.0, 1.0, 2.0))


@pytest.fixture(scope="module")
def lit_room():
    return scene_of(box_faces(*ROOM), [PointLight("lamp", [0.3, 0.2, 1.5], [100.0] * 3)])


@pytest.mark.parametrize("name", BAKE_PASSES)
def test_every_texel_of_every_pass_is_finite_and_non_negative(lit_room, name):
    result = bake(lit_room, lit_room.object_names, LightmapSettings(size=24, bake_pass=name))
    assert set(result.images) == set(lit_room.object_names) and not result.warnings
    for image in result.images.values():
        assert image.shape == (24, 24, 4) and image.dtype == np.float32
        assert np.isfinite(image).all() and (image >= 0.0).all()
        assert (image[..., 3] == 1.0).all()  # each face's island is the whole map
        assert image[..., :3].mean() > 0.01  # the lamp inside lights every face, directly or not


def test_a_room_lit_from_outside_through_closed_walls_is_dark_inside():
    """One-sided walls facing in, a floor that runs out under them into the lamp's light: the texels inside the
    room get no light, neither through the walls nor along the floor's seam with them (texels outside the wall
    whose samples see its back are moved in, ``unocclude``) nor from the denoiser."""
    walls = {name: c for name, c in box_faces(*ROOM).items() if name != "floor"}
    floor = {"floor": [(-3.0, -3.0, 0.0), (3.0, -3.0, 0.0), (3.0, 3.0, 0.0), (-3.0, 3.0, 0.0)]}
    scene = scene_of({**floor, **walls}, [PointLight("sun-ish", [2.5, 0.0, 3.0], [2000.0] * 3)])
    size = 48
    result = bake(scene, scene.object_names, LightmapSettings(size=size, bake_pass="Diffuse"))
    for name in walls:
        assert result.images[name][..., :3].max() == 0.0, name
    image = result.images["floor"][::-1]  # row 0 at v = 0 from here
    centre = (np.arange(size) + 0.5) / size * 6.0 - 3.0  # the texels' x (and y) on the floor
    inside = (np.abs(centre)[:, None] < 1.0) & (np.abs(centre)[None, :] < 1.0)
    assert image[inside, :3].max() == 0.0
    assert image[~inside, :3].mean() > 0.1  # the light outside is there


def test_the_ring_around_each_island_is_filled_by_the_margin():
    scene = scene_of({"floor": box_faces(*ROOM)["floor"]}, [PointLight("lamp", [0.0, 0.0, 1.0], [100.0] * 3)],
                     island=(0.25, 0.75))
    image = bake(scene, ["floor"], LightmapSettings(size=32, margin=2, bake_pass="Diffuse Direct")).images["floor"]
    inside = np.zeros((32, 32), bool)
    inside[8:24, 8:24] = True
    ring = np.zeros((32, 32), bool)
    ring[6:26, 6:26] = True
    ring &= ~inside
    assert (image[inside, 3] == 1.0).all() and (image[~inside, 3] == 0.0).all()
    assert (image[ring, :3] > 0.0).all()
    assert (image[~(ring | inside), :3] == 0.0).all()


def test_dilation_carries_the_edge_values_outward():
    image = np.zeros((5, 5, 1))
    image[2, 2] = 4.0
    filled = np.zeros((5, 5), bool)
    filled[2, 2] = True
    out = dilate(image, filled, 1)
    assert (out[1:4, 1:4] == 4.0).all() and out[0].max() == 0.0


def test_coverage_is_the_share_of_each_texel_inside_the_uv_map():
    """One triangle over half the map: the texels below its diagonal are covered, those above empty, those on it
    in part; the covered area is the triangle's."""
    scene = scene_of({"half": [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]}, [])
    texels = rasterise(scene, np.array([0]), 16, 16, np.random.default_rng(0))
    coverage = texels.coverage.reshape(16, 16)
    assert coverage.mean() == pytest.approx(0.5, abs=0.02)
    assert coverage[0, 15] == 1.0 and coverage[15, 0] == 0.0  # (x 15, y 0) under the diagonal u > v
    assert texels.overlap == 0.0


def test_all_objects_share_one_set_of_vpls(lit_room):
    """The VPLs are placed once: baking one object or all six places the same set, and (before the denoiser,
    which sees the maps together) the same map."""
    one = bake(lit_room, ["floor"], LightmapSettings(size=16, denoise=False))
    six = bake(lit_room, lit_room.object_names, LightmapSettings(size=16, denoise=False))
    assert one.info["vpls"] == six.info["vpls"] > 0
    assert np.array_equal(one.images["floor"], six.images["floor"])


def test_bad_settings_are_refused():
    for bad in ({"size": 0}, {"size": 16385}, {"bake_pass": "Glossy"}, {"method": "vbnl"}, {"margin": -1}):
        with pytest.raises(ValueError):
            LightmapSettings(**bad)


def test_samples_inside_a_block_are_moved_out_of_it_and_the_others_stay():
    """A closed block (faces out) standing on the floor: floor samples under it within a texel of its sides (where
    a texel straddles the block's edge) see the backs of its faces and move just past the nearest one; those in
    the open keep their place (those deeper under it are dark either way: the block's faces shadow them)."""
    from vpl_addon.core.tracer import Tracer
    from vpl_addon.lightmap.unocclude import unocclude
    floor = {"floor": box_faces(*ROOM)["floor"]}
    block = {f"block {name}": c for name, c in box_faces((-0.5, -0.5, -0.1), (0.5, 0.5, 0.5), inward=False).items()}
    scene = scene_of({**floor, **block}, [])
    texels = rasterise(scene, np.array([0, 1]), 16, 1, np.random.default_rng(0))
    surface = texels.surface(scene)
    tracer = Tracer(scene.triangles)
    moved_surface, moved = unocclude(surface, texels.footprint(scene), tracer, scene.geometric_normals)
    tracer.close()
    before, after = surface.position, moved_surface.position
    side = 0.5 - np.abs(before[:, :2]).max(axis=1)  # how far inside the block's outline
    under = (side > 0.0) & (side < 0.8 * 2 / 16)
    open_floor = (np.abs(before[:, :2]) > 0.5 + 2 / 16).any(axis=1)
    assert moved[under].all() and not moved[open_floor].any()
    assert np.array_equal(after[~moved], before[~moved])
    outside = (np.abs(after[moved]) > [0.5, 0.5, 0.5]).any(axis=1) | (after[moved, 2] < -0.1)
    assert outside.all()


def test_stitching_gives_both_sides_of_a_seam_one_value():
    """A floor and a wall of one object meet along an edge that the UV map holds at two places: stitched, the
    texels across the seam differ by at most a tenth of what they differ unstitched."""
    from vpl_addon.core.scene import Materials, Scene
    from vpl_addon.lightmap.seams import seam_pairs
    from rooms import quad
    floor, floor_uv = quad([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], (0.05, 0.45))
    wall, wall_uv = quad([(1, -1, 0), (1, -1, 2), (1, 1, 2), (1, 1, 0)], (0.55, 0.95))
    scene = Scene.build(np.concatenate([floor, wall]), Materials.make([{"name": "grey", "base_color": (0.5,) * 3}]),
                        [PointLight("lamp", [0.5, 0.0, 0.3], [100.0] * 3)], scene_of(box_faces(*ROOM), []).camera,
                        uvs=np.concatenate([floor_uv, wall_uv]), material=np.ones(4), object_names=["corner"])
    size = 32
    pairs = seam_pairs(scene.triangles, scene.uvs, size)
    assert len(pairs) >= size // 2  # the shared edge, every half texel

    def seam_difference(stitched):
        settings = LightmapSettings(size=size, bake_pass="Diffuse Direct", stitch=stitched)
        image = bake(scene, ["corner"], settings).images["corner"][::-1, :, :3].reshape(-1, 3)
        return np.abs(image[pairs[:, 0]] - image[pairs[:, 1]]).mean()
    apart, stitched = seam_difference(False), seam_difference(True)
    print(f"seam difference: {apart:.4f} apart, {stitched:.4f} stitched")
    assert apart > 0.05 and stitched <= 0.1 * apart


def test_overlapping_islands_and_a_uv_map_outside_the_unit_square_are_warned_of_by_name():
    from vpl_addon.core.scene import Materials, Scene
    from rooms import quad
    floor, floor_uv = quad([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)])
    wall, wall_uv = quad([(1, -1, 0), (1, -1, 2), (1, 1, 2), (1, 1, 0)])
    tiles = np.concatenate([floor, wall])
    camera = scene_of(box_faces(*ROOM), []).camera
    grey = Materials.make([{"name": "grey", "base_color": (0.5,) * 3}])
    lamp = [PointLight("lamp", [0.0, 0.0, 1.0], [100.0] * 3)]
    stacked = Scene.build(tiles, grey, lamp, camera, uvs=np.concatenate([floor_uv, wall_uv]), material=np.ones(4),
                          object_names=["stacked"])
    warnings = bake(stacked, ["stacked"], LightmapSettings(size=8)).warnings
    assert len(warnings) == 1 and "'stacked'" in warnings[0] and "overlaps" in warnings[0]
    outside = Scene.build(tiles, grey, lamp, camera, uvs=np.concatenate([0.5 * floor_uv, 0.5 * wall_uv + 0.75]),
                          material=np.ones(4), object_names=["spilling"])
    warnings = bake(outside, ["spilling"], LightmapSettings(size=8)).warnings
    assert len(warnings) == 1 and "'spilling'" in warnings[0] and "outside [0, 1]" in warnings[0]


def test_nan_in_the_bake_uv_map_is_sanitised_and_the_maps_stay_finite(lit_room):
    """A bake UV map with NaN and infinities (a broken import) bakes as renders treat such data: zero UVs
    there, every texel finite."""
    from vpl_addon.core.scene import Scene
    uvs = lit_room.uvs.astype(np.float64)
    uvs[0, 0] = np.nan
    uvs[1, 2] = np.inf
    scene = Scene.build(lit_room.triangles, lit_room.materials, lit_room.lights, lit_room.camera,
                        uvs=lit_room.uvs, material=lit_room.material, object_id=lit_room.object_id,
                        object_names=lit_room.object_names, bake_uvs=uvs)
    assert np.isfinite(scene.bake_uvs).all()
    for image in bake(scene, scene.object_names, LightmapSettings(size=8)).images.values():
        assert np.isfinite(image).all() and (image >= 0.0).all()


@pytest.mark.parametrize("method", ["bidir", "smc"])
def test_a_method_that_places_by_the_view_places_by_the_texels(method):
    """The scene's camera looks away from the room, so its pixels see nothing: bidir's camera points and smc's
    visible points come from the baked texels instead (``lightmap.view``), and the floor's indirect light agrees
    with ir's, which ignores the view, in the mean."""
    away = np.eye(4)
    away[:3, 3] = (50.0, 50.0, 50.0)
    camera = Camera(away, 8, 8, view_window(8, 8, orthographic=True, ortho_scale=1.0), orthographic=True)
    room = scene_of(box_faces(*ROOM), [PointLight("lamp", [0.3, 0.2, 1.5], [100.0] * 3)], camera=camera)
    means = {name: bake(room, ["floor", "ceiling"], LightmapSettings(size=16, method=name, denoise=False,
                                                                     placement=MethodSettings(vpls=2048))).images
             for name in ("ir", method)}
    for face in ("floor", "ceiling"):
        ir, other = (means[name][face][..., :3].mean() for name in ("ir", method))
        assert ir > 0.0 and abs(other / ir - 1.0) < 0.15, (face, ir, other)
