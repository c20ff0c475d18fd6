"""Flat squares in every light pass (issue 70): for each example and converted scene at its own size, each method
at the render defaults with denoise off, the number of flat 2t x 2t windows (``evaluation.flat_blocks``, t the
gather's interleave tile) in each light pass, over seeds. The filter once left such a square wherever it spread a
rare bright sample over its window; the table should hold zeros.

    .venv/bin/python bench/flat_blocks.py [--scenes cornell_area,helmet_hdri] [--methods ir,vbnl] [--seeds 2]
        [--csv out/bench/flat_blocks.csv]

The converted scenes are those ``make scenes`` writes to scenes/; a scene name is looked up there, then in
example_blends/.
"""
from __future__ import annotations

import argparse
import csv
import os
import pathlib
import sys

ROOT = pathlib.Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))
from vbnl_stages import load_scene  # noqa: E402
from vpl_addon.core import passes as P  # noqa: E402
from vpl_addon.evaluation.flat_blocks import flat_blocks  # noqa: E402
from vpl_addon.methods import METHODS  # noqa: E402
from vpl_addon.render import RenderSettings, render  # noqa: E402

LIGHT_PASSES = (P.DIFFUSE_DIRECT, P.DIFFUSE_INDIRECT, P.GLOSSY_DIRECT, P.GLOSSY_INDIRECT, P.EMIT, P.ENVIRONMENT)
STILLS = sorted(p.stem for p in (ROOT / "example_blends").glob("*.blend") if not p.stem.startswith("seq_"))


def scene_file(name: str) -> pathlib.Path:
    for folder in ("scenes", "example_blends"):
        path = ROOT / folder / f"{name}.blend"
        if path.exists():
            return path
    raise SystemExit(f"no scene {name!r} in scenes/ or example_blends/ (make scenes writes the converted ones)")


def main(argv=None) -> int:
    converted = sorted(p.stem for p in (ROOT / "scenes").glob("*.blend"))
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", default=",".join(STILLS + converted))
    ap.add_argument("--methods", default=",".join(METHODS))
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--csv", default=str(ROOT / "out" / "bench" / "flat_blocks.csv"))
    args = ap.parse_args(argv)
    rows = []
    print("| scene | size | method | " + " | ".join(LIGHT_PASSES) + " |\n| --- | --- | --- |" +
          " --- |" * len(LIGHT_PASSES))
    for name in args.scenes.split(","):
        scene = load_scene(scene_file(name))
        size = f"{scene.camera.width} x {scene.camera.height}"
        for method in args.methods.split(","):
            counts = dict.fromkeys(LIGHT_PASSES, 0)
            for seed in range(args.seeds):
                settings = RenderSettings(method=method, seed=seed, denoise=False, passes=LIGHT_PASSES)
                passes = render(scene, settings).passes
                for pass_name in LIGHT_PASSES:
                    counts[pass_name] += len(flat_blocks(passes[pass_name], 2 * settings.gather.interleave))
            rows.append({"scene": name, "size": size, "method": method, "seeds": args.seeds, **counts})
            print(f"| {name} | {size} | {method} | " + " | ".join(str(counts[n]) for n in LIGHT_PASSES) + " |",
                  flush=True)
    os.makedirs(os.path.dirname(args.csv), exist_ok=True)
    with open(args.csv, "w", newline="") as f:
        writer = csv.DictWriter(f, ["scene", "size", "method", "seeds", *LIGHT_PASSES])
        writer.writeheader()
        writer.writerows(rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
