"""Rays per second of the engine's Tracer against raw embreex on the same rays.

Scene: an example .blend (default the Cornell box with an area light), extracted through bpy. Ray sets: camera
rays, incoherent rays (random origins in the scene box, random directions) and shadow rays from visible points to
the light. Raw embreex gets float32 arrays ready-made in one call on one thread (its own best case); the Tracer
gets float64 arrays as the engine has them and splits them over all cores.

    .venv/bin/python bench/tracer_throughput.py [SCENE.blend] [--rays N]
"""
from __future__ import annotations

import argparse
import pathlib
import sys

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scene", nargs="?", default=str(ROOT / "example_blends" / "cornell_area.blend"))
    ap.add_argument("--rays", type=int, default=1_000_000)
    args = ap.parse_args()

    from vpl_addon.__main__ import extension_package
    extension_package().register()  # the scene's settings are read from the extension's properties
    import bpy
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh
    from vpl_gi.bench.runner import best_of
    from vpl_gi.operators.scene.extract import extract
    from vpl_gi.vpl_addon.core.tracer import Tracer

    bpy.ops.wm.open_mainfile(filepath=args.scene)
    scene, _ = extract(bpy.context.evaluated_depsgraph_get())
    rng = np.random.default_rng(0)
    n = args.rays
    cam = scene.camera
    px, py = rng.random(n) * cam.width, rng.random(n) * cam.height
    cam_o, cam_d, _ = cam.rays(px, py)
    lo, hi = scene.bounds
    inc_o = lo + rng.random((n, 3)) * (hi - lo)
    inc_d = rng.normal(size=(n, 3))
    inc_d /= np.linalg.norm(inc_d, axis=1, keepdims=True)

    tracer = Tracer(scene.triangles)
    hits = tracer.intersect(cam_o, cam_d)
    hit = hits.hit
    p = cam_o[hit] + cam_d[hit] * hits.t[hit][:, None]
    light = scene.lights[0].position if hasattr(scene.lights[0], "position") else scene.lights[0].center
    to_l = light - p
    dist = np.linalg.norm(to_l, axis=1)
    sh_d = to_l / dist[:, None]
    sh_o = p + sh_d * 1e-4
    sets = {"camera (closest hit)": (cam_o, cam_d, None), "incoherent (closest hit)": (inc_o, inc_d, None),
            "shadow (occlusion)": (sh_o, sh_d, dist * 0.999)}

    raw = rtcore_scene.EmbreeScene()
    TriangleMesh(raw, scene.triangles.astype(np.float32))
    print(f"scene {pathlib.Path(args.scene).name}: {len(scene.triangles)} triangles, {tracer.threads} threads")
    print(f"{'rays':26s} {'raw embreex 1 thread':>22s} {'Tracer (all cores)':>20s} {'ratio':>7s}")
    for name, (o, d, tmax) in sets.items():
        o32, d32 = o.astype(np.float32), d.astype(np.float32)
        t32 = None if tmax is None else tmax.astype(np.float32)
        query = "INTERSECT" if tmax is None else "OCCLUDED"
        t_raw = best_of(lambda: raw.run(o32, d32, dists=None if t32 is None else t32.copy(), query=query,
                                        output=1 if query == "INTERSECT" else None))
        if tmax is None:
            t_ours = best_of(lambda: tracer.intersect(o, d))
        else:
            t_ours = best_of(lambda: tracer.occluded(o, d, tmax))
        m = len(o) / 1e6
        print(f"{name:26s} {m / t_raw:17.2f} M/s {m / t_ours:15.2f} M/s {t_raw / t_ours:6.2f}x")
    tracer.close()


if __name__ == "__main__":
    main()
