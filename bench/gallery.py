"""Side-by-side pictures for the documentation: each scene rendered with the add-on's defaults (denoised), by
Cycles at the samples whose time comes nearest ours, and by Cycles + OpenImageDenoise at those samples, the wall
time and the rMAE of Combined against a converged Cycles reference under each, written as
``docs/images/<scene>.png`` with its figures in ``docs/images/<scene>.json``.

    .venv/bin/python bench/gallery.py SCENE.blend [SCENE.blend ...] [--percentage 50] [--reference-samples 1024]
        [--out docs/images]

Each renderer runs once before it is timed (libraries, kernels and caches loaded, as in ``bench``). Cycles' samples
are found by doubling from 4 until its time passes ours; the one nearer in time is shown. The images are tone
mapped alike (Blender's Standard view: clipped, sRGB) so that they compare as a user sees them.
"""
from __future__ import annotations

import argparse
import json
import os
import pathlib
import sys
import tempfile

import numpy as np

from vbnl_stages import register_extension
from vpl_addon.core.color import linear_to_srgb  # noqa: E402 (vbnl_stages puts the project on the path)
from vpl_addon.core.compiled import cache_root  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parent.parent


def _srgb(image: np.ndarray) -> np.ndarray:
    """(H,W,3) linear RGB as 8-bit-ready sRGB in [0, 1] (Blender's Standard view transform)."""
    return linear_to_srgb(np.clip(np.nan_to_num(image[..., :3], nan=0.0), 0.0, 1.0))


def ours(bpy, blend: str, percentage: int | None) -> tuple[float, np.ndarray]:
    """(wall seconds, Combined) of a render with the scene's VPL GI settings, its defaults where unset."""
    from vpl_gi.bench.runner import ENGINE_PASSES, engine_run
    from vpl_gi.operators.scene.extract import extract
    scene = _opened(bpy, blend, percentage)
    built, _ = extract(bpy.context.evaluated_depsgraph_get())
    settings = scene.vpl_gi.render_settings(ENGINE_PASSES)
    engine_run(built, settings)  # warm-up
    wall, result, _ = engine_run(built, settings)
    return wall, result.passes["Combined"]


def cycles(bpy, blend: str, percentage: int | None, wall: float, folder: str) -> list[dict]:
    """Cycles and Cycles + OIDN at the samples whose time is nearest ``wall``: two rows of label, samples,
    seconds and Combined."""
    from vpl_gi.bench.runner import cycles_run
    _opened(bpy, blend, percentage)
    cycles_run(bpy.context.scene, 4, True, folder)  # warm-up
    tried, spp = [], 4
    while True:
        seconds, images, _ = cycles_run(_opened(bpy, blend, percentage), spp, False, folder)
        tried.append((abs(np.log(seconds / wall)), spp, seconds, images["Combined"]))
        if seconds > wall or spp >= 4096:
            break
        spp *= 2
    _, spp, seconds, plain = min(tried, key=lambda t: t[0])
    seconds_oidn, denoised, _ = cycles_run(_opened(bpy, blend, percentage), spp, True, folder)
    return [{"label": f"Cycles, {spp} spp", "samples": spp, "seconds": seconds, "image": plain},
            {"label": f"Cycles + OIDN, {spp} spp", "samples": spp, "seconds": seconds_oidn,
             "image": denoised["Combined"]}]


def _opened(bpy, blend: str, percentage: int | None):
    bpy.ops.wm.open_mainfile(filepath=os.path.abspath(blend))
    scene = bpy.context.scene
    if percentage is not None:
        scene.render.resolution_percentage = percentage
    return scene


def picture(rows: list[dict], out: str) -> None:
    """The rows side by side, each with its label, seconds and rMAE under it, as ``out``."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    height, width = rows[0]["image"].shape[:2]
    fig, axes = plt.subplots(1, len(rows), figsize=(3.2 * len(rows) * width / max(height, width) + 0.4, 3.6))
    for ax, row in zip(axes, rows):
        ax.imshow(_srgb(row["image"]), interpolation="nearest")
        ax.set_axis_off()
        figures = f"{row['seconds']:.1f} s" + (f", rMAE {row['rmae']:.3f}" if "rmae" in row else "")
        ax.set_title(f"{row['label']}\n{figures}", fontsize=9)
    fig.tight_layout()
    fig.savefig(out, dpi=110, bbox_inches="tight")
    plt.close(fig)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scenes", nargs="+")
    ap.add_argument("--percentage", type=int, help="render at this share of each scene's resolution")
    ap.add_argument("--reference-samples", type=int, default=1024)
    ap.add_argument("--out", default=str(ROOT / "docs" / "images"))
    args = ap.parse_args()
    register_extension()
    import bpy
    from vpl_gi.bench.runner import reference_for
    from vpl_gi.vpl_addon.evaluation.metrics import coverage_mask, errors
    os.makedirs(args.out, exist_ok=True)
    for blend in args.scenes:
        name = pathlib.Path(blend).stem
        _opened(bpy, blend, None)
        pct = args.percentage if args.percentage != bpy.context.scene.render.resolution_percentage else None
        reference, source = reference_for(blend, pct, str(ROOT / "tests" / "references"), cache_root(),
                                          args.reference_samples, print)
        wall, image = ours(bpy, blend, pct)
        with tempfile.TemporaryDirectory() as folder:
            rows = [{"label": "VPL GI, defaults", "seconds": wall, "image": image},
                    *cycles(bpy, blend, pct, wall, folder)]
        ref = reference["Combined"]
        mask = coverage_mask(ref[..., 3], ref.shape[:2])
        for row in rows:
            row["rmae"] = errors(row["image"], ref, mask)["rmae"]
        picture(rows, os.path.join(args.out, f"{name}.png"))
        figures = {"scene": name, "size": [int(ref.shape[1]), int(ref.shape[0])], "reference": source,
                   "rows": [{k: v for k, v in row.items() if k != "image"} for row in rows]}
        with open(os.path.join(args.out, f"{name}.json"), "w") as f:
            json.dump(figures, f, indent=1)
        print(name, f"{ref.shape[1]}x{ref.shape[0]}:",
              "; ".join(f"{r['label']}: {r['seconds']:.2f} s, rMAE {r['rmae']:.4f}" for r in rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
