"""Progressive rendering for the interactive viewport: a first image within moments of a change, then refinement,
on a background thread that any new change stops.

A change (``ProgressiveRenderer.start``: new scene data, a new view, new settings) stops the running work and starts
the ``plan``:

1. *preview*: the frame with ``start_resolution`` pixels on its longer side (as Cycles' viewport Start Resolution:
   a quarter of the Cornell box's 256), one camera sample, one light sample, and a light budget
   ``BUDGETS["preview"]`` times smaller than the render's (VPLs, VBNL's photons; one VBNL gather sample), so that
   the first image costs a small fraction of a full pass;
2. *coarse*: in a view larger than 4 ``start_resolution``, images twice as fine each until a quarter of the
   resolution, with the first pass's light budget (below), shown as they come;
3. *refine*: full-resolution passes of one camera sample and one light sample each (at most four VBNL gather
   samples), each with its own pixel seed, averaged into the image (``samples`` passes at most, or until
   ``time_limit``): more VPLs as they go, the first pass with a quarter of the render's light budget, the others
   with all of it.

What a change does not touch is kept, by ``sequence.state.SequenceState`` (the machinery that bakes animations):
each light budget keeps one state (``KeptLights``: its BVH, its lights and light paths), which sees the scenes it
renders as the frames of a sequence; a state is used by one job at a time, so each keeps a BVH of its own (three
builds after a geometry change, each when its step first runs). A camera move keeps the BVH and, for the lights that
ignore the camera (``ir``'s kept light paths, ``bidir``'s and ``vbnl``'s kept light paths / photons), traces no
light path; ``vbnl``'s camera-driven lights and ``bidir``'s reverse VPLs are placed again, ``smc`` keeps its VPLs
and moves at most its few per frame. A material change keeps the BVH (light paths are traced again). A moved object
rebuilds the BVH and re-traces only the light paths that cross its old or new box (Moreau et al.). Changed settings
start afresh.

Stopping: the tracer a step uses (``Interruptible``) raises ``Cancelled`` at its next call once a stop is asked for,
and ``render``'s ``progress`` returns False after its next block of pixels, so a stop reaches every stage that
traces rays (placing lights, the G-buffer, shadow rays, the gather) within one ray batch, inside a block of pixels
as well as between blocks. Stretches without rays run to their end (VBNL's sample elimination and photon splitting
of a large budget, the filter at the end of a pass: up to a few hundred milliseconds on 2 busy cores; OIDN's run
with ``denoise`` stops through its progress monitor); the stopped
job shows nothing more, and the new job waits for it only if it needs the light state it holds. A state whose
lights were being placed when the work stopped forgets its lights (not its BVH): they may be half made.
"""
from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field, replace

import numpy as np

from .core import passes as P
from .core.denoise import check as check_denoising
from .methods import METHODS
from .render import Cancelled, RenderSettings, denoise_combined, render
from .sequence.state import SequenceState

# pixels per block of the first image: its few pixels still spread over every core (the passes keep render's
# larger blocks, 30 % faster with VBNL's gather)
PREVIEW_BLOCK_PIXELS = 1024
# the light budget (VPLs, VBNL's photons) of each light state: the render's divided by this
BUDGETS = {"preview": 16, "first": 4, "full": 1}


@dataclass
class ViewportSettings:
    start_resolution: int = 64  # pixels on the longer side of the first image
    samples: int = 16  # full-resolution passes averaged (a camera and a light sample per pixel each)
    time_limit: float = 0.0  # seconds after a change when refinement stops (0: ``samples`` alone decides)
    denoise: bool = False  # OpenImageDenoise on the averaged image after each pass
    # with Cycles' viewport defaults: one filter run, OIDN's balanced network (0.1 s at 256 x 256 on 2 cores, a
    # seventh of the render's Accurate / High)
    denoise_prefilter: str = "FAST"
    denoise_quality: str = "BALANCED"

    def __post_init__(self):
        if self.start_resolution < 1 or self.samples < 1 or self.time_limit < 0:
            raise ValueError(f"viewport settings out of range: {self}")
        check_denoising(self.denoise_prefilter, self.denoise_quality)


@dataclass
class Step:
    """One pass of the plan: its pixel size, its render settings and the name of the light state it keeps."""
    name: str  # "preview", "coarse" or "refine"
    pixel_size: int  # screen pixels per pixel rendered, along each side
    settings: RenderSettings
    lights: str  # a key of ``BUDGETS``: the light state (``KeptLights``) that keeps its BVH and lights


def plan(settings: RenderSettings, viewport: ViewportSettings, passes: tuple[str, ...], size: tuple[int, int]) \
        -> list[Step]:
    """The passes a change starts in a view of ``size`` (width, height) pixels, from the render's ``settings``
    (method, light budget, seed, film...) and the viewport's; each writes ``passes`` (Combined always)."""
    if viewport.denoise:
        passes = tuple(passes) + (P.DENOISING_ALBEDO, P.DENOISING_NORMAL)
    one = replace(settings, samples=1, light_samples=min(settings.light_samples, 1), indirect_samples=1,
                  denoise=False, passes=tuple(dict.fromkeys((P.COMBINED,) + tuple(passes))),
                  placement_seed=settings.seed)
    vbnl = settings.placement.vbnl
    pairs = METHODS["vbnl"].gather_samples(settings.placement, settings.samples)

    def budget(name):
        share = BUDGETS[name]
        vpls, photons = settings.placement.vpls, vbnl.light_paths(0)  # automatic: the fewest
        return replace(settings.placement, vpls=min(vpls, max(64, vpls // share)),
                       vbnl=replace(vbnl, photons=min(photons, max(4096, photons // share)), sampling=replace(
                           vbnl.sampling, samples=min(pairs, 1 if name == "preview" else 4))))
    coarse = replace(one, block_pixels=PREVIEW_BLOCK_PIXELS)
    pixel = -(-max(size) // viewport.start_resolution)
    steps = [Step("preview", pixel, replace(coarse, placement=budget("preview")), "preview")]
    while pixel > 4:
        pixel = -(-pixel // 2)
        steps.append(Step("coarse", pixel, replace(coarse, placement=budget("first")), "first"))
    for k in range(viewport.samples):
        lights = "first" if k == 0 else "full"
        steps.append(Step("refine", 1, replace(one, placement=budget(lights), seed=settings.seed + k), lights))
    return steps


class Interruptible:
    """A tracer whose every call first checks ``stop``: ``Cancelled`` once it is set."""

    def __init__(self, tracer, stop: threading.Event):
        self._tracer, self._stop = tracer, stop

    def __getattr__(self, name):
        value = getattr(self._tracer, name)
        if not callable(value):
            return value

        def checked(*args, **kwargs):
            if self._stop.is_set():
                raise Cancelled()
            return value(*args, **kwargs)
        return checked


class KeptLights(SequenceState):
    """The state of one light budget across the viewport's changes (a ``SequenceState`` whose frames are the scene
    after each change). One job at a time renders with it (``hold``); the tracers it hands out stop when that job's
    ``stop`` is set."""

    def __init__(self, method: str):
        super().__init__(method)
        self.stop = threading.Event()
        self._lock = threading.Lock()

    def hold(self, stop: threading.Event) -> bool:
        """Take the state for the job whose flag is ``stop``, waiting while another job still has it; False if
        ``stop`` is set meanwhile."""
        while not self._lock.acquire(timeout=0.005):
            if stop.is_set():
                return False
        self.stop = stop
        return True

    def release(self) -> None:
        self._lock.release()

    def begin(self, scene, frame=None, threads=None):
        return Interruptible(super().begin(scene, frame, threads), self.stop)

    def forget_lights(self) -> None:
        """Forget the lights and what placed them (the next frame places them as a first frame), keeping the BVH."""
        self.snapshot = self.lights = self.method_state = self.rng_state = None


@dataclass
class Frame:
    """An image the viewport shows: Combined (H,W,4, row 0 at the top) and the other passes, averaged over the
    passes done so far."""
    passes: dict[str, np.ndarray]
    step: str  # the step that made it: "preview" or "refine"
    count: int  # full-resolution passes averaged (0 for the preview)
    seconds: float  # since the change that started the work
    info: dict = field(default_factory=dict)  # the last pass's method info (light paths traced, reused...)
    rays: int = 0  # rays the last pass traced
    bvh_builds: int = 0  # BVHs the light state of the last pass has built since it was made
    number: int = 0  # the renderer's count of images made, so a viewer uploads each image once

    @property
    def combined(self) -> np.ndarray:
        return self.passes[P.COMBINED]


class ProgressiveRenderer:
    """Renders scenes progressively on background threads (see the module's docstring). The latest image is
    ``frame`` (a viewer polls it: ``Frame.number`` tells a new one); ``status`` is one line on what it is doing or
    what went wrong.

    Each change is a job with its own thread and stop flag. ``start`` sets the running job's flag and starts the new
    one at once: the old job ends at its next ray batch or block, and until it has, it shows nothing more and keeps
    the light state it holds, which the new job waits for (``KeptLights.hold``) only when it needs that state."""

    def __init__(self):
        self.frame: Frame | None = None
        self.status = ""
        self.warnings: list[str] = []
        self.stopping: threading.Thread | None = None  # the job the last change stopped (until it has ended)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._shown = threading.Lock()  # a job shows its image only while its flag is not set
        self._states: dict[str, KeptLights] = {}
        self._key = None  # the settings the states were made for
        self._made = 0  # images made

    def start(self, scene, settings: RenderSettings, viewport: ViewportSettings,
              passes: tuple[str, ...] = (P.COMBINED,)) -> None:
        """Stop the running job and render ``scene`` progressively."""
        started = time.perf_counter()
        steps = plan(settings, viewport, passes, (scene.camera.width, scene.camera.height))
        key = repr(sorted({s.lights: (s.settings.method, s.settings.placement, s.settings.threads)
                           for s in steps}.items()))
        if key != self._key:  # a new method or light budget: nothing kept is valid
            self.stop()
            self.close_states()
            self._states = {name: KeptLights(settings.method) for name in BUDGETS}
            self._key = key
        with self._shown:
            self._stop.set()
            self.stopping = self._thread
            self._stop = threading.Event()
        self._thread = threading.Thread(target=self._work, args=(scene, steps, viewport, started, self._stop),
                                        name="VPL GI viewport", daemon=True)
        self._thread.start()

    def stop(self) -> float:
        """Stop the running job and wait until it has ended; the seconds that took."""
        started = time.perf_counter()
        self._stop.set()
        for thread in (self._thread, self.stopping):
            if thread is not None:
                thread.join()
        return time.perf_counter() - started

    @property
    def busy(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def wait(self, timeout: float | None = None) -> bool:
        """Wait until the running job is done (or ``timeout`` seconds); True if it is."""
        if self._thread is not None:
            self._thread.join(timeout)
        return not self.busy

    def close_states(self) -> None:
        for state in self._states.values():
            state.close()
        self._states = {}

    def close(self) -> None:
        self.stop()
        self.close_states()

    # -- the worker ------------------------------------------------------------------------------------------------
    def _say(self, stop: threading.Event, status: str) -> None:
        with self._shown:
            if not stop.is_set():
                self.status = status

    def _work(self, scene, steps: list[Step], viewport: ViewportSettings, started: float,
              stop: threading.Event) -> None:
        total: dict[str, np.ndarray] = {}
        count = 0
        for step in steps:
            late = viewport.time_limit and time.perf_counter() - started >= viewport.time_limit
            if step.name == "refine" and count and late:
                break
            self._say(stop, f"pass {count + 1} of {viewport.samples}" if step.name == "refine" else "first images")
            state = self._states[step.lights]
            if not state.hold(stop):
                return
            placed = []  # render calls progress once its lights are placed

            def progress(fraction, text):
                placed.append(fraction)
                return not stop.is_set()
            size = step.pixel_size
            camera = scene.camera
            small = replace(scene, camera=replace(camera, width=-(-camera.width // size), region=None,
                                                  height=-(-camera.height // size)))
            try:
                result = render(small if size > 1 else scene, step.settings, progress, sequence=state)
            except Cancelled:
                if not placed:
                    state.forget_lights()
                return
            except Exception as err:  # a bug: the last image stays, the status line says what failed
                state.forget_lights()
                self._say(stop, " ".join(f"render failed ({type(err).__name__}: {err}); please report".split()))
                return
            finally:
                state.release()
            if step.name == "refine":
                count += 1
                for name, image in result.passes.items():
                    total[name] = total.get(name, 0.0) + image
                images = {name: image / count for name, image in total.items()}
                if viewport.denoise:
                    images[P.COMBINED] = _denoised(images, count * step.settings.samples, step.settings.threads,
                                                   viewport, stop, result.warnings)
            else:
                images = result.passes
            with self._shown:
                if stop.is_set() or images[P.COMBINED] is None:
                    return
                self._made += 1
                self.frame = Frame(images, step.name, count, time.perf_counter() - started, result.info,
                                   result.rays, state.bvh_builds, self._made)
                self.warnings = result.warnings
        self._say(stop, f"done: {count} passes in {time.perf_counter() - started:.1f} s")


def _denoised(images, samples: int, threads, viewport: ViewportSettings, stop: threading.Event,
              warnings: list[str]) -> np.ndarray | None:
    """Combined of the averaged ``images`` (``samples`` camera samples per pixel) denoised with the viewport's
    prefilter and quality (``render.denoise_combined``; None if ``stop`` is set meanwhile: OIDN's run stops); as it
    is, with a warning added to ``warnings``, without OIDN."""
    combined = images[P.COMBINED].copy()
    try:
        denoise_combined(combined, images[P.DENOISING_ALBEDO], images[P.DENOISING_NORMAL], threads,
                         lambda done, text: not stop.is_set(), warnings, "the viewport",
                         viewport.denoise_prefilter, viewport.denoise_quality, samples)
    except Cancelled:
        return None
    return combined
