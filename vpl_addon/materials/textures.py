"""Image textures as Cycles' Image Texture node reads them: bilinear (Linear) or nearest (Closest) lookups with the
node's extension (Repeat, Extend, Clip), through the UV transform of a Mapping node, and the value a material input
takes from them (``TextureMap``: colour, one channel or the alpha, times a factor). Texel rows run from the bottom
(v = 0) as in Blender images; a map may multiply in the mesh's colour attribute (Color Attribute node). Every
lookup is vectorised over all the points that use one map."""
from __future__ import annotations

import numpy as np

from ..core.color import luminance, srgb_to_linear
from ..core.sampling import interpolated
from ..core.scene import TextureMap


def _texels(i: np.ndarray, size: int, extension: str) -> tuple[np.ndarray, np.ndarray]:
    """(index into the image, whether the texel exists) for texel coordinates ``i`` under ``extension``."""
    if extension == "EXTEND":
        return np.clip(i, 0, size - 1), np.ones(i.shape, bool)
    if extension == "CLIP":
        inside = (i >= 0) & (i < size)
        return np.clip(i, 0, size - 1), inside
    return i % size, np.ones(i.shape, bool)


def sample_bilinear(texture: np.ndarray, uv: np.ndarray, extension: str = "REPEAT",
                    closest: bool = False) -> np.ndarray:
    """Values (K,C) of an (h,w,C) texture at UVs (K,2); texel centres sit at (i + 0.5) / w. Clip makes texels
    outside the image 0 (Cycles' transparent black)."""
    h, w = texture.shape[:2]
    x = uv[:, 0] * w
    y = uv[:, 1] * h
    if closest:
        (xi, xin), (yi, yin) = _texels(np.floor(x).astype(np.int64), w, extension), \
            _texels(np.floor(y).astype(np.int64), h, extension)
        return texture[yi, xi] * (xin & yin)[:, None]
    x, y = x - 0.5, y - 0.5
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    x0, y0 = x0.astype(np.int64), y0.astype(np.int64)
    (xa, ina), (xb, inb) = _texels(x0, w, extension), _texels(x0 + 1, w, extension)
    (ya, jna), (yb, jnb) = _texels(y0, h, extension), _texels(y0 + 1, h, extension)

    def texel(yi, xi, present):
        return texture[yi, xi] * present[:, None]

    top = texel(ya, xa, ina & jna) * (1 - fx) + texel(ya, xb, inb & jna) * fx
    bottom = texel(yb, xa, ina & jnb) * (1 - fx) + texel(yb, xb, inb & jnb) * fx
    return top * (1 - fy) + bottom * fy


def transformed_uv(tmap: TextureMap, uv: np.ndarray) -> np.ndarray:
    a, b, c, d, e, f = tmap.uv
    return np.stack([a * uv[:, 0] + b * uv[:, 1] + c, d * uv[:, 0] + e * uv[:, 1] + f], axis=1)


def lookup(tmap: TextureMap, textures: list[np.ndarray], uv: np.ndarray, scalar: bool,
           color: np.ndarray | None = None) -> np.ndarray:
    """What the input fed by ``tmap`` receives at UVs (K,2): (K,) for a ``scalar`` input (a channel, or the
    colour's luminance as Blender converts a colour to a float), else (K,3) (a channel repeated: a float into a
    colour input is grey). ``color`` (K,3) is the colour attribute at the points, which a ``vertex`` map
    multiplies in (its alpha is 1)."""
    if tmap.image >= 0:
        texel = sample_bilinear(textures[tmap.image], transformed_uv(tmap, uv), tmap.extension, tmap.closest)
        texel = texel.astype(np.float64)
        if tmap.srgb:  # as Cycles reads an 8-bit sRGB image: the texels blended as stored, the blend made linear
            texel[:, :3] = srgb_to_linear(texel[:, :3])
    else:
        texel = np.ones((len(uv), 4))
    if tmap.vertex:
        texel[:, :3] *= color
    factor = np.asarray(tmap.factor, np.float64)
    if tmap.channel >= 0:
        value = texel[:, tmap.channel]
        value = value * factor[0] if scalar else value[:, None] * factor
    else:
        value = texel[:, :3] * factor
        value = luminance(value) if scalar else value
    return (value >= tmap.cutoff).astype(np.float64) if tmap.cutoff >= 0.0 else value


def lowest(tmap: TextureMap, textures: list[np.ndarray]) -> float:
    """A lower bound of what ``tmap`` gives a scalar input anywhere (a bilinear lookup stays within its texels):
    its channel's least texel, or the luminance of each channel's least; 0 where a colour attribute multiplies in,
    whose colours it does not read, or where a cutoff makes it a mask."""
    if tmap.vertex or tmap.image < 0 or tmap.cutoff >= 0.0 or min(tmap.factor) < 0.0:
        return 0.0
    image = textures[tmap.image]
    least = image.reshape(-1, image.shape[-1]).min(axis=0).astype(np.float64)  # per channel, no copy of the image
    if tmap.srgb:
        least[:3] = srgb_to_linear(least[:3])
    factor = np.asarray(tmap.factor, np.float64)
    if tmap.channel >= 0:
        return float((least[tmap.channel] if tmap.channel < len(least) else 1.0) * factor[0])
    return float(luminance(least[:3] * factor))


def at_points(tmap: TextureMap, scene, prim: np.ndarray, bary: np.ndarray, scalar: bool) -> np.ndarray:
    """``lookup`` at points given as triangles ``prim`` (K,) and barycentric coordinates (K,3) of ``scene``: their
    UVs and (for a ``vertex`` map) colour attribute interpolated from the triangles' corners."""
    color = interpolated(scene.colors[prim], bary) if tmap.vertex else None
    return lookup(tmap, scene.textures, interpolated(scene.uvs[prim], bary), scalar, color)
