"""Time of Virtual Blue Noise Lighting's placement (Li et al. 2022, sec. 3) and of its two heavy stages at scale.

0. The placement at the engine's defaults (4,096 lights from 40,960 candidates, 2^18 light paths), its stages as
   ``RenderResult.info["seconds"]`` has them, after a warm-up placement (compiled kernels load from disk).
1. Adaptive sample elimination of 1,000,000 camera candidates (sec. 3.1, found in the scene) to 100,000 lights
   (that it spaces them like the sequential greedy is a test, tests/engine/methods/test_vbnl.py; here only the time).
2. Photon splitting of about 10,000,000 photons (light-path vertices) among those 100,000 lights, as the
   placement does it (``photon_batches``, ``split_photons``): light paths traced in batches on the tracer's threads
   and never stored, each vertex's intensity shared among the lights covering it, kept apart by bounce, on as
   many threads, the two overlapping.

    .venv/bin/python bench/vbnl_stages.py [SCENE.blend] [--candidates N] [--lights N] [--photons N]
"""
from __future__ import annotations

import argparse
import os
import pathlib
import sys
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))


def register_extension():
    """The extension loaded into bpy as ``vpl_gi`` (once): the scenes' settings (film, bounces) are its."""
    from vpl_addon.__main__ import extension_package
    package = extension_package()
    import bpy
    if not hasattr(bpy.types.Scene, "vpl_gi"):
        package.register()


def load_scene(path, percentage: int | None = None):
    """The engine's Scene of a .blend, extracted through bpy (the extension loaded as ``vpl_gi``), at its own
    resolution or at ``percentage``."""
    register_extension()
    import bpy
    from vpl_gi.operators.scene.extract import extract
    bpy.ops.wm.open_mainfile(filepath=str(path))
    if percentage is not None:
        bpy.context.scene.render.resolution_percentage = percentage
    scene, _ = extract(bpy.context.evaluated_depsgraph_get())
    return scene


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scene", nargs="?", default=str(ROOT / "example_blends" / "cornell_area.blend"))
    ap.add_argument("--candidates", type=int, default=1_000_000)
    ap.add_argument("--lights", type=int, default=100_000)
    ap.add_argument("--photons", type=int, default=10_000_000)
    args = ap.parse_args()
    scene = load_scene(args.scene)
    from vpl_gi.vpl_addon.core.tracer import Tracer
    from vpl_gi.vpl_addon.lights import LightSet
    from vpl_gi.vpl_addon.methods import MethodContext, MethodSettings, place
    from vpl_gi.vpl_addon.methods.vbnl import PATHS_PER_BATCH, candidates, open_reach, photon_batches, split_photons
    from vpl_gi.vpl_addon.methods.vbnl.photon_lights import ALPHA, PhotonLights
    from vpl_gi.vpl_addon.methods.vbnl.sample_elimination import eliminate

    rng = np.random.default_rng(0)
    tracer = Tracer(scene.triangles)
    lights_in_scene = LightSet(scene)
    print(f"{os.path.basename(args.scene)}, {os.cpu_count()} cores, load {os.getloadavg()[0]:.1f}")
    for _ in range(2):  # the first loads the compiled kernels
        context = MethodContext(scene, tracer, lights_in_scene, rng, scene.max_bounces)
        t = time.perf_counter()
        _, info = place("vbnl", context, MethodSettings())
        seconds = time.perf_counter() - t
    print(f"placement at the defaults: {seconds:.2f} s (" +
          ", ".join(f"{stage} {s:.2f}" for stage, s in info["seconds"].items()) + ")")
    t = time.perf_counter()
    position, normal = candidates(scene, tracer, args.candidates, rng)
    print(f"candidates from the camera: {len(position):,} in {time.perf_counter() - t:.2f} s")
    t = time.perf_counter()
    kept = eliminate(position, args.lights, rng)
    print(f"adaptive sample elimination {len(position):,} -> {len(kept.keep):,}: {time.perf_counter() - t:.2f} s")
    at, facing, radius = position[kept.keep], normal[kept.keep], ALPHA * kept.r_max
    t = time.perf_counter()
    reach = open_reach(at, facing, radius, tracer)
    print(f"the lights' reach ({reach.size * 2:,} rays): {time.perf_counter() - t:.2f} s")
    lights = PhotonLights(at, facing, radius, np.zeros((len(kept.keep), 3)), reach=reach)
    context = MethodContext(scene, tracer, lights_in_scene, rng, scene.max_bounces)
    bounces = max(scene.max_bounces, 1)
    counted = []

    def counting(batches):
        for photons in batches:
            counted.append(len(photons))
            yield photons

    with ThreadPoolExecutor(tracer.threads) as tracing:
        pilot = next(photon_batches(context, PATHS_PER_BATCH, (0, 0), tracing))  # photons per path, not timed
        paths = -(-int(args.photons * PATHS_PER_BATCH / len(pilot)) // PATHS_PER_BATCH) * PATHS_PER_BATCH
        t = time.perf_counter()
        split_photons(lights, counting(photon_batches(context, paths, (1, 2), tracing)), bounces, tracer)
        seconds = time.perf_counter() - t
    print(f"photon splitting of {sum(counted):,} photons ({paths:,} light paths, {bounces} bounce groups) among "
          f"{len(lights):,} lights, traced and split on {tracer.threads} threads: {seconds:.2f} s")
    tracer.close()


if __name__ == "__main__":
    main()
