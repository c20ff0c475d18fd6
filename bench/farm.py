"""Bakes on a Dask farm (``bake --workers N``, ``operators/cli/farm.py``): wall time against one process, the chunk size,
and the seams where chunks meet, on the 24-frame example sequences.

    .venv/bin/python bench/farm.py [--percentage 50] [--chunk-sizes 4,6,8,12] [--workers 2] [--out out/farm]

For each sequence method (smc on ``seq_moving_light.blend``, ir with path reuse on ``seq_moving_object.blend``):

* one bake in one process (``bake --frames 1:24``), its wall time;
* the farm bake (``--workers 2``) at each chunk size, its wall time, checked byte for byte against the one-process
  bake (chunks continue the sequence's state, ``bake.place_only``);
* cold chunks, the farm before this change: each chunk baked as a bake of its own (it starts cold, smc warming up
  again, ir tracing new light paths), which is also what ``blender -b -s A -e B -a`` per chunk gives;
* Hedman et al.'s |E'| (the change of the Reinhard tone-mapped luminance error of ``Diffuse Indirect`` from one frame
  to the next, ``evaluation.temporal``) over the whole frame, per transition against per-frame Cycles references
  (cached in the output folder), averaged over the transitions into a chunk's first frame (boundaries) and over the
  others (inside), for the cold chunks and the farm.

Prints Markdown tables and writes ``results.json`` in the output folder. Wall times are only worth reading on an
otherwise idle machine.
"""
from __future__ import annotations

import argparse
import filecmp
import json
import os
import shutil
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

RUNS = {"smc": ("seq_moving_light", ["--method", "smc"]),
        "path reuse (ir)": ("seq_moving_object", ["--method", "ir"])}


def cli(*args) -> tuple[str, float]:
    """``python -m vpl_addon ARGS``: its output and wall seconds."""
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "vpl_addon", *map(str, args)], cwd=ROOT, capture_output=True,
                          text=True, env={**os.environ, "PYTHONPATH": ROOT})
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(map(str, args))} failed: {proc.stderr.strip()[-2000:]}")
    return proc.stdout, time.perf_counter() - t0


def transitions(folder: str, references: str, frames: range) -> dict[int, float]:
    """|E'| of the whole frame (``temporal_errors``) of each transition f-1 -> f of the bake in ``folder``."""
    from vpl_addon.core import passes as P
    from vpl_addon.core.exr import read_passes
    from vpl_addon.evaluation.temporal import sequence_mask, temporal_errors
    name = P.DIFFUSE_INDIRECT
    images = [read_passes(os.path.join(folder, f"frame_{f:04d}.exr"))[0][name] for f in frames]
    refs = [read_passes(os.path.join(references, f"frame_{f:04d}.exr"))[0] for f in frames]
    mask = sequence_mask([r[P.COMBINED][..., 3] for r in refs], refs[0][name].shape[:2])
    return {f: temporal_errors(images[i - 1:i + 1], [refs[i - 1][name], refs[i][name]], mask)["frame"]["E_prime"]
            for i, f in enumerate(frames) if i > 0}


def seams(per_transition: dict[int, float], starts: set[int]) -> dict:
    boundary = [v for f, v in per_transition.items() if f in starts]
    inside = [v for f, v in per_transition.items() if f not in starts]
    b, i = sum(boundary) / len(boundary), sum(inside) / len(inside)
    return {"boundary": b, "inside": i, "ratio": b / i}


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--frames", default="1:24")
    p.add_argument("--percentage", type=int, default=50)
    p.add_argument("--vpls", type=int, default=1024)
    p.add_argument("--samples", type=int, default=4)
    p.add_argument("--light-samples", type=int, default=4)
    p.add_argument("--reference-samples", type=int, default=256)
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--chunk-sizes", default="4,6,8,12", help="farm runs; the seams are measured at the first")
    p.add_argument("--methods", default=",".join(RUNS), help=f"comma-separated, of: {', '.join(RUNS)}")
    p.add_argument("--out", default=os.path.join(ROOT, "out", "farm"))
    args = p.parse_args(argv)
    first, last = (int(v) for v in args.frames.split(":"))
    frames = range(first, last + 1)
    sizes = [int(s) for s in args.chunk_sizes.split(",")]
    common = ["--percentage", args.percentage, "--vpls", args.vpls, "--samples", args.samples, "--light-samples",
              args.light_samples]
    results = {}
    for label in args.methods.split(","):
        stem, flags = RUNS[label]
        scene = os.path.join(ROOT, "example_blends", f"{stem}.blend")
        refs = os.path.join(args.out, f"{stem}_{args.percentage}pct_references_{args.reference_samples}spp")
        os.makedirs(refs, exist_ok=True)
        for f in frames:
            target = os.path.join(refs, f"frame_{f:04d}.exr")
            if not os.path.exists(target):
                cli("reference", scene, "--frame", f, "--samples", args.reference_samples, "--percentage",
                    args.percentage, "-o", target)
        base = os.path.join(args.out, f"{stem}_{label.split()[0]}")
        shutil.rmtree(base, ignore_errors=True)
        run = {"frames": args.frames}
        _, run["one_process_s"] = cli("bake", scene, "--frames", args.frames, "-o", f"{base}/whole", *flags, *common)
        run["farm_s"], run["identical"] = {}, {}
        for size in sizes:
            folder = f"{base}/farm_{size}"
            _, run["farm_s"][size] = cli("bake", scene, "--frames", args.frames, "-o", folder, *flags, *common,
                                         "--workers", args.workers, "--chunk-size", size)
            run["identical"][size] = all(filecmp.cmp(f"{base}/whole/frame_{f:04d}.exr",
                                                     f"{folder}/frame_{f:04d}.exr", shallow=False) for f in frames)
            print(f"{label}: farm, chunks of {size}: {run['farm_s'][size]:.1f} s (one process "
                  f"{run['one_process_s']:.1f} s), identical: {run['identical'][size]}", flush=True)
        size = sizes[0]
        cold = f"{base}/cold_{size}"
        os.makedirs(cold)
        for start in range(first, last + 1, size):
            chunk = f"{base}/cold_chunk_{start}"
            cli("bake", scene, "--frames", f"{start}:{min(start + size - 1, last)}", "-o", chunk, *flags, *common)
            for name in os.listdir(chunk):
                if name.startswith("frame_"):
                    os.replace(os.path.join(chunk, name), os.path.join(cold, name))
            shutil.rmtree(chunk)
        starts = set(range(first + size, last + 1, size))
        run["seams"] = {"chunk_size": size,
                        "cold chunks": seams(transitions(cold, refs, frames), starts),
                        "farm": seams(transitions(f"{base}/farm_{size}", refs, frames), starts)}
        results[label] = run
        print(json.dumps(run["seams"]), flush=True)
    with open(os.path.join(args.out, "results.json"), "w") as f:
        json.dump(results, f, indent=1)

    print(f"\n{args.frames}, {args.percentage} %, {args.vpls} VPLs, {args.samples} spp, {args.workers} workers\n")
    columns = [f"{args.workers} workers, chunks of {s}: s (speed-up)" for s in sizes]
    print("| method | one process s | " + " | ".join(columns) + " | farm frames = one process's |")
    print("|---|---|" + "---|" * len(sizes) + "---|")
    for label, run in results.items():
        print(f"| {label} | {run['one_process_s']:.1f} | " + " | ".join(
            f"{run['farm_s'][s]:.1f} ({run['one_process_s'] / run['farm_s'][s]:.2f}x)" for s in sizes)
            + f" | {'yes' if all(run['identical'].values()) else 'NO'} |")
    print(f"\n|E'| of the whole frame at chunk boundaries and inside chunks (chunks of {sizes[0]}), against Cycles "
          f"{args.reference_samples} spp per frame\n")
    print("| method | bake | |E'| at boundaries | |E'| inside | boundaries / inside |")
    print("|---|---|---|---|---|")
    for label, run in results.items():
        for kind, s in run["seams"].items():
            if kind != "chunk_size":
                print(f"| {label} | {kind} | {s['boundary']:.4f} | {s['inside']:.4f} | {s['ratio']:.2f} |")


if __name__ == "__main__":
    main()
