"""The viewport's figures (issue 24) on the Cornell box, through bpy without a window: the code path ``view_update``
and ``view_draw`` call (``operators.engine.viewport.Viewport``), the scene camera as the view.

Per method, ``--repeats`` times: the first image (1/4 resolution) after a cold start (extraction, BVH, lights) and
after a camera move (BVH and light paths kept), their ratio, the first full-resolution pass and its Diffuse
Indirect rMAE against the Cycles reference; then ``--changes`` changes at random moments of a running job (uniform
over its first ``--window`` seconds): how long after each the old job had ended.

    .venv/bin/python bench/viewport.py [--methods vbnl,ir] [--repeats 5] [--changes 40] [--window 4]
"""
from __future__ import annotations

import argparse
import os
import pathlib
import statistics
import sys
import time
from dataclasses import replace

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
INDIRECT = "Diffuse Indirect"


def _next(view, after=None, step=None, timeout=120.0):
    frame = view.next_frame(after, step, timeout)
    if frame is None:
        raise RuntimeError(f"no image in {timeout} s: {view.status}")
    return frame


def _moved(camera, dx):
    m = camera.to_world.copy()
    m[0, 3] += dx
    return replace(camera, to_world=m)


def measure(method: str, repeats: int, changes: int, window: float, rng: np.random.Generator) -> dict:
    import bpy
    from vpl_gi.operators.scene.extract import camera_of
    from vpl_gi.operators.engine.viewport import Viewport
    from vpl_gi.vpl_addon.core.exr import read_passes
    from vpl_gi.vpl_addon.evaluation.metrics import coverage_mask, errors, pass_mask
    reference, _ = read_passes(str(ROOT / "tests" / "references" / "cornell_area.exr"))
    mask = pass_mask(INDIRECT, reference, coverage_mask(reference["Combined"][..., 3], (256, 256)))
    out = {k: [] for k in ("cold", "moved", "full", "full_moved", "rmae", "stop")}
    for _ in range(repeats):
        bpy.ops.wm.open_mainfile(filepath=str(ROOT / "example_blends" / "cornell_area.blend"))
        scene = bpy.context.scene
        scene.vpl_gi.method, scene.vpl_gi.viewport_samples = method, 1
        depsgraph = bpy.context.evaluated_depsgraph_get()
        camera = camera_of(scene, depsgraph)
        view = Viewport(passes=("Combined", INDIRECT))
        try:
            started = time.perf_counter()
            view.update(depsgraph, camera)
            first = _next(view, step="preview")
            out["cold"].append(time.perf_counter() - started)
            full = _next(view, first, step="refine")
            out["full"].append(time.perf_counter() - started)
            out["rmae"].append(errors(full.passes[INDIRECT], reference[INDIRECT], mask)["rmae"])
            view.renderer.stop()
            started = time.perf_counter()
            view.look(_moved(camera, 0.05))
            moved = _next(view, full, step="preview")
            out["moved"].append(time.perf_counter() - started)
            _next(view, moved, step="refine")
            out["full_moved"].append(time.perf_counter() - started)
            view.renderer.stop()
        finally:
            view.close()
    bpy.ops.wm.open_mainfile(filepath=str(ROOT / "example_blends" / "cornell_area.blend"))
    scene = bpy.context.scene
    scene.vpl_gi.method, scene.vpl_gi.viewport_samples = method, 4
    depsgraph = bpy.context.evaluated_depsgraph_get()
    camera = camera_of(scene, depsgraph)
    view = Viewport()
    try:
        view.update(depsgraph, camera)
        for k in range(changes):
            view.look(_moved(camera, 0.01 * (k % 2)))  # a job from a cold light state or a camera move
            time.sleep(rng.uniform(0.0, window))
            changed = time.perf_counter()
            view.look(_moved(camera, 0.02 + 0.01 * k))
            old = view.renderer.stopping
            if old is not None:
                old.join(30.0)
                out["stop"].append(time.perf_counter() - changed)
    finally:
        view.close()
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--methods", default="vbnl,ir")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--changes", type=int, default=40)
    ap.add_argument("--window", type=float, default=4.0)
    args = ap.parse_args()
    from vpl_addon.__main__ import extension_package
    extension_package().register()
    rng = np.random.default_rng(0)
    print(f"Cornell box, {os.cpu_count()} cores, load {os.getloadavg()[0]:.1f}")
    for method in args.methods.split(","):
        r = measure(method, args.repeats, args.changes, args.window, rng)
        med = {k: statistics.median(v) for k, v in r.items() if v}
        stop = np.sort(r["stop"]) * 1000
        print(f"{method}: first image cold {med['cold']:.2f} s ({min(r['cold']):.2f}-{max(r['cold']):.2f}), after a "
              f"camera move {med['moved']:.2f} s ({min(r['moved']):.2f}-{max(r['moved']):.2f}): "
              f"{med['cold'] / med['moved']:.2f}x faster; first full pass {med['full']:.2f} s "
              f"(max {max(r['full']):.2f}), after a move {med['full_moved']:.2f} s: "
              f"{med['full'] / med['full_moved']:.2f}x; Diffuse Indirect rMAE {med['rmae']:.4f} "
              f"({min(r['rmae']):.4f}-{max(r['rmae']):.4f})")
        print(f"{method}: {len(stop)} changes at random moments, the old job ended after: median "
              f"{np.median(stop):.0f} ms, 90 % {np.percentile(stop, 90):.0f} ms, max {stop[-1]:.0f} ms")


if __name__ == "__main__":
    main()
