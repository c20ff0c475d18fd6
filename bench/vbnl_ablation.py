"""Ablation of Virtual Blue Noise Lighting as in the paper's Fig. 18, at our scale: rMAE of ``Diffuse Indirect``
against the committed Cycles reference, and wall time, for no / uniform / adaptive sample elimination, each with
and without camera path extension, over gather samples per pixel; bidir at two VPL budgets for comparison.
Indirect light only (no direct-light samples), 16 camera samples per pixel.

    .venv/bin/python bench/vbnl_ablation.py [--scenes cornell_area,corridor] [--samples 4,16,64] [--csv PATH]
"""
from __future__ import annotations

import argparse
import csv
import os
import pathlib
import sys
import time

ROOT = pathlib.Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "bench"))
from vbnl_stages import load_scene  # noqa: E402


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--scenes", default="cornell_area,corridor")
    ap.add_argument("--samples", default="4,16,64", help="vbnl gather samples per pixel")
    ap.add_argument("--bidir-vpls", default="1024,4096")
    ap.add_argument("--csv", default=str(ROOT / "out" / "bench" / "vbnl_ablation.csv"))
    args = ap.parse_args()
    rows = []
    for name in args.scenes.split(","):
        scene = load_scene(ROOT / "example_blends" / f"{name}.blend")
        from vpl_gi.vpl_addon.core import passes as P
        from vpl_gi.vpl_addon.core.exr import read_passes
        from vpl_gi.vpl_addon.evaluation.metrics import coverage_mask, errors
        from vpl_gi.vpl_addon.methods import MethodSettings
        from vpl_gi.vpl_addon.methods.vbnl import VBNLSettings
        from vpl_gi.vpl_addon.methods.vbnl.virtual_light_sampling import SamplingSettings
        from vpl_gi.vpl_addon.render import RenderSettings, render
        ref, _ = read_passes(str(ROOT / "tests" / "references" / f"{name}.exr"))
        mask = coverage_mask(ref[P.COMBINED][..., 3], ref[P.COMBINED].shape[:2])
        runs = [("bidir", "-", "-", int(v), dict(method="bidir", placement=MethodSettings(vpls=int(v))))
                for v in args.bidir_vpls.split(",")]
        for elimination in ("none", "uniform", "adaptive"):
            for extension in (False, True):
                for spp in map(int, args.samples.split(",")):
                    vbnl = VBNLSettings(elimination=elimination,
                                        sampling=SamplingSettings(samples=spp, extension=extension))
                    runs.append(("vbnl", elimination, "on" if extension else "off", spp,
                                 dict(method="vbnl", placement=MethodSettings(vbnl=vbnl))))
        for method, elimination, extension, budget, kw in runs:
            settings = RenderSettings(samples=16, light_samples=0, passes=(P.COMBINED, P.DIFFUSE_INDIRECT), **kw)
            t = time.perf_counter()
            result = render(scene, settings)
            wall = time.perf_counter() - t
            e = errors(result.passes[P.DIFFUSE_INDIRECT], ref[P.DIFFUSE_INDIRECT], mask)
            row = dict(scene=name, method=method, elimination=elimination, extension=extension, budget=budget,
                       seconds=round(wall, 2), rmae=round(e["rmae"], 4), mean_ratio=round(e["mean_ratio"], 4),
                       load=round(os.getloadavg()[0], 1))
            rows.append(row)
            print(" | ".join(str(v) for v in row.values()), flush=True)
    os.makedirs(os.path.dirname(args.csv), exist_ok=True)
    with open(args.csv, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    print(f"wrote {args.csv}")


if __name__ == "__main__":
    main()
