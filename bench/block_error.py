"""rMAE of renders against a reference after averaging both over k x k pixel blocks: the reference's own noise
shrinks about k times while a method's bias stays, which separates the two when the reference is not converged
(the bench's rMAE of a method that is better than the reference's noise only measures that noise).

    .venv/bin/python bench/block_error.py REF.exr IMAGE.exr [IMAGE.exr ...] [--pass "Diffuse Indirect"]
        [--blocks 1,2,4,8]
"""
from __future__ import annotations

import argparse
import os
import sys


sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from vpl_addon.core.exr import read_passes  # noqa: E402
from vpl_addon.evaluation.metrics import FULL_COVERAGE, block_means as blocks, errors  # noqa: E402


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("reference")
    p.add_argument("images", nargs="+")
    p.add_argument("--pass", dest="pass_name", default="Diffuse Indirect")
    p.add_argument("--blocks", default="1,2,4,8")
    args = p.parse_args(argv)
    ref, _ = read_passes(args.reference)
    sizes = [int(k) for k in args.blocks.split(",")]
    color = ref.get("Diffuse Color")
    print(f"{args.pass_name} rMAE after k x k block averaging, k = {', '.join(map(str, sizes))}")
    for path in args.images:
        img, _ = read_passes(path)
        cells = []
        for k in sizes:
            full = blocks(ref["Combined"][..., 3:4], k)[..., 0] >= FULL_COVERAGE
            if color is not None and args.pass_name in ("Diffuse Direct", "Diffuse Indirect"):
                full &= blocks((color[..., :3].max(-1, keepdims=True) > 0).astype(float), k)[..., 0] >= 1.0
            cells.append(errors(blocks(img[args.pass_name][..., :3], k), blocks(ref[args.pass_name][..., :3], k),
                                full)["rmae"])
        print(f"  {os.path.basename(path)}: " + ", ".join(f"{c:.4f}" for c in cells))
    return 0


if __name__ == "__main__":
    sys.exit(main())
