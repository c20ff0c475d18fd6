"""The camera: Blender's view-plane conventions and Cycles' pixel filter, as primary rays.

View plane (Blender ``BKE_camera_params_compute_viewplane``): the sensor dimension given by the sensor fit spans
the image along that axis; AUTO fits the sensor width to the larger image dimension; shift is a fraction of the
fitted extent. Pixel (i, j), i from the left and j from the TOP, covers [i, i+1] x [j, j+1] of the plane.

Render border (Cycles with *Render Region*): ``region`` is the rectangle of pixels that is rendered, on the full
frame's view plane, so a pixel of the region sees what the same pixel of the whole frame sees.

Pixel filter (Cycles ``scene/film.cpp``): samples are importance-sampled from the filter, each weighing 1.
Box is always one pixel wide whatever the width (measured), Blackman-Harris spans [-w, w] (Cycles evaluates it at
twice the width), Gaussian exp(-8 u^2 / w^2) is tabulated over [-1.5w, 1.5w].
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .compiled import kernel
from .sampling import normalize

FILTER_TABLE_SIZE = 1024


def view_window(width: int, height: int, *, orthographic: bool, lens: float = 50.0, sensor_width: float = 36.0,
                sensor_height: float = 24.0, sensor_fit: str = "AUTO", ortho_scale: float = 6.0,
                shift_x: float = 0.0, shift_y: float = 0.0, pixel_aspect: float = 1.0) -> tuple[float, ...]:
    """(x0, x1, y0, y1) of the image on the plane at distance 1 (perspective) or in metres (orthographic).

    ``pixel_aspect`` is Blender's pixel_aspect_y / pixel_aspect_x (1 for square pixels).
    """
    aspect_w, aspect_h = float(width), float(height) * pixel_aspect
    fit = sensor_fit
    if fit == "AUTO":
        fit = "HORIZONTAL" if aspect_w >= aspect_h else "VERTICAL"
        sensor = sensor_width
    else:
        sensor = sensor_width if fit == "HORIZONTAL" else sensor_height
    half_fit = 0.5 * ortho_scale if orthographic else 0.5 * sensor / lens
    if fit == "HORIZONTAL":
        sx, sy = half_fit, half_fit * aspect_h / aspect_w
    else:
        sx, sy = half_fit * aspect_w / aspect_h, half_fit
    cx, cy = 2.0 * half_fit * shift_x, 2.0 * half_fit * shift_y
    return (cx - sx, cx + sx, cy - sy, cy + sy)


def filter_inverse_cdf(kind: str, width: float, size: int = FILTER_TABLE_SIZE) -> np.ndarray:
    """Table mapping u in [0,1] (``size`` uniform steps) to a sub-pixel offset distributed as the filter."""
    if kind == "BOX" or width <= 0.0:
        return np.linspace(0.0, 1.0, size) - 0.5
    half = width if kind == "BLACKMAN_HARRIS" else 1.5 * width
    x = np.linspace(-half, half, 4 * size + 1)
    if kind == "BLACKMAN_HARRIS":
        t = 2.0 * np.pi * (x / (2.0 * half) + 0.5)
        f = 0.35875 - 0.48829 * np.cos(t) + 0.14128 * np.cos(2 * t) - 0.01168 * np.cos(3 * t)
    else:  # GAUSSIAN, Cycles' exp(-2 (6 v / (3w))^2)
        f = np.exp(-2.0 * (x * 6.0 / (3.0 * width)) ** 2)
    cdf = np.concatenate([[0.0], np.cumsum(0.5 * (f[1:] + f[:-1]))])
    cdf /= cdf[-1]
    return np.interp(np.linspace(0.0, 1.0, size), cdf, x)


@dataclass
class Camera:
    to_world: np.ndarray  # (4,4) camera-to-world, columns = right, up, backward (looks down -Z), position
    width: int
    height: int
    window: tuple[float, float, float, float]  # see view_window
    orthographic: bool = False
    clip_start: float = 1e-3
    clip_end: float = 1e30
    filter_type: str = "BLACKMAN_HARRIS"
    filter_width: float = 1.5
    # (x, y, width, height) of the pixels rendered, x from the left and y from the top of the frame; None: all
    region: tuple[int, int, int, int] | None = None

    def __post_init__(self):
        m = np.asarray(self.to_world, np.float64).reshape(4, 4).copy()
        for axis in range(3):  # keep only rotation and translation: object scale must not skew rays
            m[:3, axis] = normalize(m[:3, axis])
        self.to_world = m
        self.width, self.height = int(self.width), int(self.height)
        if self.region is not None:
            x, y, w, h = (int(v) for v in self.region)
            if w < 1 or h < 1 or x < 0 or y < 0 or x + w > self.width or y + h > self.height:
                raise ValueError(f"the region {w}x{h} at ({x}, {y}) is not a rectangle of pixels within the "
                                 f"{self.width}x{self.height} frame")
            self.region = (x, y, w, h)

    @property
    def pixel_region(self) -> tuple[int, int, int, int]:
        """(x, y, width, height) of the pixels rendered: the region, or the whole frame."""
        return self.region if self.region is not None else (0, 0, self.width, self.height)

    def around(self, margin: int) -> "Camera":
        """This camera with its region grown by ``margin`` pixels on every side within the frame: the pixels that a
        filter reading ``margin`` pixels away needs to filter the region as it filters the whole frame."""
        if self.region is None or margin <= 0:
            return self
        x, y, w, h = self.region
        x0, y0 = max(0, x - margin), max(0, y - margin)
        x1, y1 = min(self.width, x + w + margin), min(self.height, y + h + margin)
        return replace(self, region=(x0, y0, x1 - x0, y1 - y0))

    def frame_pixels(self, local: np.ndarray) -> np.ndarray:
        """Flat indices in the whole frame (row-major, row 0 at the top) of the region's pixels ``local`` (flat
        indices in the region, row-major)."""
        x, y, w, _ = self.pixel_region
        local = np.asarray(local, np.int64)
        return (y + local // w) * self.width + x + local % w

    @property
    def position(self) -> np.ndarray:
        return self.to_world[:3, 3]

    def filter_offsets(self, u: np.ndarray) -> np.ndarray:
        """Sub-pixel offsets from the pixel centre for uniform numbers u, distributed as the pixel filter: the
        table read linearly between its uniform steps (what ``np.interp`` gives, without its search per number:
        a fifth of the time, which was a third of the G-buffer's)."""
        table = filter_inverse_cdf(self.filter_type, self.filter_width)
        x = np.clip(np.asarray(u, np.float64), 0.0, 1.0) * (len(table) - 1)
        step = np.minimum(x.astype(np.intp), len(table) - 2)
        low = table[step]
        return low + (x - step) * (table[step + 1] - low)

    def rays(self, px: np.ndarray, py: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """World-space rays through continuous image positions (px from the left, py from the top).

        Returns origins, unit directions and the near distance (clip start measured along the optical axis).
        """
        x0, x1, y0, y1 = self.window
        sx = x0 + (x1 - x0) * (px / self.width)
        sy = y1 - (y1 - y0) * (py / self.height)
        rot, pos = self.to_world[:3, :3], self.to_world[:3, 3]
        if self.orthographic:
            local_o = np.stack([sx, sy, np.zeros_like(sx)], axis=-1)
            origins = local_o @ rot.T + pos
            dirs = np.broadcast_to(-rot[:, 2], origins.shape).copy()
            near = np.full(len(px), self.clip_start)
        else:
            dirs, length = np.empty((len(sx), 3)), np.empty(len(sx))
            _perspective(np.asarray(sx, np.float64), np.asarray(sy, np.float64), rot, dirs, length)
            origins = np.broadcast_to(pos, dirs.shape).copy()
            near = self.clip_start * length
        return origins, dirs, near


@kernel
def _perspective(sx, sy, rot, dirs, length):
    """The unit directions (``rot`` times (sx, sy, -1) over its ``length``) of a perspective camera's rays."""
    for i in range(len(sx)):
        length[i] = np.sqrt(sx[i] * sx[i] + sy[i] * sy[i] + 1.0)
        for c in range(3):
            dirs[i, c] = (rot[c, 0] * sx[i] + rot[c, 1] * sy[i] - rot[c, 2]) / length[i]
