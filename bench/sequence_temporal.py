"""Temporal error of animation bakes against per-frame Cycles references (Hedman et al., Table 1): |E| and |E'|
after Reinhard tone mapping, tracked pixels and whole frame, for each method baked over the same frames at the same
VPL budget.

    .venv/bin/python bench/sequence_temporal.py [--scene example_blends/seq_moving_light.blend] [--frames 1:24]
        [--run LABEL=METHOD[ FLAGS] ...] [--vpls 1024] [--reference-samples 256] [--seeds 1] [--out out/sequence]

    e.g. the path reuse of ir on the moving block:
    .venv/bin/python bench/sequence_temporal.py --scene example_blends/seq_moving_object.blend \\
        --run reuse=ir --run "retrace=ir --no-path-reuse"

``--picture`` judges the finished picture instead (issue 23): every run is baked with ``--denoise`` and compared on
``Combined``, next to Cycles + OpenImageDenoise rendered frame by frame at the first run's time per frame (its
samples per pixel from a timed trial on the first frame), the rival a user would animate with: a denoiser that works
frame by frame flickers where a converged indirect does not.

References are rendered once per frame through ``python -m vpl_addon reference`` and cached by hash (the default
cache ~/.cache/vpl_gi); bakes go through ``python -m vpl_addon bake`` (so a method that keeps state, smc, carries it;
ir keeps its light paths and re-traces those that moved objects cut, the others place their lights again in
every frame in which something moved). Prints a Markdown table and
writes ``results.json`` in the output folder. ``--seeds N`` bakes every run with placement seeds 0..N-1 and reports
the per-frame rMAE averaged over the seeds (a single draw's rMAE at 1024 VPLs varies by about 15 % per frame).
"""
from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)


def cli(*args):
    proc = subprocess.run([sys.executable, "-m", "vpl_addon", *map(str, args)], cwd=ROOT, capture_output=True,
                          text=True, env={**os.environ, "PYTHONPATH": ROOT})
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(map(str, args))} failed: {proc.stderr.strip()}")
    return proc.stdout


def _mean_over_seeds(results: list[dict]) -> dict:
    """One run's results averaged over its seeds, frame by frame (the per-seed results kept under "seeds")."""
    if len(results) == 1:
        return results[0]
    mean = lambda values: sum(values) / len(values)  # noqa: E731
    out = {"seeds": results, "bake_seconds": mean([r["bake_seconds"] for r in results]),
           "rmae_per_frame": [mean(v) for v in zip(*(r["rmae_per_frame"] for r in results))],
           "light_path_rays": [mean(v) for v in zip(*(r["light_path_rays"] for r in results))]}
    for part in ("tracked", "frame"):
        out[part] = {k: mean([r[part][k] for r in results]) for k in ("E", "E_prime")}
    return out


def cycles_oidn_frames(scene: str, frames: range, seconds: float, folder: str, percentage: int | None) -> dict:
    """Cycles + OIDN (the reference's settings, denoiser on) rendered frame by frame into ``folder`` at about
    ``seconds`` a frame (scene sync and EXR write included, as in the bench): samples per pixel scaled from timed
    trials of the first frame (16 spp, then the scaled count, up to three times, since a render's fixed costs make
    time grow slower than samples). Returns the samples and the mean seconds a frame."""
    from vpl_addon.__main__ import PACKAGE, extension_package
    extension_package()
    import importlib
    runner = importlib.import_module(f"{PACKAGE}.bench.runner")
    cli_module = importlib.import_module(f"{PACKAGE}.operators.cli.scene_flags")
    cli_module.ensure_registered()
    import bpy

    def opened(frame):
        cli_module.open_blend(scene)
        if percentage:
            bpy.context.scene.render.resolution_percentage = percentage
        bpy.context.scene.frame_set(frame)
        return bpy.context.scene

    os.makedirs(folder, exist_ok=True)
    spp = 16
    for _ in range(3):
        trial, _, _ = runner.cycles_run(opened(frames[0]), spp, True, folder)
        scaled = max(1, round(spp * seconds / trial))
        if abs(scaled - spp) <= 0.1 * spp:
            break
        spp = scaled
    walls = []
    for frame in frames:
        wall, images, _ = runner.cycles_run(opened(frame), spp, True, folder)
        walls.append(wall)
        os.replace(os.path.join(folder, "cycles.exr"), os.path.join(folder, f"frame_{frame:04d}.exr"))
    return {"samples": spp, "seconds_per_frame": sum(walls) / len(walls)}


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scene", default=os.path.join(ROOT, "example_blends", "seq_moving_light.blend"))
    p.add_argument("--frames", default="1:24")
    p.add_argument("--run", action="append", metavar="LABEL=METHOD[ FLAGS]",
                   help="a bake to measure, e.g. 'retrace=ir --no-path-reuse' (repeatable; default smc and bidir)")
    p.add_argument("--vpls", type=int, default=1024)
    p.add_argument("--samples", type=int, default=4)
    p.add_argument("--light-samples", type=int, default=4)
    p.add_argument("--reference-samples", type=int, default=256)
    p.add_argument("--percentage", type=int, help="resolution percentage of references and bakes (default: the "
                                                   "scene's)")
    p.add_argument("--seeds", type=int, default=1, help="bake each run with seeds 0..N-1 and average per frame")
    p.add_argument("--extra", default="", help="more bake flags, e.g. '--smc-warmup 20'")
    p.add_argument("--picture", action="store_true",
                   help="bake denoised and judge Combined, next to Cycles + OIDN at the first run's time per frame")
    p.add_argument("--out", default=os.path.join(ROOT, "out", "sequence"))
    args = p.parse_args(argv)
    first, last = (int(v) for v in args.frames.split(":"))
    stem = os.path.splitext(os.path.basename(args.scene))[0]
    refs = os.path.join(args.out, f"{stem}_references_{args.reference_samples}spp")
    os.makedirs(refs, exist_ok=True)
    t0 = time.perf_counter()
    for frame in range(first, last + 1):
        target = os.path.join(refs, f"frame_{frame:04d}.exr")
        if not os.path.exists(target):
            cli("reference", args.scene, "--frame", frame, "--samples", args.reference_samples, "-o", target,
                *(["--percentage", args.percentage] if args.percentage else []))
    print(f"references: {time.perf_counter() - t0:.0f} s", flush=True)

    from vpl_addon.evaluation.compare import compare_sequences
    judged = "Combined" if args.picture else "Diffuse Indirect"
    results = {}
    runs = args.run or ["smc=smc", "bidir=bidir"]
    for run in runs:
        label, _, spec = run.partition("=")
        method, *flags = spec.split()
        per_seed = []
        for seed in range(args.seeds):
            folder = os.path.join(args.out, f"{stem}_{label}_{args.vpls}" + (f"_seed{seed}" if args.seeds > 1 else ""))
            shutil.rmtree(folder, ignore_errors=True)  # a fresh bake (the same settings would resume the old one)
            t0 = time.perf_counter()
            log = cli("bake", args.scene, "--frames", args.frames, "-o", folder, "--method", method, "--vpls",
                      args.vpls, "--samples", args.samples, "--light-samples", args.light_samples, "--overwrite",
                      *flags, *(["--seed", seed] if args.seeds > 1 else []), *args.extra.split(),
                      *(["--denoise"] if args.picture else []),
                      *(["--percentage", args.percentage] if args.percentage else []))
            seconds = time.perf_counter() - t0
            result = compare_sequences(folder, refs, [judged])[judged]
            result["bake_seconds"] = round(seconds, 1)
            result["log"] = log.splitlines()
            result["light_path_rays"] = [int(m.group(1)) for m in re.finditer(r"light paths \((\d+) rays\)", log)]
            per_seed.append(result)
            print(f"{label} seed {seed}: {seconds:.0f} s", flush=True)
        results[label] = _mean_over_seeds(per_seed)
    if args.picture:
        frames = range(first, last + 1)
        first_run = next(iter(results.values()))
        folder = os.path.join(args.out, f"{stem}_cycles_oidn")
        shutil.rmtree(folder, ignore_errors=True)
        rival = cycles_oidn_frames(args.scene, frames, first_run["bake_seconds"] / len(frames), folder,
                                   args.percentage)
        result = compare_sequences(folder, refs, [judged])[judged]
        result["bake_seconds"] = round(rival["seconds_per_frame"] * len(frames), 1)
        result["light_path_rays"] = []
        label = f"cycles+oidn {rival['samples']} spp"
        results[label] = result
        print(f"{label}: {rival['seconds_per_frame']:.2f} s a frame", flush=True)
    with open(os.path.join(args.out, f"{stem}_results.json"), "w") as f:
        json.dump(results, f, indent=1)
    print(f"\n{stem}, frames {args.frames}, {args.percentage or 100} %, {args.vpls} VPLs, {args.samples} spp, "
          f"Cycles {args.reference_samples} "
          f"spp per frame ({judged}{', denoised' if args.picture else ''}, Reinhard tone mapped luminance)\n")
    print("| run | mean abs E, tracked | mean abs E', tracked | mean abs E, frame | mean abs E', frame | "
          "rMAE (mean of frames) | light-path rays per frame, frames 2.. | bake s |")
    print("|---|---|---|---|---|---|---|---|")
    for label, r in results.items():
        rmae = sum(r["rmae_per_frame"]) / len(r["rmae_per_frame"])
        rays = r["light_path_rays"][1:]
        per_frame = f"{sum(rays) / len(rays):.0f}" if rays else "-"
        print(f"| {label} | {r['tracked']['E']:.4f} | {r['tracked']['E_prime']:.4f} | {r['frame']['E']:.4f} | "
              f"{r['frame']['E_prime']:.4f} | {rmae:.3f} | {per_frame} | {r['bake_seconds']:.0f} |")
    labels = list(results)
    if len(labels) == 2 and all(results[l]["light_path_rays"][1:] for l in labels):
        a, b = (results[l] for l in labels)
        ratio = [rb / max(ra, 1) for ra, rb in zip(a["light_path_rays"][1:], b["light_path_rays"][1:])]
        rel = [ea / eb for ea, eb in zip(a["rmae_per_frame"], b["rmae_per_frame"])]
        print(f"\n{labels[1]} / {labels[0]} light-path rays per frame (frames 2..): mean {sum(ratio) / len(ratio):.1f}x, "
              f"min {min(ratio):.1f}x; rMAE {labels[0]} / {labels[1]} per frame: {min(rel):.3f} .. {max(rel):.3f}")


if __name__ == "__main__":
    main()
