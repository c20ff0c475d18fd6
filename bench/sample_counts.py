"""Camera and light samples per pixel for the best picture per second (issue 23: "camera/light sample counts chosen
by the bench for the best error at equal time rather than fixed"; issue 26: direct light is most of a default render).

Each scene renders with its own settings (the default method and its budget), denoised as F12 does, over a grid of
camera samples x light samples per camera sample (x vbnl's pairs x its lights and light paths, if given), for
several seeds; a row gives the mean wall time of ``render`` and
the mean rMAE of Combined against the scene's converged Cycles reference, denoised and as rendered (``Noisy Image``),
then the denoised one's rMAE in 4 x 4 blocks and, where the scene has a twin reference, its clean rRMSE (both
references' noise taken out; ``evaluation.metrics.clean_rrmse``).

    .venv/bin/python bench/sample_counts.py [cornell_area,cornell_sun,...] [--samples 16,64] [--light-samples 1,2,4,8]
        [--pairs 16,64] [--lights 4096/262144,8192/1048576] [--seeds 2] [--percentage 50]

A name is an example scene (``example_blends/NAME.blend``, committed reference) or a converted scene
(``scenes/NAME.blend``, whose reference at ``--percentage`` is rendered once and cached as the bench does).
"""
from __future__ import annotations

import argparse
import dataclasses
import sys

import numpy as np

from vbnl_stages import ROOT, load_scene, register_extension


def blend_path(name: str) -> str:
    for folder in ("example_blends", "scenes"):
        path = ROOT / folder / f"{name}.blend"
        if path.exists():
            return str(path)
    raise SystemExit(f"no scene {name!r} in example_blends/ or scenes/")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("scenes", nargs="?", default="cornell_area,cornell_point,cornell_sun,cornell_textured,corridor")
    ap.add_argument("--samples", default="4,16,64", help="camera samples per pixel, comma-separated")
    ap.add_argument("--light-samples", default="1,2,4,8", help="light samples per camera sample, comma-separated")
    ap.add_argument("--pairs", default=None, help="vbnl's sample pairs per pixel, comma-separated (default: the "
                    "scene's; 0: one per camera sample)")
    ap.add_argument("--lights", default=None, help="VPLs / vbnl light paths, comma-separated pairs such as "
                    "4096/262144,8192/1048576 (default: the scene's)")
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--percentage", type=int, default=None, help="render (and reference) resolution percentage")
    ap.add_argument("--reference-samples", type=int, default=1024)
    args = ap.parse_args(argv)
    print("| scene | camera x light samples | vbnl pairs | VPLs / light paths | seconds | rMAE denoised | "
          "rMAE as rendered | block rMAE | clean rRMSE |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for name in args.scenes.split(","):
        blend = blend_path(name)
        register_extension()
        import bpy
        from vpl_gi.bench.runner import Options, engine_run, reference_for, twin_for
        from vpl_gi.vpl_addon.core import passes as P
        from vpl_gi.vpl_addon.evaluation.metrics import clean_rrmse, coverage_mask, errors
        from vpl_gi.vpl_addon.render import render
        options = Options([], [], {}, "")
        bpy.ops.wm.open_mainfile(filepath=blend)
        pct = None if args.percentage in (None, bpy.context.scene.render.resolution_percentage) else args.percentage
        reference, _ = reference_for(blend, pct, options.reference_dir, options.cache_dir, args.reference_samples,
                                     print)
        scene = load_scene(blend, pct)
        _, twin = twin_for(blend, pct, options.reference_dir)
        reference = reference[P.COMBINED]
        mask = coverage_mask(reference[..., 3], reference.shape[:2])
        base = dataclasses.replace(bpy.context.scene.vpl_gi.render_settings((P.COMBINED, P.NOISY_IMAGE)),
                                   denoise=True)
        render(scene, dataclasses.replace(base, samples=1, light_samples=1))  # warm-up: kernels, caches
        vbnl = base.placement.vbnl
        budgets = [tuple(map(int, b.split("/"))) for b in args.lights.split(",")] if args.lights else \
            [(base.placement.vpls, vbnl.photons)]
        grid = [(s, n, p, b) for s in map(int, args.samples.split(",")) for n in map(int, args.light_samples.split(","))
                for p in (map(int, args.pairs.split(",")) if args.pairs else [vbnl.sampling.samples]) for b in budgets]
        for samples, light_samples, pairs, (vpls, photons) in grid:
            placement = dataclasses.replace(base.placement, vpls=vpls, vbnl=dataclasses.replace(
                vbnl, photons=photons, sampling=dataclasses.replace(vbnl.sampling, samples=pairs)))
            rows = []
            for seed in range(args.seeds):
                settings = dataclasses.replace(base, samples=samples, light_samples=light_samples, seed=seed,
                                               placement=placement)
                wall, result, _ = engine_run(scene, settings)
                image = result.passes[P.COMBINED]
                found = errors(image, reference, mask)
                clean = clean_rrmse(image, reference, twin, mask) if twin is not None else np.nan
                rows.append((wall, found["rmae"], errors(result.passes[P.NOISY_IMAGE], reference, mask)["rmae"],
                             found["rmae4"], clean))
            wall, denoised, noisy, blocks, clean = np.mean(rows, axis=0)
            print(f"| {name} | {samples} x {light_samples} | {pairs or samples} | {vpls} / {photons} | {wall:.2f} | "
                  f"{denoised:.4f} | "
                  f"{noisy:.4f} | {blocks:.4f} | {clean:.4f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
