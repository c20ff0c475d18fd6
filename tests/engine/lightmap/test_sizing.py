"""Map sizes from a texel density (``lightmap.sizing``), and maps of different sizes baked and denoised together."""
import numpy as np
import pytest

from rooms import scene_of
from vpl_addon.lightmap import LightmapSettings, bake
from vpl_addon.lightmap.denoising import _shelves
from vpl_addon.lightmap.sizing import MIN_SIZE, density_size
from vpl_addon.lights import PointLight


def _floors():
    """A 4 m x 4 m floor and a 1 m x 1 m tile above it, each UV-mapped to its whole map."""
    return scene_of({"floor": [(-2, -2, 0), (2, -2, 0), (2, 2, 0), (-2, 2, 0)],
                     "tile": [(0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]},
                    [PointLight("lamp", [0.0, 0.0, 3.0], [100.0] * 3)])


def test_a_metre_spans_the_density_in_texels_rounded_to_a_power_of_two():
    scene = _floors()
    floor, tile = np.arange(2), np.arange(2, 4)
    uv = scene.uvs
    assert density_size(scene, floor, uv[floor], 16.0, 16384) == 64  # 4 m at 16 a metre
    assert density_size(scene, tile, uv[tile], 16.0, 16384) == 16
    assert density_size(scene, tile, uv[tile] * 0.5, 16.0, 16384) == 32  # the island a quarter of the map
    assert density_size(scene, tile, uv[tile], 20.0, 16384) == 16  # 20 is nearer 16 than 32
    assert density_size(scene, floor, uv[floor], 1e6, 8192) == 8192
    assert density_size(scene, tile, np.zeros_like(uv[tile]), 16.0, 16384) == MIN_SIZE  # no UV area


def test_objects_of_one_density_get_their_own_sizes_and_are_denoised_together():
    scene = _floors()
    result = bake(scene, ["floor", "tile"], LightmapSettings(texel_density=8.0, bake_pass="Diffuse"))
    assert result.images["floor"].shape == (32, 32, 4) and result.images["tile"].shape == (8, 8, 4)
    for image in result.images.values():
        assert np.isfinite(image).all() and (image >= 0).all() and image[..., :3].mean() > 0.0


def test_shelves_hold_every_tile_without_overlap():
    tiles = [64, 16, 16, 48, 8, 64, 32]
    corners, (height, width) = _shelves(tiles)
    used = np.zeros((height, width), int)
    for (y, x), tile in zip(corners, tiles):
        used[y:y + tile, x:x + tile] += 1
    assert used.max() == 1 and used.sum() == sum(t * t for t in tiles)
    assert _shelves([10] * 7) == ([(0, 0), (0, 10), (0, 20), (10, 0), (10, 10), (10, 20), (20, 0)], (30, 30))


@pytest.mark.parametrize("density", [0.0, -1.0, float("inf"), float("nan")])
def test_a_density_that_is_not_a_positive_number_is_refused(density):
    with pytest.raises(ValueError, match="texel density"):
        LightmapSettings(texel_density=density)
