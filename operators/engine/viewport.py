"""The 3D view's Rendered shading: what ``RenderEngine.view_update`` / ``view_draw`` do, as a ``Viewport`` that needs
no window (tests drive it through bpy with the scene's camera as the view).

``Viewport.update`` (a depsgraph change) extracts the scene seen from the view and restarts the progressive render
(``vpl_addon.progressive``) unless nothing the picture depends on changed; ``Viewport.look`` (every redraw) restarts
it when only the view moved, with the scene already extracted. Bad input met while editing (an object, light or the
view with non-finite transforms, a scene that cannot be extracted) keeps the last image and names the problem in
``status``. ``ImageTexture`` puts the latest image on the GPU and draws it over the region.
"""
from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

from ...vpl_addon.core import passes as P
from ...vpl_addon.core.camera import Camera
from ...vpl_addon.progressive import ProgressiveRenderer
from ...vpl_addon.render import Cancelled
from ...vpl_addon.sequence.motion import Motion, Snapshot
from ..scene.extract import ExtractionError, extract


def view_camera(view_matrix, window_matrix, width: int, height: int, film=None, lens: dict | None = None) -> Camera:
    """The camera of a 3D view from its view matrix (world to view) and window (projection) matrix, ``width`` x
    ``height`` pixels, with the pixel filter of ``film`` (the scene's ``vpl_gi`` settings, or the default) and the
    depth of field ``lens`` (``extract.depth_of_field``: a view through the scene's camera, as in Cycles). The
    projection gives the view plane at distance 1 (perspective) or in metres (orthographic) and the clipping
    distances; an orthographic view's rays start at its near plane, which Blender puts behind the eye."""
    view = np.array(view_matrix, np.float64).reshape(4, 4)
    p = np.array(window_matrix, np.float64).reshape(4, 4)
    to_world = np.linalg.inv(view)
    perspective = p[3, 3] == 0.0
    if perspective:
        window = ((p[0, 2] - 1) / p[0, 0], (p[0, 2] + 1) / p[0, 0], (p[1, 2] - 1) / p[1, 1], (p[1, 2] + 1) / p[1, 1])
        near, far = p[2, 3] / (p[2, 2] - 1), p[2, 3] / (p[2, 2] + 1)
    else:
        window = ((-1 - p[0, 3]) / p[0, 0], (1 - p[0, 3]) / p[0, 0], (-1 - p[1, 3]) / p[1, 1],
                  (1 - p[1, 3]) / p[1, 1])
        near, far = (p[2, 3] + 1) / p[2, 2], (p[2, 3] - 1) / p[2, 2]
        to_world[:3, 3] -= near * to_world[:3, 2] / np.linalg.norm(to_world[:3, 2])  # the eye onto the near plane
        near, far = 0.0, far - near
    extra = {} if film is None else {"filter_type": film.pixel_filter_type, "filter_width": film.filter_width}
    extra.update(lens or {})
    return Camera(to_world, max(1, int(width)), max(1, int(height)), tuple(float(v) for v in window),
                  orthographic=not perspective, clip_start=float(near), clip_end=float(far), **extra)


def nonfinite_transforms(depsgraph) -> list[str]:
    """Names of the rendered objects (geometry, lights, the camera) whose transform has non-finite values."""
    names = []
    for inst in depsgraph.object_instances:
        if inst.object.type != "EMPTY" and not np.isfinite(np.array(inst.matrix_world)).all():
            names.append(inst.object.name)
    return sorted(set(names))


def _key(camera: Camera) -> bytes:
    """What of a camera changes the picture, as bytes to compare."""
    return np.concatenate([camera.to_world.ravel(), camera.window, [camera.width, camera.height,
                           camera.orthographic, camera.clip_start, camera.clip_end, *camera.optics]]).tobytes()


class Viewport:
    """The progressive render of one 3D view: ``update`` on depsgraph changes, ``look`` on redraws, ``frame`` and
    ``status`` to draw. ``passes``: what each image holds besides Combined (tests ask for Diffuse Indirect)."""

    def __init__(self, passes: tuple[str, ...] = (P.COMBINED,)):
        self.renderer = ProgressiveRenderer()
        self.passes = passes
        self.scene = None  # the scene last rendered (extracted), its settings and viewport settings
        self._settings = None
        self._problem = ""  # why the last change was not rendered
        self._warnings: list[str] = []  # what extraction said of the scene rendered

    @property
    def frame(self):
        return self.renderer.frame

    @property
    def status(self) -> str:
        warnings = self._warnings + self.renderer.warnings
        return "; ".join([self._problem or self.renderer.status] + warnings)

    @property
    def busy(self) -> bool:
        return self.renderer.busy

    def update(self, depsgraph, camera: Camera) -> bool:
        """The scene of ``depsgraph`` changed (or its settings did): render it from ``camera`` if anything the
        picture depends on changed. True if a render started; with bad input the last image stays."""
        broken = nonfinite_transforms(depsgraph)
        if broken:
            return self._refuse(f"{', '.join(repr(name) for name in broken)}: non-finite transform (location, "
                                f"rotation or scale); showing the last image")
        if not np.isfinite(camera.to_world).all() or not np.isfinite(camera.window).all():
            return self._refuse("the view has a non-finite transform; showing the last image")
        try:
            scene, warnings = extract(depsgraph, lambda text: True, camera=camera)
        except (ExtractionError, Cancelled) as err:
            return self._refuse(f"{err}; showing the last image")
        except Exception as err:  # a bug: the viewport keeps going, the status line says what failed
            return self._refuse(" ".join(f"scene extraction failed ({type(err).__name__}: {err}); please "
                                         f"report".split()))
        props = depsgraph.scene.vpl_gi
        settings = (props.render_settings(self.passes), props.viewport_settings())
        if self.scene is not None and settings == self._settings and not self._problem and \
                Motion.between(Snapshot.of(self.scene), Snapshot.of(scene)).static():
            return False  # selection and other changes that render the same picture
        self._problem = ""
        self.scene, self._settings = scene, settings
        self._warnings = warnings
        self.renderer.start(scene, *settings, passes=self.passes)
        return True

    def look(self, camera: Camera) -> bool:
        """Render from ``camera`` if the view changed since the last render (the scene as last extracted). True
        if a render started."""
        if self.scene is None or _key(camera) == _key(self.scene.camera):
            return False
        if not np.isfinite(camera.to_world).all() or not np.isfinite(camera.window).all():
            return self._refuse("the view has a non-finite transform; showing the last image")
        self.scene = replace(self.scene, camera=camera)
        self.renderer.start(self.scene, *self._settings, passes=self.passes)
        return True

    def next_frame(self, after=None, step: str | None = None, timeout: float = 120.0):
        """The first image newer than ``after`` (and made by ``step``, "preview" or "refine"), waiting up to
        ``timeout`` seconds for it; None if none came. How a headless driver (tests, bench/viewport.py) follows
        the refinement that ``view_draw`` polls."""
        end = time.perf_counter() + timeout
        while time.perf_counter() < end:
            frame = self.frame
            if frame is not None and (after is None or frame.number > after.number) and step in (None, frame.step):
                return frame
            time.sleep(0.002)
        return None

    def _refuse(self, problem: str) -> bool:
        self._problem = problem
        return False

    def close(self) -> None:
        self.renderer.close()


class ImageTexture:
    """The latest image as a GPU texture (uploaded once per image), drawn over ``width`` x ``height`` pixels of the
    current framebuffer from its lower left corner: the region in ``view_draw``, whose matrices map pixels."""

    def __init__(self):
        self.number = None
        self.texture = None

    def draw(self, frame, width: int, height: int) -> None:
        import gpu
        from gpu_extras.presets import draw_texture_2d
        if frame.number != self.number:
            rgba = np.ascontiguousarray(frame.combined[::-1], np.float32)  # the GPU's rows go up
            buffer = gpu.types.Buffer("FLOAT", rgba.size, rgba.ravel())
            self.texture = gpu.types.GPUTexture((rgba.shape[1], rgba.shape[0]), format="RGBA32F", data=buffer)
            self.number = frame.number
        draw_texture_2d(self.texture, (0, 0), width, height)
