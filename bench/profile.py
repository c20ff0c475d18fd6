"""Where a default render's time goes, per stage and per function, next to raw embreex on the same triangles.

One process extracts the scene and renders it with the scene's settings (the defaults of the render panel; a warm-up
render at 1 sample first, so compiled kernels are loaded); it prints wall time, the stages' seconds (blocks' stages
are thread-seconds, summed over the threads that ran them), rays and rays per wall second, peak memory, and raw
embreex's rays per second measured in the same run: incoherent closest-hit rays (random origins in the scene's box,
random directions) in batches of 65,536 on as many threads as the render used, float32 arrays made beforehand (its
best case). The ratio of the two is the bar of issue 26. Then, per stage, the seconds its threads waited on embree
(``RenderResult.embree_seconds``) and their share of the stage, and of the render's wall time x threads.

With ``--functions`` the render runs under py-spy (a sampling profiler that sees every thread, numpy's and
embree's time included in the line that called them), and the functions and lines with the largest share of the
samples are listed: a compiled kernel's time shows in the line that called it.

    .venv/bin/python bench/profile.py [SCENE.blend] [--size WxH] [--method M] [--samples N]
        [--functions [--rate HZ]] [--top N]
"""
from __future__ import annotations

import argparse
import collections
import os
import pathlib
import re
import resource
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

BATCH = 1 << 16


def raw_embreex(triangles: np.ndarray, threads: int, rays: int = 4_000_000, seed: int = 0) -> float:
    """Rays per second of raw embreex: ``rays`` incoherent closest-hit rays in batches of ``BATCH`` on ``threads``
    threads (embreex releases the GIL), the best of three runs."""
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh
    tri = np.ascontiguousarray(triangles, np.float32).reshape(-1, 3, 3)
    scene = rtcore_scene.EmbreeScene()
    TriangleMesh(scene, tri)
    rng = np.random.default_rng(seed)
    lo, hi = tri.min(axis=(0, 1)), tri.max(axis=(0, 1))
    origins = (lo + rng.random((rays, 3)) * (hi - lo)).astype(np.float32)
    dirs = rng.normal(size=(rays, 3))
    dirs = (dirs / np.linalg.norm(dirs, axis=1, keepdims=True)).astype(np.float32)
    far = np.full(rays, 1e30, np.float32)

    def batch(start):
        end = start + BATCH
        scene.run(origins[start:end], dirs[start:end], dists=far[start:end].copy(), query="INTERSECT", output=1)

    best = np.inf
    with ThreadPoolExecutor(threads) as pool:
        for _ in range(3):
            t0 = time.perf_counter()
            list(pool.map(batch, range(0, rays, BATCH)))
            best = min(best, time.perf_counter() - t0)
    return rays / best


def hot_spots(raw: str, top: int) -> list[str]:
    """The functions (own time) and the engine's lines (the innermost frame in vpl_addon) with the largest shares of
    py-spy's raw samples ("frame;frame;... count" lines) of the engine (not the scene's extraction, nor raw
    embreex)."""
    own, lines, total = collections.Counter(), collections.Counter(), 0
    for row in raw.splitlines():
        stack, _, count = row.rpartition(" ")
        if "/vpl_addon/" not in stack or "extract (" in stack:  # the render's samples alone
            continue
        frames, count = stack.split(";"), int(count)
        total += count
        own[re.sub(r":\d+\)$", ")", frames[-1])] += count
        engine = next((f for f in reversed(frames) if "/vpl_addon/" in f), None)
        if engine is not None:
            lines[engine] += count
    out = [f"py-spy: {total} samples of the engine over all threads", "  own time of functions:"]
    out += [f"  {100 * n / total:5.1f} %  {name}" for name, n in own.most_common(top)]
    out += ["  the engine's lines (a call's time, kernels' included, in the line that made it):"]
    out += [f"  {100 * n / total:5.1f} %  {name}" for name, n in lines.most_common(top)]
    return out


def render_once(args) -> None:
    from vpl_addon.__main__ import extension_package
    extension_package().register()
    import bpy
    from vpl_gi.bench.runner import PeakMemory
    from vpl_gi.operators.scene.extract import extract
    bpy.ops.wm.open_mainfile(filepath=args.scene)
    if args.size:
        size = bpy.context.scene.render
        (size.resolution_x, size.resolution_y), size.resolution_percentage = (int(v) for v in args.size.split("x")), 100
    scene, _ = extract(bpy.context.evaluated_depsgraph_get())
    from vpl_gi.vpl_addon.render import RenderSettings, render
    settings = bpy.context.scene.vpl_gi.render_settings(("Combined",))
    if args.method:
        settings.method = args.method
    if args.block_pixels:
        settings.block_pixels = args.block_pixels
    if args.samples:
        settings.samples = args.samples
    render(scene, RenderSettings(samples=1, light_samples=1, method=settings.method))  # kernels loaded
    with PeakMemory() as memory:
        t0, cpu0, faults0 = time.perf_counter(), os.times(), resource.getrusage(resource.RUSAGE_SELF).ru_minflt
        result = render(scene, settings)
        wall, cpu = time.perf_counter() - t0, os.times()
        faults = resource.getrusage(resource.RUSAGE_SELF).ru_minflt - faults0
    raw = raw_embreex(scene.triangles, result.threads)
    cam = scene.camera
    print(f"{pathlib.Path(args.scene).name}: {len(scene.triangles):,} triangles, {cam.width}x{cam.height}, method "
          f"{settings.method}, {settings.samples} spp x {settings.light_samples} light samples, "
          f"{result.threads} threads, load {os.getloadavg()[0]:.1f}")
    print(f"wall {wall:.2f} s, {result.rays / 1e6:.1f} M rays, {result.rays / wall / 1e6:.2f} M rays/s; raw embreex "
          f"{raw / 1e6:.2f} M rays/s on {result.threads} threads: {100 * result.rays / wall / raw:.0f} %; "
          f"peak memory {memory.peak_mb:.0f} MB; cpu user {cpu.user - cpu0.user:.2f} s, system "
          f"{cpu.system - cpu0.system:.2f} s, {faults / 1000:.0f} K page faults")
    stages = {**result.seconds, **{f"place: {k}": v for k, v in result.info.get("seconds", {}).items()}}
    print("stages (s; blocks' stages are thread-seconds): " + ", ".join(f"{k} {v:.2f}" for k, v in stages.items()))
    print(embree_shares(result, wall))


def embree_shares(result, wall: float) -> str:
    """The line of each stage's seconds waiting on embree and their share of the stage's seconds (place's are
    summed over the threads that traced, so its share may pass 100 %), and all of them as a share of the render's
    thread-seconds (wall x threads)."""
    waited = result.embree_seconds
    parts = [f"{stage} {seconds:.2f} s ({100 * seconds / max(result.seconds[stage], 1e-9):.0f} %)"
             for stage, seconds in waited.items()]
    total = sum(waited.values())
    return (f"waiting on embree: {', '.join(parts)}; in all {total:.2f} thread-s, "
            f"{100 * total / (wall * result.threads):.0f} % of wall x {result.threads} threads")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scene", nargs="?", default=str(ROOT / "example_blends" / "cornell_area.blend"))
    ap.add_argument("--size", help="render at WxH pixels instead of the scene's resolution, e.g. 1920x1080")
    ap.add_argument("--method", help="placement method (default: the scene's)")
    ap.add_argument("--block-pixels", type=int, help="pixels per block (default: the engine's)")
    ap.add_argument("--samples", type=int, help="camera samples per pixel (default: the scene's)")
    ap.add_argument("--functions", action="store_true", help="profile the run with py-spy")
    ap.add_argument("--top", type=int, default=25)
    ap.add_argument("--rate", type=int, default=100, help="py-spy's samples per second (it falls behind at 200 "
                    "on 2 busy cores)")
    ap.add_argument("--inner", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if not args.functions:
        render_once(args)
        return
    spy = pathlib.Path(sys.executable).with_name("py-spy")
    command = [sys.executable, __file__, args.scene, *(["--size", args.size] if args.size else []),
               *(["--method", args.method] if args.method else []),
               *(["--block-pixels", str(args.block_pixels)] if args.block_pixels else []),
               *(["--samples", str(args.samples)] if args.samples else [])]
    with tempfile.TemporaryDirectory() as folder:
        raw = os.path.join(folder, "samples.txt")
        subprocess.run([str(spy), "record", "--rate", str(args.rate), "--format", "raw", "--output", raw, "--",
                        *command],
                       check=True)
        samples = pathlib.Path(raw).read_text() if os.path.exists(raw) else ""
        if "/vpl_addon/" not in samples:
            raise SystemExit("the profiled render failed (its error is above)")
        for line in hot_spots(samples, args.top):
            print(line)


if __name__ == "__main__":
    main()
