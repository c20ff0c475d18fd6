"""``python -m vpl_addon bench``: every method and Cycles swept over their budgets on the same machine in one run,
timed, and judged against one converged Cycles reference per scene.

Per scene: the .blend is extracted once (timed separately), then each engine method renders through
``vpl_addon.render.render`` with its budget knob set (wall time measured around ``render()``), Cycles renders with
``configure_cycles`` at each sample count (wall time around Blender's render, EXR write included), and Cycles with
OpenImageDenoise on ``Combined``; ``METHOD+oidn`` is an engine method with its render denoised
(``RenderSettings.denoise``, the F12 default), judged on ``Combined`` against Cycles + OIDN. ``Diffuse Indirect`` is
compared for the undenoised engine methods and plain Cycles, ``Combined`` for all of them. Results: ``bench.csv``,
``<scene>.png`` (log-log rMAE against seconds) and ``summary.txt`` with the headline numbers
(``vpl_addon.evaluation.convergence``). With ``--seeds N`` every budget runs N times, with seeds 0..N-1 (the engine's
``RenderSettings.seed``, Cycles' seed), one CSV row set per run; the curves take the mean wall time and mean rMAE of
each budget's runs.

Peak memory is the process's peak resident set size during each run: Linux's ``/proc/self/clear_refs`` (writing
"5") resets the peak before a run and ``VmHWM`` reads it after, which sees everything, embree's BVH and Cycles
included (tracemalloc would miss both, and slows Python down), at no cost to the timing.
"""
from __future__ import annotations

import contextlib
import csv
import dataclasses
import os
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from typing import Callable

import bpy
import numpy as np

from ..operators.scene.extract import ExtractionError, extract
from ..operators.output.render_file import render_to
from ..operators.output.reference import SEED, TWIN_SEED, cache_entry, configure_cycles, make_reference, reference_hash, \
    stored_info
from ..vpl_addon.core import passes as P
from ..vpl_addon.core import tracer as tracer_module
from ..vpl_addon.core.exr import read_passes
from ..vpl_addon.core.memory import status_kb, trim_heap
from ..vpl_addon.evaluation import convergence as C
from ..vpl_addon.evaluation.metrics import clean_rrmse, coverage_mask, errors, noise_floor, pass_mask
from ..vpl_addon.evaluation.subdivision import levels_for, subdivide
from ..vpl_addon.gather import summing
from ..vpl_addon.lights.area import AreaLight
from ..vpl_addon.methods import METHODS
from ..vpl_addon.render import RenderSettings, render

CYCLES = "cycles"
OIDN = "cycles+oidn"
DENOISED = "+oidn"  # an engine method's name + this: the same method, its Combined denoised
ENGINE_PASSES = (P.COMBINED, P.DIFFUSE_DIRECT, P.DIFFUSE_INDIRECT, P.DIFFUSE_COLOR)
COMPARED = (P.DIFFUSE_INDIRECT, P.COMBINED)
HEADLINE_SECONDS = (2.0, 10.0, 30.0)
EQUAL_ERROR_SECONDS = 10.0  # the equal-error speed-up is read at this time of the best method
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


class BenchError(Exception):
    """A problem with the bench's input; the CLI turns it into one line."""


@dataclass
class Knob:
    """A method's budget: what the sweep varies, its default and --quick values, and how it enters the
    settings (engine methods; None for Cycles, whose knob is samples per pixel)."""
    name: str
    budgets: tuple[int, ...]
    quick: tuple[int, ...]
    apply: Callable[[RenderSettings, int], RenderSettings] | None = None


def _vpl_count(settings: RenderSettings, n: int) -> RenderSettings:
    return dataclasses.replace(settings, placement=dataclasses.replace(settings.placement, vpls=n))


def _camera_samples(settings: RenderSettings, n: int) -> RenderSettings:
    """Samples as a user raises them: ``n`` camera samples, with vbnl's one gather pair each (its default)."""
    placement = settings.placement
    if "vbnl" in METHODS:
        vbnl = placement.vbnl
        placement = dataclasses.replace(placement, vbnl=dataclasses.replace(
            vbnl, sampling=dataclasses.replace(vbnl.sampling, samples=0)))
    return dataclasses.replace(settings, samples=n, placement=placement)


VPL_COUNT = Knob("vpls", (64, 256, 1024, 4096, 16384, 65536), (64, 256), _vpl_count)
SAMPLES = Knob("spp", (1, 4, 16, 64, 256, 1024, 4096), (1, 4))
# a method whose budget is "samples" (``Method.budget``: a fixed set of lights, sampled with more camera samples
# and (BSDF + light) pairs, as vbnl's) sweeps the camera samples
CAMERA_SAMPLES = Knob("samples", (1, 4, 16, 64, 256), (1, 4), _camera_samples)
# Method -> budget knob: Cycles' samples per pixel, each engine method's from its ``budget``
KNOBS: dict[str, Knob] = {CYCLES: SAMPLES, OIDN: SAMPLES, **{
    m.name: CAMERA_SAMPLES if m.budget == "samples" else VPL_COUNT for m in METHODS.values()}}


def engine_method(method: str) -> str | None:
    """The engine method a bench method runs (``vbnl+oidn``: ``vbnl``); None for Cycles."""
    base = method.removesuffix(DENOISED)
    return base if base in METHODS else None


def knob_of(method: str) -> Knob:
    return KNOBS[engine_method(method) or method]


def all_methods() -> tuple[str, ...]:
    return (*METHODS, *(m + DENOISED for m in METHODS), CYCLES, OIDN)


def default_methods() -> tuple[str, ...]:
    """Every engine method as it is, the default one (``RenderSettings.method``) denoised as F12 renders it, and
    both Cycles rivals."""
    return (*METHODS, RenderSettings().method + DENOISED, CYCLES, OIDN)


def parse_budgets(specs: list[str] | None, methods: list[str]) -> dict[str, list[int]]:
    """``--budgets ir=64,256`` for one method, ``--budgets 64,256`` for every engine method."""
    out: dict[str, list[int]] = {}
    for spec in specs or []:
        name, _, values = spec.rpartition("=")
        try:
            numbers = sorted({int(v) for v in values.split(",") if v.strip()})
        except ValueError:
            raise BenchError(f"--budgets {spec!r}: budgets are whole numbers separated by commas") from None
        if not numbers or numbers[0] < 1:
            raise BenchError(f"--budgets {spec!r}: give at least one budget, each at least 1")
        targets = [name] if name else [m for m in methods if engine_method(m)]
        if name and name not in all_methods():
            raise BenchError(f"--budgets {spec!r}: unknown method {name!r}; choose one of {', '.join(all_methods())}")
        for t in targets:
            out[t] = numbers
    return out


class PeakMemory:
    """Peak resident set size of this process during a ``with`` block (MB), and its rise over the start.

    glibc keeps the heap that earlier runs freed (a 64 x 64 vbnl run at 256 sample pairs leaves about 1.2 GB), and a
    sweep's later runs started ever higher (veach-ajar, vbnl 256 over three seeds: 3.4, 4.1, 5.1 GB), so that heap
    is handed back to the system (``malloc_trim``) before the peak is reset."""

    def __enter__(self):
        self.peak_mb = self.rise_mb = None
        trim_heap()
        try:
            with open("/proc/self/clear_refs", "w") as f:
                f.write("5")
            self.start = status_kb("VmRSS")
        except OSError:
            self.start = None
        return self

    def __exit__(self, *exc):
        if self.start is not None:
            peak = status_kb("VmHWM")
            self.peak_mb, self.rise_mb = peak / 1024, max(0, peak - self.start) / 1024
        return False


@dataclass
class Run:
    scene: str
    width: int
    height: int
    method: str
    budget: int
    wall: float
    seed: int = 0
    extract: float | None = None
    stages: dict[str, float] = field(default_factory=dict)
    rays: int | None = None
    peak_mb: float | None = None
    rise_mb: float | None = None
    errors: dict[str, dict] = field(default_factory=dict)  # compared pass -> metrics

    def rows(self) -> list[dict]:
        base = {"scene": self.scene, "width": self.width, "height": self.height, "method": self.method,
                "knob": knob_of(self.method).name, "budget": self.budget, "seed": self.seed,
                "wall_s": _num(self.wall),
                "extract_s": _num(self.extract), **{f"{s}_s": _num(self.stages.get(s)) for s in STAGES},
                "rays": "" if self.rays is None else self.rays, "peak_rss_mb": _num(self.peak_mb, 1),
                "run_rss_mb": _num(self.rise_mb, 1)}
        return [{**base, "pass": name, **{k: _num(m.get(k), 6) for k in METRICS}} for name, m in self.errors.items()]


STAGES = ("build", "place", "gbuffer", "direct", "gather", "filter")
METRICS = ("rmae", "relmse", "rmse_reinhard", "mean_ratio", "rmae4", "clean_rrmse")  # the last: Combined, with a twin
COLUMNS = ("scene", "width", "height", "method", "knob", "budget", "seed", "pass", "wall_s", "extract_s",
           *(f"{s}_s" for s in STAGES), "rays", "peak_rss_mb", "run_rss_mb", *METRICS)


def _num(value, digits=4):
    return "" if value is None else round(float(value), digits)


def write_csv(path: str, rows: list[dict]) -> None:
    """All rows so far, replaced atomically (a bench killed half-way leaves the scenes it finished)."""
    fd, tmp = tempfile.mkstemp(prefix=".partial-", suffix=".csv", dir=os.path.dirname(path))
    with os.fdopen(fd, "w", newline="") as f:
        writer = csv.DictWriter(f, COLUMNS)
        writer.writeheader()
        writer.writerows(rows)
    os.replace(tmp, path)


@contextlib.contextmanager
def quiet_blender():
    """Blender's own log lines (file read, image saved, per-sample progress) go to the C-level stdout and would
    bury the progress bar: send file descriptor 1 to /dev/null and give Python's ``sys.stdout`` a copy of it."""
    sys.stdout.flush()
    keep = os.dup(1)
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 1)
    os.close(devnull)
    previous = sys.stdout
    sys.stdout = os.fdopen(os.dup(keep), "w", buffering=1)
    try:
        yield
    finally:
        sys.stdout.flush()
        sys.stdout.close()
        sys.stdout = previous
        os.dup2(keep, 1)
        os.close(keep)


# ---------------------------------------------------------------------------------------------------------------
# references

def find_reference(blend: str, percentage: int | None, folder: str, seed: int = SEED) -> str | None:
    """A committed reference of ``blend`` at ``percentage`` rendered with Cycles' ``seed`` (``TWIN_SEED``: the
    twin) in ``folder`` whose hash is current (highest samples)."""
    if not os.path.isdir(folder):
        return None
    found = []
    for name in sorted(os.listdir(folder)):
        if not name.endswith(".exr"):
            continue
        path = os.path.join(folder, name)
        try:
            info = stored_info(path)
        except Exception:  # not a readable EXR: not a reference
            continue
        if info.get("blend") != os.path.basename(blend) or info.get("percentage") != percentage:
            continue
        if info.get("hash") == reference_hash(blend, info["samples"], info.get("frame"), percentage, seed):
            found.append((info["samples"], path))
    return max(found)[1] if found else None


def twin_for(blend: str, percentage: int | None, folder: str, cache_dir: str | None = None,
             samples: int | None = None) -> tuple[str | None, np.ndarray | None]:
    """The twin reference of ``blend`` in ``folder`` (``find_reference`` with ``TWIN_SEED``) or else, at
    ``samples``, in ``cache_dir`` (where ``reference --twin`` keeps it by hash: the twins of the converted scenes,
    whose .blend files ``make scenes`` writes here and git does not hold), and its Combined, or (None, None): what
    ``clean_rrmse`` and ``noise_floor`` need beside the reference."""
    path = find_reference(blend, percentage, folder, TWIN_SEED)
    if path is None and cache_dir and samples:
        cached, held = cache_entry(cache_dir, reference_hash(blend, samples, None, percentage, TWIN_SEED))
        path = cached if held else None
    return path, (read_passes(path)[0][P.COMBINED] if path else None)


def reference_for(blend: str, percentage: int | None, reference_dir: str, cache_dir: str, samples: int,
                  say: Callable[[str], None]) -> tuple[dict, str]:
    path = find_reference(blend, percentage, reference_dir)
    if path is not None:
        return read_passes(path)[0], f"{os.path.relpath(path)} ({stored_info(path)['samples']} spp, hash fresh)"
    os.makedirs(cache_dir, exist_ok=True)
    out = os.path.join(cache_dir, f"{os.path.splitext(os.path.basename(blend))[0]}-{percentage or 'scene'}pct.exr")
    say(f"no committed reference of {os.path.basename(blend)} at this resolution: rendering Cycles at {samples} spp "
        f"(cached in {cache_dir})")
    info = make_reference(blend, out, samples, None, cache_dir, percentage)
    return read_passes(out)[0], f"Cycles {samples} spp ({'cache' if info.get('cached') else 'rendered'})"


# ---------------------------------------------------------------------------------------------------------------
# runs

def engine_run(built, settings: RenderSettings) -> tuple[float, object, PeakMemory]:
    with PeakMemory() as memory:
        t0 = time.perf_counter()
        result = render(built, settings)
        wall = time.perf_counter() - t0
    return wall, result, memory


def cycles_run(scene, spp: int, denoise: bool, folder: str, seed: int = 0) -> tuple[float, dict, PeakMemory]:
    configure_cycles(scene, spp)
    scene.cycles.seed += seed
    if denoise:
        scene.cycles.use_denoising = True
        try:
            scene.cycles.denoiser = "OPENIMAGEDENOISE"
        except TypeError:
            raise BenchError("this Blender build has no OpenImageDenoise: leave cycles+oidn out of --methods") \
                from None
    path = os.path.join(folder, "cycles.exr")
    with PeakMemory() as memory:
        t0 = time.perf_counter()
        render_to(scene, path)
        wall = time.perf_counter() - t0
    return wall, read_passes(path)[0], memory


def record_gather_rays(built, settings: RenderSettings, limit: int) -> tuple[np.ndarray, ...]:
    """Shadow rays the gather issues during one render (origins, directions, tmax as the Tracer receives them),
    the first ``limit`` of them, kept as float32 (what embree is given anyway)."""
    batches, lock, count = [], threading.Lock(), [0]

    def recorder(origins, dirs, tmax):
        frame, from_gather = sys._getframe(1), False
        for _ in range(6):  # occluded <- visible <- connect (gather/summing.py) <- ...
            frame = frame.f_back
            if frame is None:
                break
            if frame.f_globals.get("__name__") == summing.__name__:
                from_gather = True
                break
        if not from_gather:
            return
        with lock:
            take = min(len(origins), limit - count[0])
            if take <= 0:
                return
            count[0] += take
        batches.append(tuple(np.array(a[:take], np.float32) for a in (origins, dirs, tmax)))

    tracer_module.OCCLUSION_RECORDER = recorder
    try:
        render(built, settings)
    finally:
        tracer_module.OCCLUSION_RECORDER = None
    if not batches:
        return np.zeros((0, 3), np.float32), np.zeros((0, 3), np.float32), np.zeros(0, np.float32)
    return tuple(np.concatenate([b[i] for b in batches]) for i in range(3))


def best_of(fn, repeat=3) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def gather_ray_throughput(triangles: np.ndarray, origins, dirs, tmax) -> dict:
    """The recorded gather rays through raw embreex (float32, one call, one thread) and through the Tracer
    (float64 in, as the engine calls it, split over all cores); both must agree on every ray."""
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh

    from ..vpl_addon.core.tracer import FAR, Tracer
    raw = rtcore_scene.EmbreeScene()
    TriangleMesh(raw, np.ascontiguousarray(triangles, np.float32))
    t32 = np.minimum(tmax, FAR).astype(np.float32)
    raw_hits = raw.run(origins, dirs, dists=t32.copy(), query="OCCLUDED")
    t_raw = best_of(lambda: raw.run(origins, dirs, dists=t32.copy(), query="OCCLUDED"))
    o64, d64, m64 = (a.astype(np.float64) for a in (origins, dirs, tmax))
    tracer = Tracer(triangles)
    try:
        ours = tracer.occluded(o64, d64, m64)
        t_ours = best_of(lambda: tracer.occluded(o64, d64, m64))
        threads = tracer.threads
    finally:
        tracer.close()
    n = len(origins)
    return {"rays": n, "raw_mrays_s": n / t_raw / 1e6, "tracer_mrays_s": n / t_ours / 1e6, "ratio": t_raw / t_ours,
            "threads": threads, "disagree": int(np.count_nonzero((np.asarray(raw_hits) >= 0) != ours))}


# ---------------------------------------------------------------------------------------------------------------
# the sweep

@dataclass
class Options:
    scenes: list[str]
    methods: list[str]
    budgets: dict[str, list[int]]
    out_dir: str
    percentage: int | None = None
    samples: int | None = None  # engine camera and light samples; None: the scene's (the user's defaults)
    light_samples: int | None = None
    denoise_prefilter: str | None = None  # the denoised engine runs' (None: the scene's, as F12 would)
    denoise_quality: str | None = None
    time_cap: float = 40.0
    reference_dir: str = os.path.join(ROOT, "tests", "references")
    reference_samples: int = 4096
    cache_dir: str = os.path.join(os.path.expanduser("~"), ".cache", "vpl_gi")
    gather_rays: int = 2_000_000
    quick: bool = False
    scaling: bool = False
    seeds: int = 1  # runs of each budget, with seeds 0..seeds-1

    def engine_settings(self, settings: RenderSettings) -> RenderSettings:
        """``settings`` with the camera and light samples and the denoiser's settings asked for (the scene's where
        not)."""
        given = {"samples": self.samples, "light_samples": self.light_samples,
                 "denoise_prefilter": self.denoise_prefilter, "denoise_quality": self.denoise_quality}
        return dataclasses.replace(settings, **{k: v for k, v in given.items() if v is not None})


def plan(options: Options) -> dict[str, list[int]]:
    return {m: list(options.budgets.get(m) or (knob_of(m).quick if options.quick else knob_of(m).budgets))
            for m in options.methods}


class Bench:
    def __init__(self, options: Options, open_blend: Callable[[str], object]):
        self.o = options
        self.open_blend = open_blend
        self.budgets = plan(options)
        self.rows: list[dict] = []
        self.summary: list[str] = []
        self.warm: set[tuple[str, str]] = set()  # (method, scene) warmed up
        from tqdm import tqdm
        total = len(options.scenes) * sum(len(b) for b in self.budgets.values()) * options.seeds
        self.bar = tqdm(total=total, unit="run", file=sys.stderr, dynamic_ncols=True, mininterval=0.5,
                        bar_format="{l_bar}{bar}| {n_fmt}/{total_fmt} runs [{elapsed}<{remaining}]")

    def say(self, text: str) -> None:
        self.bar.write(text, file=sys.stdout)
        sys.stdout.flush()

    def sweep(self, method: str, label: str, run_one: Callable[[int, int], Run],
              warm_up: Callable[[int], object]) -> list:
        """Budgets in increasing order, each run with every seed; stops (and says so) when the next budget's runs
        would pass the time cap, judging by the last budget's mean time scaled by the budget ratio. A method's first
        run on each scene is a warm-up, not kept: libraries, and the kernels, tables and caches its materials and
        lights use (cornell_textured's first run after four other scenes took 11.8 s against 2.5 s, its texture
        kernels compiling), as a user's first render after an install compiles them once."""
        runs, budgets, seeds = [], self.budgets[method], self.o.seeds
        if (method, label) not in self.warm:
            warm_up(budgets[0])
            self.warm.add((method, label))
        for i, budget in enumerate(budgets):
            walls = []
            for seed in range(seeds):
                self.bar.set_description(f"{label} {method} {knob_of(method).name}={budget}"
                                         + (f" seed {seed}" if seeds > 1 else ""))
                run = run_one(budget, seed)
                runs.append(run)
                walls.append(run.wall)
                self.bar.update(1)
                shown = ", ".join(f"{p} rMAE {m['rmae']:.4f}" for p, m in run.errors.items())
                self.say(f"  {label} {method:12s} {knob_of(method).name}={budget:<6d}"
                         + (f" seed {seed:<3d}" if seeds > 1 else "") + f" {run.wall:7.2f} s  {shown}")
            wall = sum(walls) / len(walls)
            if i + 1 < len(budgets) and wall * budgets[i + 1] / budget > self.o.time_cap:
                left = budgets[i + 1:]
                self.bar.update(len(left) * seeds)
                self.say(f"  {label} {method:12s} skips {knob_of(method).name}={','.join(map(str, left))}: the next "
                         f"run would take about {wall * budgets[i + 1] / budget:.0f} s (--time-cap "
                         f"{self.o.time_cap:g})")
                break
        return runs

    def scene(self, blend: str) -> None:
        label = os.path.splitext(os.path.basename(blend))[0]
        scene = self.open_blend(blend)
        own = scene.render.resolution_percentage
        pct = None if self.o.percentage in (None, own) else self.o.percentage
        reference, source = reference_for(blend, pct, self.o.reference_dir, self.o.cache_dir,
                                          self.o.reference_samples, self.say)
        scene = self.open_blend(blend)
        if pct is not None:
            scene.render.resolution_percentage = pct
        ref_alpha = reference[P.COMBINED][..., 3]
        h, w = ref_alpha.shape
        mask = coverage_mask(ref_alpha, (h, w))
        twin_path, twin = twin_for(blend, pct, self.o.reference_dir, self.o.cache_dir, self.o.reference_samples)
        floor = None if twin is None else noise_floor(reference[P.COMBINED], twin, mask)
        self.say(f"{label}: {w}x{h}, reference {source}" +
                 (f", twin {os.path.relpath(twin_path)}" if twin_path else ""))

        def judge(images: dict, passes) -> dict:
            found = {name: errors(images[name], reference[name], pass_mask(name, reference, mask)) for name in passes}
            if twin is not None and P.COMBINED in found:
                found[P.COMBINED]["clean_rrmse"] = clean_rrmse(images[P.COMBINED], reference[P.COMBINED], twin, mask)
            return found

        runs: list[Run] = []
        engine_methods = [m for m in self.o.methods if engine_method(m)]
        if engine_methods:
            t0 = time.perf_counter()
            try:
                built, _ = extract(bpy.context.evaluated_depsgraph_get())
            except ExtractionError as err:
                raise BenchError(f"{blend}: {err}") from None
            t_extract = time.perf_counter() - t0
            if (built.camera.height, built.camera.width) != (h, w):
                raise BenchError(f"{blend}: renders at {built.camera.width}x{built.camera.height} but its reference "
                                 f"is {w}x{h}")
            base = scene.vpl_gi.render_settings(ENGINE_PASSES)
            base = self.o.engine_settings(base)
            for method in engine_methods:
                knob = knob_of(method)
                denoised = method.endswith(DENOISED)  # judged on the picture only: the light passes stay estimates
                settings = dataclasses.replace(base, method=engine_method(method), denoise=denoised)
                compared = (P.COMBINED,) if denoised else COMPARED

                def one(budget, seed, method=method, knob=knob, settings=settings, compared=compared):
                    wall, result, mem = engine_run(built, knob.apply(dataclasses.replace(settings, seed=seed), budget))
                    return Run(label, w, h, method, budget, wall, seed, t_extract, dict(result.seconds), result.rays,
                               mem.peak_mb, mem.rise_mb, judge(result.passes, compared))

                runs += self.sweep(method, label, one,
                                   lambda b, knob=knob, settings=settings: render(built, knob.apply(settings, b)))
            ran = [r.budget for r in runs if r.method == engine_methods[0]]
            budget = ran[len(ran) // 2]
            method = engine_method(engine_methods[0])
            self.bar.set_description(f"{label} gather rays")
            rays = record_gather_rays(built, knob_of(method).apply(dataclasses.replace(base, method=method), budget),
                                      self.o.gather_rays)
            if len(rays[0]):
                g = gather_ray_throughput(built.triangles, *rays)
                self.summary.append(f"{label}: gather shadow rays ({method}, {knob_of(method).name}={budget}, "
                                    f"{g['rays'] / 1e6:.2f} M rays replayed): raw embreex {g['raw_mrays_s']:.2f} M/s "
                                    f"(1 thread), Tracer {g['tracer_mrays_s']:.2f} M/s ({g['threads']} threads): "
                                    f"{g['ratio'] * 100:.0f} % of raw"
                                    + (f"; {g['disagree']} rays disagree" if g["disagree"] else ""))
                self.say("  " + self.summary[-1])
        with tempfile.TemporaryDirectory(dir=self.o.out_dir, prefix=".cycles-") as tmp:
            for method in (m for m in self.o.methods if m in (CYCLES, OIDN)):
                denoise = method == OIDN
                compared = (P.COMBINED,) if denoise else COMPARED

                def one(spp, seed, denoise=denoise, compared=compared, method=method):
                    wall, images, mem = cycles_run(scene, spp, denoise, tmp, seed)
                    if images[P.COMBINED].shape[:2] != (h, w):
                        raise BenchError(f"{blend}: Cycles rendered {images[P.COMBINED].shape[1]}x"
                                         f"{images[P.COMBINED].shape[0]} but the reference is {w}x{h}")
                    return Run(label, w, h, method, spp, wall, seed, None, {}, None, mem.peak_mb, mem.rise_mb,
                               judge(images, compared))

                runs += self.sweep(method, label, one,
                                   lambda spp, denoise=denoise: cycles_run(scene, spp, denoise, tmp))
        for run in runs:
            self.rows += run.rows()
        self.report(label, w, h, runs, floor)

    def report(self, label: str, w: int, h: int, runs: list[Run], floor: dict | None = None) -> None:
        curves = curves_of(runs)
        C.plot(os.path.join(self.o.out_dir, f"{label}.png"), f"{label} ({w}x{h})", curves)
        lines = headline(label, curves, floor=floor) + headline(label, curves_of(runs, "rmae4"), "rmae4", floor) + \
            headline(label, curves_of(runs, "clean_rrmse"), "clean_rrmse")
        self.summary += lines
        for line in lines:
            self.say(line)

    def run(self) -> list[str]:
        csv_path = os.path.join(self.o.out_dir, "bench.csv")
        t0 = time.perf_counter()
        try:
            with quiet_blender():
                for blend in self.o.scenes:
                    self.scene(blend)
                    write_csv(csv_path, self.rows)
                if self.o.scaling:
                    self.summary += scaling(self, self.o.scenes[0])
        finally:
            self.bar.close()
        self.summary.append(f"bench: {len(self.o.scenes)} scene(s), {len(self.rows)} CSV rows, "
                            f"{time.perf_counter() - t0:.0f} s; wrote {csv_path}")
        return self.summary


def curves_of(runs: list[Run], metric: str = "rmae") -> dict[str, dict[str, C.Curve]]:
    """Compared pass -> method -> curve of ``metric``."""
    panels: dict[str, dict[str, C.Curve]] = {}
    for name in COMPARED:
        for method in dict.fromkeys(r.method for r in runs):
            mine = [r for r in runs if r.method == method and metric in r.errors.get(name, {})]
            if mine:  # a clean_rrmse of 0 (within the references' own noise) kept above 0 for the log-log curves
                panels.setdefault(name, {})[method] = C.Curve.of([r.wall for r in mine],
                                                                 [max(r.errors[name][metric], 1e-9) for r in mine],
                                                                 [r.budget for r in mine])
    return panels


def headline(label: str, panels: dict[str, dict[str, C.Curve]], metric: str = "rmae",
             floor: dict | None = None) -> list[str]:
    """The two headline numbers against Cycles on Diffuse Indirect, and the same against Cycles + OIDN on
    Combined (where the undenoised and the denoised engine methods compete); for ``metric`` "rmae4" (rMAE of 4 x 4
    blocks, which a reference's own noise disturbs less) and "clean_rrmse" (relative RMSE with the references'
    own noise taken out, where the scene has a twin reference) the Combined ones only. ``floor``
    (``metrics.noise_floor``, where the scene has a twin) adds what a perfect image scores in ``metric`` on
    Combined, and so the largest ratio against Cycles + OIDN that any image could show at each time."""
    lines = []
    rmae, what = {"rmae": ("rMAE", ":"), "rmae4": ("block rMAE", ", rMAE of 4 x 4 blocks:"),
                  "clean_rrmse": ("clean rRMSE", ", relative RMSE with the references' own noise taken out:")}[metric]
    for name, rival in ((P.DIFFUSE_INDIRECT, CYCLES), (P.COMBINED, OIDN))[0 if metric == "rmae" else 1:]:
        curves = panels.get(name, {})
        ours = {m: c for m, c in curves.items() if m not in (CYCLES, OIDN)}
        if rival not in curves or not ours:
            continue
        lines.append(f"{label}, {name}, against {rival}{what}")
        for seconds in HEADLINE_SECONDS:
            eq = C.equal_time(ours, curves[rival], seconds)
            if eq.best is None:
                lines.append(f"  equal time {seconds:g} s: n/a (no method's runs span {seconds:g} s: {spans(ours)})")
            elif eq.cycles_error.value is None:
                lines.append(f"  equal time {seconds:g} s: {eq.best} {rmae} {eq.best_error.value:.4f}; {rival} "
                             f"{eq.cycles_error.note}")
            else:
                lines.append(f"  equal time {seconds:g} s: {rival} {rmae} {eq.cycles_error.value:.4f} / {eq.best} "
                             f"{eq.best_error.value:.4f} = {eq.ratio:.2f}x")
        each = []
        for m, c in ours.items():
            ratios = [C.equal_time({m: c}, curves[rival], t).ratio for t in HEADLINE_SECONDS]
            each.append(f"{m} " + " / ".join("n/a" if r is None else f"{r:.2f}x" for r in ratios))
        times = " / ".join(f"{t:g} s" for t in HEADLINE_SECONDS)
        lines.append(f"  each method, {rival} {rmae} / its {rmae} at {times}: "
                     + ", ".join(each))
        if floor is not None and name == P.COMBINED and metric in floor:
            most = [C.error_at(curves[rival], t).value for t in HEADLINE_SECONDS]
            lines.append(f"  the references' floor: a perfect image scores about {floor[metric]:.4f} (the twin's "
                         f"{rmae} over sqrt 2); the most any image can show against {rival} at {times}: "
                         + " / ".join("n/a" if e is None else f"{e / floor[metric]:.2f}x" for e in most))
        ee = C.equal_error(ours, curves[rival], EQUAL_ERROR_SECONDS)
        if ee.best is None:
            lines.append(f"  equal error: n/a (no method's runs span {ee.seconds:g} s)")
        elif ee.speedup is None:
            lines.append(f"  equal error: {rival} {ee.cycles_time.note}")
        else:
            how = f" ({ee.cycles_time.note})" if ee.cycles_time.note else ""
            lines.append(f"  equal error: {rival} needs {ee.cycles_time.value:.1f} s{how} to reach {ee.best}'s "
                         f"{ee.seconds:g} s {rmae} {ee.target.value:.4f}: speed-up {ee.speedup:.2f}x")
    return lines


def spans(curves: dict[str, C.Curve]) -> str:
    return ", ".join(f"{m} {c.seconds.min():.2f}-{c.seconds.max():.2f} s" for m, c in curves.items() if len(c))


# ---------------------------------------------------------------------------------------------------------------
# scaling

def scaling(bench: Bench, blend: str) -> list[str]:
    """Wall time, rays per second as a share of raw embreex's on the same triangles and threads (measured in the
    same run, ``profile.raw_embreex``) and peak memory of one engine method against triangle count (midpoint
    subdivision, to 2 M), image size (256 px to 1920 x 1080), light count (the first rectangular light cut into 1
    to 1000 strips, ``split_light``: the same light in expectation) and the method's budget, with the fitted
    log-log exponent of each."""
    from .profile import raw_embreex
    o = bench.o
    method = next((m for m in o.methods if m in METHODS), "bidir")
    knob = knob_of(method)
    label = os.path.splitext(os.path.basename(blend))[0]
    scene = bench.open_blend(blend)
    own = scene.render.resolution_percentage
    size = scene.render.resolution_x, scene.render.resolution_y

    def extracted(percentage, width=size[0], height=size[1]):
        scene.render.resolution_percentage = percentage
        scene.render.resolution_x, scene.render.resolution_y = width, height
        try:
            return extract(bpy.context.evaluated_depsgraph_get())[0]
        finally:
            scene.render.resolution_x, scene.render.resolution_y = size

    base = o.engine_settings(dataclasses.replace(scene.vpl_gi.render_settings(ENGINE_PASSES), method=method))
    small, budget = (25, 64) if o.quick else (50, 1024)
    built = extracted(max(1, own * small // 100))
    levels = levels_for(len(built.triangles), largest=2_000_000)[:2 if o.quick else None]
    sizes = ((32, 32), (64, 36)) if o.quick else ((256, 256), (640, 360), (1280, 720), (1920, 1080))
    sweeps = {
        "triangles": [(len(built.triangles) * 4 ** k, lambda k=k: (subdivide(built, k), budget)) for k in levels],
        "pixels": [(w * h, lambda w=w, h=h: (extracted(100, w, h), budget)) for w, h in sizes],
        knob.name: [(b, lambda b=b: (built, b)) for b in ((64, 256) if o.quick else (256, 1024, 4096, 16384))],
    }
    if any(_rectangle(light) for light in built.lights):
        sweeps["lights"] = [(n, lambda n=n: (split_light(built, n), budget)) for n in
                            ((1, 10) if o.quick else (1, 10, 100, 1000))]
    raw = {}  # rays per second of raw embreex by triangle count
    rows, lines = [], [f"scaling ({label}, {method}, {base.samples} spp, {base.light_samples} light samples; "
                       f"{knob.name}={budget} and {small} % resolution unless varied):",
                       f"  {'sweep':10s} {'count':>10s} {'wall s':>8s} {'M rays':>8s} {'M rays/s':>9s} {'% raw':>6s} "
                       f"{'peak MB':>8s}"]
    bench.bar.reset(total=sum(len(v) for v in sweeps.values()))
    for sweep, points in sweeps.items():
        xs, ts = [], []
        for count, make in points:
            scene_here, n = make()
            bench.bar.set_description(f"scaling {sweep}={count}")
            if not xs:  # the first point of a sweep warms caches for its kind of change
                render(scene_here, knob.apply(base, n))
            wall, result, mem = engine_run(scene_here, knob.apply(base, n))
            if len(scene_here.triangles) not in raw:
                raw[len(scene_here.triangles)] = raw_embreex(scene_here.triangles, result.threads,
                                                             rays=200_000 if o.quick else 4_000_000)
            share = result.rays / wall / raw[len(scene_here.triangles)]
            bench.bar.update(1)
            xs.append(count)
            ts.append(wall)
            rows.append({"sweep": sweep, "count": count, "wall_s": round(wall, 4),
                         **{f"{s}_s": _num(result.seconds.get(s)) for s in STAGES}, "rays": result.rays,
                         "raw_rays_per_s": round(raw[len(scene_here.triangles)]), "share_of_raw": round(share, 4),
                         "peak_rss_mb": _num(mem.peak_mb, 1)})
            lines.append(f"  {sweep:10s} {count:>10,d} {wall:8.2f} {result.rays / 1e6:8.1f} "
                         f"{result.rays / wall / 1e6:9.2f} {100 * share:6.0f} {mem.peak_mb:8.0f}")
        lines.append(f"  {sweep:10s} fitted exponent (wall ~ count^k): k = {C.fit_exponent(xs, ts):.2f}")
    path = os.path.join(o.out_dir, "scaling.csv")
    fd, tmp = tempfile.mkstemp(prefix=".partial-", suffix=".csv", dir=o.out_dir)
    with os.fdopen(fd, "w", newline="") as f:
        writer = csv.DictWriter(f, ("sweep", "count", "wall_s", *(f"{s}_s" for s in STAGES), "rays", "raw_rays_per_s",
                                    "share_of_raw", "peak_rss_mb"))
        writer.writeheader()
        writer.writerows(rows)
    os.replace(tmp, path)
    for line in lines:
        bench.say(line)
    return lines


def _rectangle(light) -> bool:
    return isinstance(light, AreaLight) and not light.round


def split_light(scene, count: int):
    """``scene`` with its first rectangular area light cut into ``count`` strips along its X edge, each with its
    share of the power: the same light in expectation, ``count`` lights for the light tree to choose among."""
    index = next(i for i, light in enumerate(scene.lights) if _rectangle(light))
    light = scene.lights[index]
    strips = [dataclasses.replace(light, name=f"{light.name}.{k}", axis_u=light.axis_u / count,
                                  center=light.center + ((k + 0.5) / count - 0.5) * light.axis_u,
                                  power=light.power / count) for k in range(count)]
    return dataclasses.replace(scene, lights=scene.lights[:index] + strips + scene.lights[index + 1:])
