"""Glossy transport on the rough-metal Cornell box (issue 4): vbnl's ``Glossy Indirect`` against Cycles' on the
metal block's pixels, beside bidir, which has no glossy lobe: its "diffuse-only treatment" renders the block as a
diffuse surface of the same colour (metallic set to 0), and its ``Diffuse Indirect`` there stands for the indirect
light the block reflects. Also the glossy direct light and colour, and the frame's diffuse passes.

    .venv/bin/python bench/glossy.py [--scene cornell_metal] [--vbnl-samples 16,64] [--csv PATH]
"""
from __future__ import annotations

import argparse
import copy
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
    ap.add_argument("--scene", default="cornell_metal")
    ap.add_argument("--vbnl-samples", default="16,64", help="vbnl gather sample pairs per pixel")
    ap.add_argument("--bidir-vpls", default="4096,16384")
    ap.add_argument("--csv", default=str(ROOT / "out" / "bench" / "glossy.csv"))
    args = ap.parse_args()
    scene = load_scene(ROOT / "example_blends" / f"{args.scene}.blend")
    from vpl_gi.vpl_addon.core import passes as P
    from vpl_gi.vpl_addon.core.exr import read_passes
    from vpl_gi.vpl_addon.evaluation.metrics import coverage_mask, errors
    from vpl_gi.vpl_addon.methods import MethodSettings
    from vpl_gi.vpl_addon.methods.vbnl import VBNLSettings
    from vpl_gi.vpl_addon.methods.vbnl.virtual_light_sampling import SamplingSettings
    from vpl_gi.vpl_addon.render import RenderSettings, render

    ref, _ = read_passes(str(ROOT / "tests" / "references" / f"{args.scene}.exr"))
    full = coverage_mask(ref[P.COMBINED][..., 3], ref[P.COMBINED].shape[:2])
    metal = full & (ref[P.GLOSSY_COLOR].max(axis=2) > 0.0) & (ref[P.DIFFUSE_COLOR].max(axis=2) == 0.0)
    diffuse_only = copy.deepcopy(scene)
    diffuse_only.materials.metallic[:] = 0.0  # the block as a diffuse surface of its base colour
    runs = [("vbnl", n, scene, dict(method="vbnl", placement=MethodSettings(
        vbnl=VBNLSettings(sampling=SamplingSettings(samples=n))))) for n in map(int, args.vbnl_samples.split(","))]
    runs += [("bidir (diffuse-only)", n, diffuse_only, dict(method="bidir", placement=MethodSettings(vpls=n)))
             for n in map(int, args.bidir_vpls.split(","))]
    rows = []
    for method, budget, target, kw in runs:
        t = time.perf_counter()
        result = render(target, RenderSettings(passes=P.ALL, **kw))
        wall = time.perf_counter() - t
        out = result.passes
        reflected = out[P.GLOSSY_INDIRECT] if method == "vbnl" else out[P.DIFFUSE_INDIRECT]
        g = errors(reflected, ref[P.GLOSSY_INDIRECT], metal)
        row = dict(method=method, budget=budget, seconds=round(wall, 1),
                   glossy_indirect_rmae=round(g["rmae"], 4), glossy_indirect_ratio=round(g["mean_ratio"], 4),
                   metal_pixels=g["pixels"], load=round(os.getloadavg()[0], 1))
        if method == "vbnl":
            for name in (P.GLOSSY_DIRECT, P.GLOSSY_COLOR):
                e = errors(out[name], ref[name], metal)
                row[f"{name.lower().replace(' ', '_')}_ratio"] = round(e["mean_ratio"], 4)
                row[f"{name.lower().replace(' ', '_')}_rmae"] = round(e["rmae"], 4)
            e = errors(out[P.DIFFUSE_INDIRECT], ref[P.DIFFUSE_INDIRECT], full & ~metal)
            row["diffuse_indirect_rmae"], row["diffuse_indirect_ratio"] = round(e["rmae"], 4), round(e["mean_ratio"], 4)
            e = errors(out[P.COMBINED], ref[P.COMBINED], full)
            row["combined_rmae"], row["combined_ratio"] = round(e["rmae"], 4), round(e["mean_ratio"], 4)
        rows.append(row)
        print(" | ".join(f"{k}={v}" for k, v in row.items()), flush=True)
    os.makedirs(os.path.dirname(args.csv), exist_ok=True)
    fields = list(dict.fromkeys(k for r in rows for k in r))
    with open(args.csv, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=fields)
        writer.writeheader()
        writer.writerows(rows)
    print(f"wrote {args.csv}")


if __name__ == "__main__":
    main()
