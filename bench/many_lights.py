"""Direct light with many small lights (issue 23, item 2): how fast ``Diffuse Direct`` converges, in rMAE against
wall seconds, with this tree's light sampler and with a baseline revision's (by default 9142b60, the sampler before
the light tree: a light chosen in proportion to power / distance^2 through a dense samples x lights CDF).

Two scenes made here: ``points``, the stress suite's "two hundred lights" (200 point lights of 1 W at random in a
closed 2 m room), and ``areas``, the same room with a block in it and 160 small one-sided area lights (8 cm squares)
facing random ways, where a light's orientation and shadows matter. Each is rendered (``render``, method "none",
the Diffuse Direct pass only) at several light-sample counts per camera sample and seeds; the baseline runs the same
measurement from its own code, unpacked from git into a temporary folder, in a subprocess, its runs interleaved
with ours so that the machine's load hits both alike.

The reference is our own direct light at ``--reference-samples`` light samples per camera sample, one per scene and
seed: next-event estimation is unbiased, so both samplers converge to it, and with the same seed both render the same
camera samples (the G-buffer is drawn before any light sample), so the error measured is the light sampling's alone.
The gain is the time the baseline needs over the time this tree needs for the same rMAE, at every rMAE either
reached, each sampler's seconds interpolated on its log-log curve of rMAE against seconds; outside the rMAE a sampler
was measured at, from its fitted model (rMAE = A n^B in light samples n, seconds linear in n), marked as such.

    .venv/bin/python bench/many_lights.py --out out/many-lights [--baseline 9142b60] [--res 128] [--seeds 3]
"""
from __future__ import annotations

import argparse
import json
import os
import pathlib
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parent.parent
SCENES = ("points", "areas")


def look_at(eye, target, res):
    """The camera at ``eye`` looking at ``target``, Z up, a 20 mm lens, ``res`` pixels square."""
    from vpl_addon.core.camera import Camera, view_window
    eye, target = np.asarray(eye, float), np.asarray(target, float)
    back = (eye - target) / np.linalg.norm(eye - target)
    right = np.cross([0.0, 0.0, 1.0], back)
    right /= np.linalg.norm(right)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = right, np.cross(back, right), back, eye
    return Camera(m, res, res, view_window(res, res, orthographic=False, lens=20.0), clip_start=1e-6)


def cuboid(lo, hi, inward):
    """(12,3,3) triangles of an axis-aligned box, wound to face in (a room) or out (a block)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    tris = []
    for axis in range(3):
        u, v = (axis + 1) % 3, (axis + 2) % 3
        for side, value in ((-1.0, lo[axis]), (1.0, hi[axis])):
            quad = []
            for a, b in ((0, 0), (1, 0), (1, 1), (0, 1)):
                corner = np.empty(3)
                corner[axis], corner[u], corner[v] = value, (lo, hi)[a][u], (lo, hi)[b][v]
                quad.append(corner)
            if (side > 0) == inward:  # (u, v) order faces +axis: flip to face the other way
                quad = quad[::-1]
            tris += [(quad[0], quad[1], quad[2]), (quad[0], quad[2], quad[3])]
    return np.array(tris)


def scene_of(name, res):
    """The scene ``name`` (``SCENES``) at ``res`` pixels square."""
    from vpl_addon.core.scene import Materials, Scene
    from vpl_addon.lights import AreaLight, PointLight
    rng = np.random.default_rng(1)
    triangles = cuboid([-1, -1, 0], [1, 1, 2], inward=True)
    if name == "points":  # as tests/stress/test_hostile_scenes.py's "two hundred lights"
        lights = [PointLight(f"l{i}", p, [1.0] * 3)
                  for i, p in enumerate(rng.uniform([-0.9, -0.9, 0.1], [0.9, 0.9, 1.9], (200, 3)))]
    else:
        triangles = np.concatenate([triangles, cuboid([-0.3, -0.2, 0.0], [0.3, 0.4, 0.9], inward=False)])
        lights = []
        for i, (p, n) in enumerate(zip(rng.uniform([-0.95, -0.95, 0.05], [0.95, 0.95, 1.95], (160, 3)),
                                       rng.normal(size=(160, 3)))):
            n /= np.linalg.norm(n)
            u = np.cross(n, [0.36, 0.48, 0.8])
            u /= np.linalg.norm(u)
            lights.append(AreaLight(f"a{i}", p, 0.08 * u, 0.08 * np.cross(n, u), n, [2.0] * 3))
    camera = look_at([0.5, -0.9, 1.0], [0.0, 0.5, 0.6], res)
    white = Materials.make([{"name": "white", "base_color": (0.8, 0.8, 0.8)}])
    return Scene.build(triangles, white, lights, camera, material=np.ones(len(triangles), int))


def render_direct(scene, light_samples, camera_samples, seed):
    """(Diffuse Direct (H,W,3), Diffuse Color, coverage, wall seconds) of one render."""
    from vpl_addon.core import passes as P
    from vpl_addon.render import RenderSettings, render
    settings = RenderSettings(samples=camera_samples, light_samples=light_samples, method="none", seed=seed,
                              passes=(P.DIFFUSE_DIRECT, P.DIFFUSE_COLOR))
    start = time.perf_counter()
    out = render(scene, settings).passes
    seconds = time.perf_counter() - start
    return out[P.DIFFUSE_DIRECT], out[P.DIFFUSE_COLOR], out[P.COMBINED][..., 3], seconds


def measure(args):
    """Worker: render one scene at every budget for one seed with the code on sys.path; one JSON line per
    budget."""
    from vpl_addon.evaluation.metrics import coverage_mask, errors, pass_mask
    ref = np.load(args.reference)
    mask = pass_mask("Diffuse Direct", {"Diffuse Color": ref["color"]},
                     coverage_mask(ref["alpha"], ref["direct"].shape[:2]))
    scene = scene_of(args.scene, args.res)
    render_direct(scene, 1, 1, args.seed + 1000)  # warm up: imports, first-call costs
    for budget in map(int, args.light_samples.split(",")):
        direct, _, _, seconds = render_direct(scene, budget, args.camera_samples, args.seed)
        row = dict(scene=args.scene, seed=args.seed, light_samples=budget, seconds=seconds,
                   rmae=errors(direct, ref["direct"], mask)["rmae"], load=os.getloadavg()[0])
        print(json.dumps(row), flush=True)


def worker(code, args, scene, seed, budgets, reference):
    """Run ``measure`` in a subprocess with ``code`` (a source tree) first on the path: its rows."""
    command = [sys.executable, __file__, "--measure", "--scene", scene, "--seed", str(seed), "--res", str(args.res),
               "--camera-samples", str(args.camera_samples), "--light-samples", budgets, "--reference", reference]
    env = dict(os.environ, PYTHONPATH=str(code))
    done = subprocess.run(command, env=env, capture_output=True, text=True, check=True)
    return [json.loads(line) for line in done.stdout.splitlines() if line.startswith("{")]


def reference(scene_name, seed, args, path):
    """Our direct light at ``--reference-samples``, saved to ``path`` (kept between runs)."""
    if not path.exists():
        direct, color, alpha, seconds = render_direct(scene_of(scene_name, args.res), args.reference_samples,
                                                      args.camera_samples, seed)
        np.savez(path, direct=direct, color=color, alpha=alpha)
        print(f"reference {scene_name} seed {seed}: {seconds:.0f} s", flush=True)
    return str(path)


def curve(rows):
    """Per light-sample count n (sorted): mean seconds and mean rMAE over seeds; and the model fitted to them for
    extrapolation: rMAE = A n^B (least squares in log-log) and seconds = t0 + k n (least squares)."""
    budgets = np.array(sorted({r["light_samples"] for r in rows}), float)
    t = np.array([np.mean([r["seconds"] for r in rows if r["light_samples"] == b]) for b in budgets])
    e = np.array([np.mean([r["rmae"] for r in rows if r["light_samples"] == b]) for b in budgets])
    slope, intercept = np.polyfit(np.log(budgets), np.log(e), 1)
    k, t0 = np.polyfit(budgets, t, 1)
    return dict(budgets=budgets, seconds=t, rmae=e, exponent=slope, model=(intercept, slope, t0, k))


def seconds_for(error, c):
    """(seconds the sampler of curve ``c`` needs for rMAE ``error``, True if interpolated between its
    measurements on the log-log curve of rMAE against seconds, False if from its fitted model)."""
    order = np.argsort(c["rmae"])
    if c["rmae"].min() <= error <= c["rmae"].max():
        return float(np.exp(np.interp(np.log(error), np.log(c["rmae"][order]), np.log(c["seconds"][order])))), True
    intercept, slope, t0, k = c["model"]
    return float(t0 + k * np.exp((np.log(error) - intercept) / slope)), False


def report(name, rows, args):
    """The table of one scene (markdown) and the gains: at each rMAE either sampler reached, the baseline's
    seconds over ours."""
    curves = {who: curve([r for r in rows if r["scene"] == name and r["sampler"] == who])
              for who in ("baseline", "ours")}
    lines = [f"### {name}: {args.res}x{args.res} px, {args.camera_samples} camera samples, mean of {args.seeds} seeds",
             "", "| light samples | baseline s | baseline rMAE | ours s | ours rMAE |", "|---|---|---|---|---|"]
    old, new = curves["baseline"], curves["ours"]
    for i, b in enumerate(old["budgets"]):
        j = np.nonzero(new["budgets"] == b)[0]
        ours = f"{new['seconds'][j[0]]:.2f} | {new['rmae'][j[0]]:.4f}" if len(j) else "- | -"
        lines.append(f"| {int(b)} | {old['seconds'][i]:.2f} | {old['rmae'][i]:.4f} | {ours} |")
    lines += ["", f"rMAE ~ n^{old['exponent']:.2f} (baseline), n^{new['exponent']:.2f} (ours) in light samples n", "",
              "| rMAE | baseline s | ours s | gain |", "|---|---|---|---|"]
    gains = []
    for error in sorted(set(old["rmae"]) | set(new["rmae"]), reverse=True):
        (t_old, in_old), (t_new, in_new) = seconds_for(error, old), seconds_for(error, new)
        gains.append((t_old / t_new, in_old and in_new))
        cells = [f"{t:.2f}" if inside else f"({t:.2f})" for t, inside in ((t_old, in_old), (t_new, in_new))]
        lines.append(f"| {error:.4f} | {cells[0]} | {cells[1]} | {t_old / t_new:.1f}x |")
    both = [g for g, inside in gains if inside]
    lines += ["", "(seconds in brackets: from the sampler's fitted model, outside its measured rMAE)",
              f"gain where both curves were measured: {', '.join(f'{g:.1f}x' for g in both) or 'none (no overlap)'}"]
    best = np.argmin(old["rmae"])
    below = np.nonzero(new["rmae"] <= old["rmae"][best])[0]
    if len(below):  # measured only: the baseline's most accurate run against our first run at least as accurate
        i = below[np.argmin(new["seconds"][below])]
        lines.append(f"without any model: ours reaches rMAE {new['rmae'][i]:.4f} in {new['seconds'][i]:.2f} s, the "
                     f"baseline {old['rmae'][best]:.4f} in {old['seconds'][best]:.2f} s: at least "
                     f"{old['seconds'][best] / new['seconds'][i]:.1f}x")
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default=str(ROOT / "out" / "many-lights"))
    ap.add_argument("--baseline", default="9142b60", help="git revision of the sampler to compare with")
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--res", type=int, default=128)
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--camera-samples", type=int, default=4)
    ap.add_argument("--light-samples", default="1,2,4,8,16", help="ours, per camera sample")
    ap.add_argument("--baseline-light-samples", default="1,2,4,8,16,32,64")
    ap.add_argument("--reference-samples", type=int, default=512)
    ap.add_argument("--measure", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--scene", help=argparse.SUPPRESS)
    ap.add_argument("--seed", type=int, default=0, help=argparse.SUPPRESS)
    ap.add_argument("--reference", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.measure:
        return measure(args)
    sys.path.insert(0, str(ROOT))
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = {"ours": [], "baseline": []}
    with tempfile.TemporaryDirectory() as old:
        archive = subprocess.run(["git", "-C", str(ROOT), "archive", args.baseline, "vpl_addon"], capture_output=True,
                                 check=True).stdout
        subprocess.run(["tar", "-x", "-C", old], input=archive, check=True)
        for name in args.scenes.split(","):
            for seed in range(args.seeds):
                ref = reference(name, seed, args, out / f"reference-{name}-{args.res}-{seed}.npz")
                for who, code, budgets in (("baseline", old, args.baseline_light_samples),
                                           ("ours", ROOT, args.light_samples)):
                    for row in worker(code, args, name, seed, budgets, ref):
                        rows[who].append(dict(row, sampler=who))
                        print(" | ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}"
                                         for k, v in rows[who][-1].items()), flush=True)
    with open(out / "many_lights.json", "w") as f:
        json.dump(rows["baseline"] + rows["ours"], f, indent=1)
    loads = [r["load"] for r in rows["ours"] + rows["baseline"]]
    text = "\n\n".join(report(name, rows["baseline"] + rows["ours"], args) for name in args.scenes.split(","))
    text += f"\n\nload (1-minute average) during the runs: {min(loads):.1f}-{max(loads):.1f} on {os.cpu_count()} cores"
    (out / "many_lights.md").write_text(text + "\n")
    print("\n" + text + f"\nwrote {out / 'many_lights.json'} and {out / 'many_lights.md'}")


if __name__ == "__main__":
    main()
