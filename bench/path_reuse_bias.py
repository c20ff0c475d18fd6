"""Is path reuse (Moreau et al., ``path_verification``) unbiased? Over many seeds, the VPL flux that kept-and-verified
light paths leave after one change is compared with that of paths traced afresh in the changed scene, per bounce
and per cell of a 6 x 5 x 4 grid over the room of ``tests/engine/methods/test_path_verification.py`` (a floor,
a wall, a 0.4 m block, a lamp at 2.5 m). No Blender, no images: the flux sums are exact functions of the paths.

    .venv/bin/python bench/path_reuse_bias.py --change block [--seeds 600] [--threshold 0.001]
    .venv/bin/python bench/path_reuse_bias.py --change lamp            # a 0.05 m sphere lamp moved by 0.1 m

Prints the mean flux per bounce of both and its standard error, chi^2 per cell of the difference (about 1
when unbiased), and the variance over seeds of the reused flux against the fresh one's.
"""
from __future__ import annotations

import argparse
import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path[:0] = [ROOT, os.path.join(ROOT, "tests"), os.path.join(ROOT, "tests", "engine", "methods")]

from test_path_verification import room_with_block, room_with_lamp  # noqa: E402
from vpl_addon.core.tracer import Tracer  # noqa: E402
from vpl_addon.lights import LightSet  # noqa: E402
from vpl_addon.paths.light_paths import trace_until  # noqa: E402
from vpl_addon.sequence.motion import Motion, Snapshot  # noqa: E402
from vpl_addon.sequence.path_verification import LightPathStore  # noqa: E402

LO, HI, CELLS = np.array([-3.0, -3.0, 0.0]), np.array([3.0, 2.0, 4.0]), np.array([6, 5, 4])


def histogram(vpls) -> np.ndarray:
    """Flux (sum of intensities) per grid cell and bounce (1, 2, 3+)."""
    cell = np.clip(((vpls.position - LO) / (HI - LO) * CELLS).astype(int), 0, CELLS - 1)
    index = (np.ravel_multi_index(tuple(cell.T), tuple(CELLS)) * 3 + np.minimum(vpls.bounce, 3) - 1)
    return np.bincount(index, vpls.intensity.sum(axis=1), int(CELLS.prod()) * 3)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--change", choices=("block", "lamp"), default="block")
    p.add_argument("--seeds", type=int, default=600)
    p.add_argument("--threshold", type=float, default=1e-3)
    p.add_argument("--vpls", type=int, default=2000)
    args = p.parse_args(argv)
    before, after = (room_with_block(0.0), room_with_block(0.3)) if args.change == "block" else \
        (room_with_lamp(0.0), room_with_lamp(0.1))
    boxes = Motion.between(Snapshot.of(before), Snapshot.of(after)).boxes
    tb, ta = Tracer(before.triangles), Tracer(after.triangles)
    reused, fresh, rays = [], [], []
    for seed in range(args.seeds):
        store = LightPathStore()
        store.trace(before, tb, LightSet(before), args.vpls, np.random.default_rng(seed), 3)
        full = store.rays_last_frame
        store.update(after, ta, LightSet(after), boxes, np.random.default_rng(10 ** 6 + seed), 3, 1e-6,
                     args.threshold)
        rays.append((store.rays_last_frame, full))
        reused.append(histogram(store.vpls))
        vpls, _ = trace_until(after, ta, LightSet(after), args.vpls, np.random.default_rng(2 * 10 ** 6 + seed), 3)
        fresh.append(histogram(vpls))
    tb.close()
    ta.close()
    reused, fresh = np.array(reused), np.array(fresh)
    n = len(reused)
    print(f"{args.change}, T = {args.threshold:g}, {n} seeds, {args.vpls} VPLs: light-path rays per update "
          f"{np.mean([r for r, _ in rays]):.0f}, a full trace {np.mean([f for _, f in rays]):.0f}")
    for bounce in (1, 2, 3):
        a, b = reused[:, bounce - 1::3].sum(axis=1), fresh[:, bounce - 1::3].sum(axis=1)
        se = np.sqrt(a.var() / n + b.var() / n)
        print(f"bounce {bounce}: reused {a.mean():.3f}, fresh {b.mean():.3f}, difference "
              f"{(a.mean() - b.mean()) / se:+.1f} standard errors")
    se = np.sqrt(reused.var(axis=0) / n + fresh.var(axis=0) / n)
    lit = fresh.mean(axis=0) > 0
    chi2 = (((reused.mean(axis=0) - fresh.mean(axis=0)) / np.where(se > 0, se, 1.0)) ** 2)[lit].mean()
    print(f"chi^2 per cell: {chi2:.2f} over {lit.sum()} cells; variance over seeds, reused / fresh: "
          f"{reused.var(axis=0)[lit].sum() / fresh.var(axis=0)[lit].sum():.3f}")


if __name__ == "__main__":
    main()
