"""Slow: every converted public scene through ``python -m vpl_addon bench`` with every engine method and Cycles at
a small resolution, against a Cycles reference rendered (and cached by hash) when missing. Minutes per scene on 2
cores: `make test-all` and the benchmark runs, not CI.

The assertions are the ones a broken conversion or a broken method on a real scene would fail: every method and
Cycles produce finite errors, rays and a peak memory; Cycles converges towards the reference; and each engine
method's mean Diffuse Indirect at its largest budget is near Cycles': within 25 % on the scenes whose materials the
engine represents exactly (diffuse only), within [0.4, 2.5] on the others (their dielectric specular and transmission are missing from
the engine, and the environment map is a constant; a light unit off by pi or 4 pi, an emitter on the wrong side or a camera looking elsewhere
still falls outside). Known engine issues are xfail with their reason, so a fix shows up as XPASS."""
from __future__ import annotations

import csv
import math

import pytest

from conftest import ROOT, run_cli

SHARED = ROOT.parent / "shared" / "scenes"
SCENES = ("cornell_measured", "cornell_bitterli", "veach_bidir", "veach_ajar", "veach_ajar_diffuse", "living_room")
EXACT = {"cornell_measured", "cornell_bitterli", "veach_ajar_diffuse"}  # diffuse-only materials
KNOWN: dict[tuple[str, str], str] = {}  # (scene, method) -> reason; vbnl's living-room leak is fixed (SLAB)
pytestmark = [pytest.mark.slow, pytest.mark.blender,
              pytest.mark.skipif(not SHARED.is_dir(), reason="../shared/scenes is not beside the repository")]


@pytest.fixture(scope="module")
def converted():
    code, out, err = run_cli("scenes", "--source", SHARED, "--out", ROOT / "scenes", timeout=1200)
    assert code == 0, err
    return ROOT / "scenes"


@pytest.mark.parametrize("name", SCENES)
def test_every_method_and_cycles_on_the_converted_scene(converted, name, tmp_path):
    code, out, err = run_cli("bench", converted / f"{name}.blend", "--methods", "ir,bidir,vbnl,cycles",
                             "--percentage", 25, "--budgets", "ir=256,1024", "--budgets", "bidir=256,1024",
                             "--budgets", "vbnl=1,4", "--budgets", "cycles=4,64", "--reference-samples", 1024,
                             "--time-cap", 120, "--out", tmp_path, timeout=3600)
    assert code == 0, err
    with open(tmp_path / "bench.csv") as f:
        rows = list(csv.DictReader(f))
    methods = {r["method"] for r in rows}
    assert methods == {"ir", "bidir", "vbnl", "cycles"}
    for r in rows:
        assert math.isfinite(float(r["rmae"])) and float(r["wall_s"]) > 0, r
        assert float(r["peak_rss_mb"]) > 0, r
        if r["method"] != "cycles":
            assert int(r["rays"]) > 0, r
    indirect = {(r["method"], int(r["budget"])): r for r in rows if r["pass"] == "Diffuse Indirect"}
    assert float(indirect[("cycles", 64)]["rmae"]) < float(indirect[("cycles", 4)]["rmae"])
    low, high = (0.75, 1.33) if name in EXACT else (0.4, 2.5)
    failed = []
    for method in ("ir", "bidir", "vbnl"):
        largest = max(b for (m, b) in indirect if m == method)
        ratio = float(indirect[(method, largest)]["mean_ratio"])
        if not low <= ratio <= high:
            failed.append(f"{method}: mean Diffuse Indirect {ratio:.3f} x Cycles'")
    known = [KNOWN[(name, f.split(':')[0])] for f in failed if (name, f.split(":")[0]) in KNOWN]
    if failed and len(known) == len(failed):
        pytest.xfail("; ".join(known))
    assert not failed, (failed, {k: (v["rmae"], v["mean_ratio"]) for k, v in indirect.items()})
