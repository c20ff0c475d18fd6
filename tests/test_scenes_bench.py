"""Slow: every converted public scene through ``python -m vpl_addon bench`` with every engine method and Cycles at
a small resolution, against a Cycles reference rendered (and cached by hash) when missing. Minutes per scene on 2
cores: `make test-all` and the benchmark runs, not CI.

The assertions are the ones a broken conversion or a broken method on a real scene would fail: every method and
Cycles produce finite errors, rays and a peak memory; Cycles converges towards the reference; and each engine
method's Diffuse Indirect is within a loose bound of Cycles' (wrong light units, a camera looking elsewhere or an
emitter on the wrong side give an rMAE near or above 1)."""
from __future__ import annotations

import csv
import math

import pytest

from conftest import ROOT, run_cli

SHARED = ROOT.parent / "shared" / "scenes"
SCENES = ("cornell_measured", "cornell_bitterli", "veach_bidir", "veach_ajar", "living_room")
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
    indirect = {(r["method"], int(r["budget"])): float(r["rmae"]) for r in rows if r["pass"] == "Diffuse Indirect"}
    assert indirect[("cycles", 64)] < indirect[("cycles", 4)]
    for method in ("ir", "bidir", "vbnl"):
        best = min(v for (m, _), v in indirect.items() if m == method)
        assert best < 0.8, (method, best, indirect)
