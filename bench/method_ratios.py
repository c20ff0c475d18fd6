"""Equal-time error ratios between engine methods, read from a ``bench.csv``: how many times lower one method's rMAE is
than a baseline's at the same wall time (log-log interpolation between runs, as ``vpl_addon.evaluation.convergence``
does against Cycles; a time outside either curve is n/a, never extrapolated). Runs of one budget with other seeds
(``bench --seeds``) count as one point, their mean time and mean rMAE (``Curve.of``).

    .venv/bin/python bench/method_ratios.py out/bench_ajar/bench.csv [--baseline ir] [--pass "Diffuse Indirect"]
        [--seconds 5,10,20]
"""
from __future__ import annotations

import argparse
import csv
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from vpl_addon.evaluation import convergence as C  # noqa: E402


def curves(rows, scene, pass_name):
    out = {}
    for method in dict.fromkeys(r["method"] for r in rows if r["scene"] == scene):
        mine = [r for r in rows if r["scene"] == scene and r["method"] == method and r["pass"] == pass_name]
        if mine:
            out[method] = C.Curve.of([float(r["wall_s"]) for r in mine], [float(r["rmae"]) for r in mine],
                                     [int(r["budget"]) for r in mine])
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("csv")
    p.add_argument("--baseline", default="ir")
    p.add_argument("--pass", dest="pass_name", default="Diffuse Indirect")
    p.add_argument("--seconds", default="5,10,20")
    args = p.parse_args(argv)
    with open(args.csv) as f:
        rows = list(csv.DictReader(f))
    times = [float(t) for t in args.seconds.split(",")]
    for scene in dict.fromkeys(r["scene"] for r in rows):
        cs = curves(rows, scene, args.pass_name)
        if args.baseline not in cs:
            continue
        base = cs[args.baseline]
        for method, curve in cs.items():
            if method == args.baseline or method.startswith("cycles"):
                continue
            cells = []
            for t in times:
                eq = C.equal_time({method: curve}, base, t)
                cells.append(f"{t:g} s: " + ("n/a" if eq.ratio is None else
                                             f"{args.baseline} {eq.cycles_error.value:.4f} / {method} "
                                             f"{eq.best_error.value:.4f} = {eq.ratio:.2f}x"))
            print(f"{scene} {args.pass_name}: " + "; ".join(cells))
    return 0


if __name__ == "__main__":
    sys.exit(main())
