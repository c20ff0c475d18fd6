"""The compiled kernels made ready before the first render needs them.

numba compiles a kernel at its first call for the argument types of that call, and keeps the machine code in the
user's cache folder (``core.compiled``): the first render after an install would spend most of its time compiling
(25 s of a 27 s Cornell box), every later one loads or reuses the code. ``Precompile`` renders a tiny scene that
calls the kernels a frame calls (every light type, a glossy and a textured material, every method, the data passes)
with the argument types a real frame passes, so compiling happens once per machine, Python and package name, and in
every later session only loading from the cache, before the user presses F12. Blender starts it on a background
thread at registration (``start``), and a render waits for its method's kernels, saying so in the status line
(``wait``). The thread calls the kernels as a render does, so numba's compile lock would make a render that does
not wait wait for a kernel being compiled instead of compiling it again.
"""
from __future__ import annotations

import atexit
import threading
import time
from contextlib import contextmanager

import numpy as np

from .core import passes as P
from .core.camera import Camera, view_window
from .core.scene import Materials, Scene, TextureMap
from .lights.area import AreaLight
from .lights.point import PointLight, SpotLight
from .lights.sun import SunLight
from .methods import METHODS, MethodSettings
from .render import Cancelled, RenderSettings, render

SIZE = 12  # pixels on a side of the tiny scene's frame
PASSES = (*P.ALL, *P.DATA, *P.DENOISING)


def _quad(a, b, c, d) -> list:
    return [[a, b, c], [a, c, d]]


def tiny_scene() -> Scene:
    """A box open to the camera, lit by one light of every kind: diffuse walls, a glossy floor and a textured back."""
    corners = np.array([[x, y, z] for z in (0.0, 2.0) for y in (-1.0, 1.0) for x in (-1.0, 1.0)])
    c = corners.tolist()
    walls = [_quad(c[0], c[1], c[3], c[2]), _quad(c[4], c[6], c[7], c[5]), _quad(c[0], c[2], c[6], c[4]),
             _quad(c[1], c[5], c[7], c[3]), _quad(c[2], c[3], c[7], c[6])]
    triangles = np.array([t for wall in walls for t in wall], float)
    material = np.repeat([1, 2, 2, 3, 4], 2)
    uvs = np.tile([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]], (len(triangles), 1, 1))
    materials = Materials.make([
        {"name": "glossy", "base_color": (0.7, 0.7, 0.7), "metallic": 1.0, "roughness": 0.3},
        {"name": "white", "base_color": (0.8, 0.8, 0.8), "specular": 0.5},
        {"name": "red", "base_color": (0.8, 0.1, 0.1)},
        {"name": "texture", "maps": {"base_color": TextureMap(0)}},
    ])
    texture = np.random.default_rng(0).random((4, 4, 3)).astype(np.float32)
    lights = [AreaLight("area", [0.0, 0.0, 1.95], [0.5, 0.0, 0.0], [0.0, 0.5, 0.0], [0.0, 0.0, -1.0], [20.0] * 3),
              PointLight("point", [0.5, -0.5, 1.0], [10.0] * 3, radius=0.1),
              SpotLight("spot", [-0.5, -0.5, 1.5], [10.0] * 3, direction=[0.0, 0.3, -1.0]),
              SunLight("sun", [0.2, 0.3, -1.0], [1.0] * 3)]
    to_world = np.array([[1, 0, 0, 0], [0, 0, -1, -4.0], [0, 1, 0, 1.0], [0, 0, 0, 1]], float)
    camera = Camera(to_world, SIZE, SIZE, view_window(SIZE, SIZE, orthographic=False))
    return Scene.build(triangles, materials, lights, camera, uvs=uvs, material=material, textures=[texture],
                       world=(0.05, 0.05, 0.05), max_bounces=2)


class Precompile:
    """The kernels compiled (or loaded from the cache) once per process, method by method in ``METHODS``' order
    (the default first), on a thread of its own or in the caller's.

    ``status()`` is one line for the user; ``wait(method)`` blocks until a method's kernels are ready; a render
    runs inside ``rendering()``, during which the thread starts no further method, so the render has the cores;
    ``stop()`` ends the thread at its next block of pixels and joins it (unregistering and exit call it, so no
    thread outlives the add-on)."""

    def __init__(self):
        self._lock = threading.Condition()
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._renders = 0
        self.done: dict[str, float] = {}  # method -> seconds its kernels took
        self.started: float | None = None
        self.error: str | None = None
        self.method = ""

    def start(self) -> None:
        """Compile on a background thread, unless that is running or done."""
        with self._lock:
            if self.ready or self._thread is not None:
                return
            self._stop.clear()
            self._thread = threading.Thread(target=self.run, name="vpl_gi kernels", daemon=True)
            self._thread.start()
        atexit.register(self.stop)

    def run(self) -> None:
        """Render the tiny scene by every method not done yet, with every pass; records the times, or the error."""
        self.started = time.perf_counter()
        scene = tiny_scene()

        def progress(_fraction, _text):
            return not self._stop.is_set()

        for name in METHODS:
            with self._lock:
                self._lock.wait_for(lambda: self._renders == 0 or self._stop.is_set())
            if self._stop.is_set():
                return
            if name in self.done:
                continue
            self.method, began = name, time.perf_counter()
            try:
                for denoise in (True, False):  # not denoised, the indirect light is filtered (``gather.bilateral``)
                    settings = RenderSettings(samples=2, light_samples=1, passes=PASSES, method=name,
                                              denoise=denoise, placement=MethodSettings(vpls=64))
                    render(scene, settings, progress=progress)
            except Cancelled:
                return
            except Exception as exc:  # a failing kernel fails the render too; here it is reported, not raised
                self.error = f"{type(exc).__name__}: {exc}"
            with self._lock:
                self.done[name] = time.perf_counter() - began
                self._lock.notify_all()

    @property
    def ready(self) -> bool:
        return len(self.done) == len(METHODS)

    def wait(self, method: str, timeout: float | None = None) -> bool:
        """Block until ``method``'s kernels are ready or nothing compiles them (True), or ``timeout`` seconds passed
        (False)."""
        with self._lock:
            return self._lock.wait_for(lambda: method in self.done or method not in METHODS
                                       or self._thread is None, timeout)

    @contextmanager
    def rendering(self):
        """A render runs: no further method starts compiling until it ends."""
        with self._lock:
            self._renders += 1
        try:
            yield
        finally:
            with self._lock:
                self._renders -= 1
                self._lock.notify_all()

    def status(self) -> str:
        """One line: compiling (since how long, which method), ready (in how long) or what failed."""
        if self.error:
            return f"Kernels: compiling failed ({self.error})"
        if self.ready:
            return f"Kernels ready ({sum(self.done.values()):.1f} s)"
        if self._thread is None:
            return "Kernels: compiled at first use"
        return (f"Compiling kernels for this Blender (once): {self.method} ({len(self.done) + 1} of "
                f"{len(METHODS)}), {time.perf_counter() - self.started:.0f} s")

    def stop(self) -> None:
        """End the background thread at its next block and wait for it."""
        self._stop.set()
        with self._lock:
            thread, self._thread = self._thread, None
            self._lock.notify_all()
        if thread is not None:
            thread.join()
        atexit.unregister(self.stop)


KERNELS = Precompile()
