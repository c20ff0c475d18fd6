"""Image textures: bilinear lookup with repeat wrapping, as Cycles' Image Texture node does by default
(interpolation Linear, extension Repeat). Texel rows run from the bottom (v = 0) as in Blender images."""
from __future__ import annotations

import numpy as np


def sample_bilinear(texture: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Colours (K,C) of an (h,w,C) texture at UVs (K,2); texel centres sit at (i + 0.5) / w."""
    h, w = texture.shape[:2]
    x = uv[:, 0] * w - 0.5
    y = uv[:, 1] * h - 0.5
    x0 = np.floor(x)
    y0 = np.floor(y)
    fx = (x - x0)[:, None]
    fy = (y - y0)[:, None]
    x0 = x0.astype(np.int64) % w
    y0 = y0.astype(np.int64) % h
    x1 = (x0 + 1) % w
    y1 = (y0 + 1) % h
    top = texture[y0, x0] * (1 - fx) + texture[y0, x1] * fx
    bottom = texture[y1, x0] * (1 - fx) + texture[y1, x1] * fx
    return top * (1 - fy) + bottom * fy
