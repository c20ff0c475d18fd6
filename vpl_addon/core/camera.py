"""The camera: Blender's view-plane conventions and Cycles' pixel filter, as primary rays.

View plane (Blender ``BKE_camera_params_compute_viewplane``): the sensor dimension given by the sensor fit spans
the image along that axis; AUTO fits the sensor width to the larger image dimension; shift is a fraction of the
fitted extent. Pixel (i, j), i from the left and j from the TOP, covers [i, i+1] x [j, j+1] of the plane.

Render border (Cycles with *Render Region*): ``region`` is the rectangle of pixels that is rendered, on the full
frame's view plane, so a pixel of the region sees what the same pixel of the whole frame sees.

Depth of field (Cycles ``kernel/camera/camera.h``): a thin lens of radius ``aperture`` (Cycles' aperture size,
focal length / (2 f-stop), or 1 / (2 f-stop) for an orthographic camera) focused at ``focus`` metres along the view
axis. A ray leaves from a point of the aperture (a disc, or a regular polygon of ``blades`` corners turned by
``blade_rotation``, squeezed across by ``aperture_ratio``) toward the point of the plane of focus its pinhole ray
meets, so what lies on that plane stays sharp.

Pixel filter (Cycles ``scene/film.cpp``): samples are importance-sampled from the filter, each weighing 1.
Box is always one pixel wide whatever the width (measured), Blackman-Harris spans [-w, w] (Cycles evaluates it at
twice the width), Gaussian exp(-8 u^2 / w^2) is tabulated over [-1.5w, 1.5w].
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .compiled import kernel
from .sampling import concentric_disk, normalize

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
    aperture: float = 0.0  # radius of the lens in metres (0: a pinhole, everything in focus)
    focus: float = 10.0  # distance of the plane of focus along the view axis
    blades: int = 0  # corners of the aperture (fewer than 3: a disc)
    blade_rotation: float = 0.0  # radians
    aperture_ratio: float = 1.0  # anamorphic squeeze: the aperture's height over its width

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
        if not np.isfinite(self.optics).all() or self.aperture < 0.0 or self.aperture_ratio <= 0.0:
            raise ValueError(f"the camera's depth of field needs a finite aperture >= 0 and ratio > 0 (got aperture "
                             f"{self.aperture}, focus {self.focus}, ratio {self.aperture_ratio})")
        self.focus = max(float(self.focus), 1e-5)  # as Cycles clamps it

    @property
    def optics(self) -> tuple[float, ...]:
        """The lens's settings (aperture, focus, blades, blade rotation, ratio): what of depth of field changes
        the picture."""
        return (self.aperture, self.focus, self.blades, self.blade_rotation, self.aperture_ratio)

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
        a fifth of its time; with ``np.interp`` the lookup takes a third of the G-buffer's)."""
        table = filter_inverse_cdf(self.filter_type, self.filter_width)
        x = np.clip(np.asarray(u, np.float64), 0.0, 1.0) * (len(table) - 1)
        step = np.minimum(x.astype(np.intp), len(table) - 2)
        low = table[step]
        return low + (x - step) * (table[step + 1] - low)

    def rays(self, px: np.ndarray, py: np.ndarray, lens: tuple[np.ndarray, np.ndarray] | None = None
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """World-space rays through continuous image positions (px from the left, py from the top); ``lens``: two
        arrays of uniform numbers, the point of the aperture each ray leaves from (ignored for a pinhole; without
        them every ray leaves from the lens's centre, in focus everywhere).

        Returns origins, unit directions and the near distance (clip start measured along the optical axis).
        """
        x0, x1, y0, y1 = self.window
        sx = x0 + (x1 - x0) * (px / self.width)
        sy = y1 - (y1 - y0) * (py / self.height)
        rot, pos = self.to_world[:3, :3], self.to_world[:3, 3]
        if self.orthographic:
            local_o = np.stack([sx, sy, np.zeros_like(sx)], axis=-1)
            dirs = np.broadcast_to(-rot[:, 2], local_o.shape).copy()
            near = np.full(len(px), self.clip_start)
        else:
            dirs, length = np.empty((len(sx), 3)), np.empty(len(sx))
            _perspective(np.asarray(sx, np.float64), np.asarray(sy, np.float64), rot, dirs, length)
            local_o = np.zeros((len(sx), 3))
            near = self.clip_start * length
        if self.aperture > 0.0 and lens is not None:
            # the lens point, and the point of the plane of focus (local z = -focus) the pinhole ray meets
            lx, ly = self.aperture_points(*lens)
            focal = np.stack([sx, sy, -np.ones_like(sx)], axis=-1) * self.focus
            if self.orthographic:
                focal[:, :2] = 0.0
            local_d = normalize(focal - np.stack([lx, ly, np.zeros_like(lx)], axis=-1))
            local_o[:, 0] += lx
            local_o[:, 1] += ly
            dirs = local_d @ rot.T
            if self.orthographic:  # the clip plane stays a plane
                near = self.clip_start / -local_d[:, 2]
        return local_o @ rot.T + pos, dirs, near

    def aperture_points(self, u1: np.ndarray, u2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(x, y) in metres on the lens, uniform over the aperture for uniform numbers (u1, u2): a disc (Shirley and
        Chiu's map), or with ``blades`` >= 3 the regular polygon of that many corners on the disc's rim, the first
        at ``blade_rotation`` + pi / blades, drawn as one of its triangles about the centre and a uniform point in
        it; x divided by ``aperture_ratio`` (Cycles' anamorphic bokeh)."""
        u1, u2 = np.asarray(u1, np.float64), np.asarray(u2, np.float64)
        if self.blades < 3:
            x, y = concentric_disk(u1, u2)
        else:
            n = self.blades
            corner = np.minimum(np.floor(u1 * n), n - 1)
            a = np.sqrt(u1 * n - corner)  # uniform in the triangle (centre, corner k, corner k + 1)
            b = u2 * a
            half = np.pi / n
            px, py = a * np.cos(half), (2.0 * b - a) * np.sin(half)
            turn = self.blade_rotation + corner * 2.0 * half
            x, y = np.cos(turn) * px - np.sin(turn) * py, np.sin(turn) * px + np.cos(turn) * py
        return x * self.aperture / self.aperture_ratio, y * self.aperture


@kernel
def _perspective(sx, sy, rot, dirs, length):
    """The unit directions (``rot`` times (sx, sy, -1) over its ``length``) of a perspective camera's rays."""
    for i in range(len(sx)):
        length[i] = np.sqrt(sx[i] * sx[i] + sy[i] * sy[i] + 1.0)
        for c in range(3):
            dirs[i, c] = (rot[c, 0] * sx[i] + rot[c, 1] * sy[i] - rot[c, 2]) / length[i]
