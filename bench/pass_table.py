"""Every light pass against Cycles (issue 70): for each example scene with a committed reference
(``tests/references``) and each converted scene (``make scenes``; Cycles renders it at ``CONVERTED`` % with every
light pass, cached by hash), each method at the render defaults with denoise off, and each light pass both hold,
the mean ratio on the pixels where Cycles defines the pass, the per-pixel rMAE, the rMAE of 8 x 8-block means
(which the reference's own fireflies disturb less) and the mean ratio of the light the pass gives Combined (the
pass times its colour, ``_light_ratio``). Passes a reference lacks are listed as such, so the table says which
comparisons it cannot make.

    .venv/bin/python bench/pass_table.py [--scenes cornell_area,living_room] [--methods ir,vbnl] [--seeds 2]
        [--reference-samples 4096] [--csv out/bench/pass_table.csv]
"""
from __future__ import annotations

import argparse
import csv
import os
import pathlib
import sys

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))
from vbnl_stages import load_scene, register_extension  # noqa: E402
from vpl_addon.core import passes as P  # noqa: E402
from vpl_addon.core.exr import read_passes  # noqa: E402
from vpl_addon.evaluation.metrics import DIVIDED_BY, block_means, coverage_mask, errors, pass_mask  # noqa: E402
from vpl_addon.render import RenderSettings, render  # noqa: E402

LIGHT_PASSES = (P.DIFFUSE_DIRECT, P.DIFFUSE_INDIRECT, P.GLOSSY_DIRECT, P.GLOSSY_INDIRECT, P.EMIT, P.ENVIRONMENT)
BLOCK = 8
# each scene's committed reference and the resolution percentage it was rendered at
REFERENCES = {"cornell_area": ("cornell_area.exr", None), "cornell_point": ("cornell_point.exr", None),
              "cornell_sun": ("cornell_sun.exr", None), "cornell_textured": ("cornell_textured.exr", None),
              "corridor": ("corridor.exr", None), "cornell_metal": ("cornell_metal.exr", None),
              "cornell_pbr": ("cornell_pbr_50pct.exr", 50)}
CONVERTED = 50  # the converted scenes' resolution percentage
# Cycles' samples of a converted scene where ``--reference-samples`` is not enough: the helmet's ground caustics
# (at 4096 samples its Diffuse Indirect is 12 % above the 16384-sample render's, one pixel at 185)
SAMPLES = {"helmet_hdri": 16384}
CACHE = pathlib.Path.home() / ".cache" / "vpl_gi"


def reference_of(name: str, samples: int) -> tuple[dict, pathlib.Path, int | None]:
    """(reference passes, .blend, resolution percentage) of scene ``name``: an example's committed reference, or a
    converted scene's Cycles render at ``samples`` (``reference.make_reference``, cached by hash)."""
    if name in REFERENCES:
        file, percentage = REFERENCES[name]
        return read_passes(str(ROOT / "tests" / "references" / file))[0], ROOT / "example_blends" / f"{name}.blend", \
            percentage
    blend = ROOT / "scenes" / f"{name}.blend"
    register_extension()
    from vpl_gi.operators.output.reference import make_reference
    out = CACHE / f"{name}-{CONVERTED}pct-passes.exr"
    CACHE.mkdir(parents=True, exist_ok=True)
    make_reference(str(blend), str(out), max(samples, SAMPLES.get(name, 0)), None, str(CACHE), CONVERTED)
    return read_passes(str(out))[0], blend, CONVERTED


def pass_rows(scene_name: str, method: str, ours: list[dict], ref: dict) -> list[dict]:
    """One row per light pass: the mean over seeds of each figure, or why there is none."""
    full = coverage_mask(ref[P.COMBINED][..., 3], ref[P.COMBINED].shape[:2])
    rows = []
    for name in LIGHT_PASSES:
        row = {"scene": scene_name, "method": method, "pass": name}
        if name not in ref:
            rows.append({**row, "note": "not in the reference"})
            continue
        # the world where the camera sees it: at the pixels the film leaves open, which full coverage leaves out
        mask = np.ones_like(full) if name == P.ENVIRONMENT else pass_mask(name, ref, full)
        if not mask.any():
            rows.append({**row, "note": "Cycles defines it at no pixel (no surface of its kind)"})
            continue
        if not ref[name][..., :3][mask].any():
            level = np.mean([image[name][..., :3][mask].mean() for image in ours])
            rows.append({**row, "note": f"zero in Cycles; ours {level:.2g} in the mean"})
            continue
        found = [errors(image[name], ref[name], mask) for image in ours]
        whole = block_means(mask[..., None].astype(float), BLOCK)[..., 0] >= 1.0
        blocks = [errors(block_means(image[name][..., :3], BLOCK), block_means(ref[name][..., :3], BLOCK), whole)
                  ["rmae"] for image in ours] if whole.any() else [np.nan]  # nan: no whole block
        rows.append({**row, "mean_ratio": np.mean([f["mean_ratio"] for f in found]),
                     "rmae": np.mean([f["rmae"] for f in found]), "rmae_8x8": np.mean(blocks),
                     "light_ratio": np.mean([_light_ratio(name, image, ref, full) for image in ours]), "note": ""})
    return rows


def _light_ratio(name: str, image: dict, ref: dict, full: np.ndarray) -> float:
    """The mean of the light the pass gives Combined (times its colour, ``metrics.DIVIDED_BY``) over Cycles':
    unlike the pass's own mean, it does not count the pixels where few camera samples found the pass's kind of
    surface, whose pass is then 0 (Cycles' convention for 0 / 0) while the reference's is not."""
    color = DIVIDED_BY.get(name)
    if color is None:
        return float("nan")
    ours, theirs = (i[name][..., :3] * i[color][..., :3] for i in (image, ref))
    return float(ours[full].mean() / max(theirs[full].mean(), 1e-30))


def _figure(value: float) -> str:
    return f"{value:.3f}" if np.isfinite(value) else "n/a"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    converted = sorted(p.stem for p in (ROOT / "scenes").glob("*.blend"))
    ap.add_argument("--scenes", default=",".join([*REFERENCES, *converted]))
    ap.add_argument("--reference-samples", type=int, default=4096, help="Cycles' samples of a converted scene")
    ap.add_argument("--methods", default="ir,vbnl")
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--csv", default=str(ROOT / "out" / "bench" / "pass_table.csv"))
    args = ap.parse_args(argv)
    rows = []
    print("| scene | method | pass | mean ratio | rMAE | rMAE 8x8 | light x colour ratio |\n"
          "| --- | --- | --- | --- | --- | --- | --- |")
    for scene_name in args.scenes.split(","):
        ref, blend, percentage = reference_of(scene_name, args.reference_samples)
        scene = load_scene(blend, percentage)
        assert (scene.camera.height, scene.camera.width) == ref[P.COMBINED].shape[:2], f"{scene_name}: another size"
        for method in args.methods.split(","):
            ours = [render(scene, RenderSettings(method=method, seed=seed, passes=P.ALL)).passes
                    for seed in range(args.seeds)]
            for row in pass_rows(scene_name, method, ours, ref):
                rows.append(row)
                figures = " | ".join(_figure(row[k]) for k in ("mean_ratio", "rmae", "rmae_8x8", "light_ratio")) \
                    if not row["note"] else f"{row['note']} | | |"
                print(f"| {scene_name} | {method} | {row['pass']} | {figures} |", flush=True)
    os.makedirs(os.path.dirname(args.csv), exist_ok=True)
    with open(args.csv, "w", newline="") as f:
        writer = csv.DictWriter(f, ["scene", "method", "pass", "mean_ratio", "rmae", "rmae_8x8", "light_ratio", "note"])
        writer.writeheader()
        writer.writerows(rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
