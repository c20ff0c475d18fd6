"""The benchmark: its arithmetic on synthetic curves (exact values), midpoint subdivision, and one tiny run of
``python -m vpl_addon bench`` with the real bpy, Cycles and embree (columns, files, finite numbers; no timings)."""
import csv
import math
import shutil

import numpy as np
import pytest

from conftest import EXAMPLES, REFERENCES, plane_scene, run_cli
from test_cli import assert_one_line_error
from vpl_addon.evaluation.convergence import Curve, equal_error, equal_time, error_at, fit_exponent, time_to_error
from vpl_addon.evaluation.subdivision import levels_for, subdivide

# Cycles-like: error halves when time quadruples (error ~ t^-1/2)
CYCLES = Curve.of([1.0, 4.0, 16.0, 64.0], [0.4, 0.2, 0.1, 0.05], [1, 4, 16, 64])
SLOW_START = Curve.of([1.0, 100.0], [0.1, 0.01], [64, 6400])  # error ~ t^-1/2
FAST_FINISH = Curve.of([1.0, 100.0], [0.4, 0.004], [64, 6400])  # error ~ t^-1


def test_error_at_interpolates_log_log_and_refuses_to_extrapolate():
    assert error_at(CYCLES, 2.0).value == pytest.approx(0.4 / math.sqrt(2), rel=1e-12)
    assert error_at(CYCLES, 8.0).value == pytest.approx(0.2 / math.sqrt(2), rel=1e-12)
    assert error_at(CYCLES, 16.0).value == pytest.approx(0.1, rel=1e-12)
    low, high = error_at(CYCLES, 0.5), error_at(CYCLES, 65.0)
    assert low.value is None and "fastest run took 1.00 s" in low.note
    assert high.value is None and "slowest run took 64.00 s" in high.note


def test_curves_are_ordered_by_budget():
    c = Curve.of([4.0, 1.0], [0.2, 0.4], [16, 4])
    assert list(c.budget) == [4, 16] and list(c.seconds) == [1.0, 4.0] and list(c.error) == [0.4, 0.2]


def test_runs_of_one_budget_are_averaged():
    c = Curve.of([3.0, 1.0, 5.0, 2.0], [0.5, 0.1, 0.3, 0.2], [16, 4, 16, 4])  # two seeds of each budget
    assert list(c.budget) == [4, 16]
    assert np.allclose(c.seconds, [1.5, 4.0]) and np.allclose(c.error, [0.15, 0.4])


def test_time_to_error_interpolates_bounds_and_extrapolates_with_a_label():
    inside = time_to_error(CYCLES, 0.25)
    assert inside.value == pytest.approx((0.4 / 0.25) ** 2, rel=1e-12) and inside.note == ""
    beyond = time_to_error(CYCLES, 0.025)
    assert beyond.value == pytest.approx(64.0 * 4.0, rel=1e-12) and "extrapolated" in beyond.note
    already = time_to_error(CYCLES, 0.5)
    assert already.value == 1.0 and "at most" in already.note
    assert time_to_error(CYCLES, 0.025, extrapolate=False).value is None


def test_equal_time_picks_the_best_method_at_each_time():
    ours = {"slow_start": SLOW_START, "fast_finish": FAST_FINISH}
    early = equal_time(ours, CYCLES, 4.0)  # slow_start 0.05, fast_finish 0.1, Cycles 0.2
    assert early.best == "slow_start" and early.ratio == pytest.approx(4.0, rel=1e-12)
    late = equal_time(ours, CYCLES, 64.0)  # slow_start 0.0125, fast_finish 0.00625, Cycles 0.05
    assert late.best == "fast_finish" and late.ratio == pytest.approx(8.0, rel=1e-12)
    outside = equal_time(ours, CYCLES, 200.0)
    assert outside.best is None and outside.ratio is None


def test_equal_error_speedup():
    ee = equal_error({"fast_finish": FAST_FINISH}, CYCLES, 64.0)
    # target 0.4 / 64; Cycles ends at 0.05 after 64 s -> 64 * (0.05 / 0.00625)^2 s, extrapolated
    assert ee.target.value == pytest.approx(0.4 / 64, rel=1e-12)
    assert ee.cycles_time.value == pytest.approx(64.0 * 64.0, rel=1e-12) and "extrapolated" in ee.cycles_time.note
    assert ee.speedup == pytest.approx(64.0, rel=1e-12)
    measured = equal_error({"slow_start": SLOW_START}, CYCLES, 4.0)  # target 0.05: Cycles at 64 s
    assert measured.speedup == pytest.approx(16.0, rel=1e-12) and measured.cycles_time.note == ""


def test_fit_exponent():
    x = np.array([1e4, 4e4, 1.6e5, 6.4e5])
    assert fit_exponent(x, 3.0 * x ** 0.25) == pytest.approx(0.25, abs=1e-12)
    assert fit_exponent(x, 2.0 * x) == pytest.approx(1.0, abs=1e-12)


def test_subdivision_quadruples_triangles_and_keeps_the_surface():
    scene = plane_scene()
    finer = subdivide(scene, 2)
    assert len(finer.triangles) == 16 * len(scene.triangles)
    assert finer.surface_area == pytest.approx(scene.surface_area, rel=1e-6)
    assert np.allclose(finer.bounds[0], scene.bounds[0]) and np.allclose(finer.bounds[1], scene.bounds[1])
    assert np.allclose(np.linalg.norm(finer.normals, axis=2), 1.0, atol=1e-6)
    assert np.allclose(finer.geometric_normals, [0, 0, 1])
    assert len(finer.material) == len(finer.uvs) == len(finer.triangles)
    assert levels_for(34) == [4, 5, 6, 7]


@pytest.mark.blender
def test_a_light_cut_into_strips_gives_the_same_light(ext):
    """The scaling bench's light sweep (``split_light``): 10 strips light the floor as the one panel did."""
    from vpl_gi.bench.runner import split_light
    from vpl_gi.vpl_addon.lights.area import AreaLight
    from vpl_gi.vpl_addon.render import RenderSettings, render
    panel = AreaLight("panel", [0.5, 0.0, 2.0], [2.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0], [100.0] * 3)
    scene = plane_scene([panel], res=16)
    strips = split_light(scene, 10)
    assert len(strips.lights) == 10 and np.allclose(sum(s.power for s in strips.lights), panel.power)
    settings = RenderSettings(samples=4, light_samples=16, method="none", passes=("Diffuse Direct",))
    one, ten = (render(s, settings).passes["Diffuse Direct"] for s in (scene, strips))
    assert abs(ten.mean() / one.mean() - 1.0) < 0.02
    assert np.abs(ten - one).max() / one.max() < 0.1


@pytest.mark.blender
def test_bench_cli_tiny_run(ext, tmp_path):
    """The bench's sweep, CSV, plot, headlines and scaling, with the committed 25 % reference and a twin of it
    rendered here (``reference --twin``): the twin's Combined takes the references' noise out of Combined's errors."""
    out, refs = tmp_path / "bench", tmp_path / "references"
    refs.mkdir()
    shutil.copy(REFERENCES / "cornell_area_25pct.exr", refs)
    code, _, stderr = run_cli("reference", EXAMPLES / "cornell_area.blend", "-o", refs / "twin.exr", "--twin",
                              "--percentage", "25", "--samples", "64", "--cache-dir", tmp_path / "cache")
    assert code == 0, stderr
    from vpl_gi.operators.output.reference import TWIN_SEED, stored_info
    from vpl_gi.vpl_addon.core.exr import read_passes
    assert list(read_passes(str(refs / "twin.exr"))[0]) == ["Combined"]
    assert stored_info(str(refs / "twin.exr"))["seed"] == TWIN_SEED
    from vpl_gi.bench.runner import twin_for
    nowhere = tmp_path / "empty"
    nowhere.mkdir()
    found, combined = twin_for(str(EXAMPLES / "cornell_area.blend"), 25, str(nowhere), str(tmp_path / "cache"), 64)
    assert found is not None and np.array_equal(combined, read_passes(str(refs / "twin.exr"))[0]["Combined"])
    assert twin_for(str(EXAMPLES / "cornell_area.blend"), 25, str(nowhere), str(tmp_path / "cache"), 4096) == \
        (None, None)  # the cache holds it at the samples it was rendered with alone
    code, stdout, stderr = run_cli("bench", EXAMPLES / "cornell_area.blend", "--quick", "--scaling",
                                   "--methods", "ir,bidir,ir+oidn,cycles,cycles+oidn", "--out", out,
                                   "--reference-dir", refs)
    assert code == 0, stderr
    from vpl_gi.bench.runner import COLUMNS
    with open(out / "bench.csv", newline="") as f:
        reader = csv.DictReader(f)
        assert tuple(reader.fieldnames) == COLUMNS
        rows = list(reader)
    assert {(r["method"], r["pass"]) for r in rows} == {
        (m, p) for m in ("ir", "bidir", "cycles") for p in ("Diffuse Indirect", "Combined")} | {
        ("cycles+oidn", "Combined"), ("ir+oidn", "Combined")}
    assert {int(r["budget"]) for r in rows if r["method"] == "ir"} == {64, 256}
    assert {int(r["budget"]) for r in rows if r["method"] == "cycles"} == {1, 4}
    for r in rows:
        for column in ("wall_s", "rmae", "relmse", "rmse_reinhard", "mean_ratio", "rmae4", "peak_rss_mb"):
            assert math.isfinite(float(r[column])), (column, r)
        assert (r["clean_rrmse"] != "") == (r["pass"] == "Combined"), r  # the twin has Combined alone
        assert r["width"] == r["height"] == "64"  # --quick: 25 % of 256, the committed 25 % reference
        if r["method"] in ("ir", "bidir"):
            assert int(r["rays"]) > 0 and math.isfinite(float(r["gather_s"]))
    # more VPLs and more samples: lower error on this easy scene
    err = {(r["method"], int(r["budget"])): float(r["rmae"]) for r in rows if r["pass"] == "Diffuse Indirect"}
    assert err["ir", 256] < err["ir", 64] and err["cycles", 4] < err["cycles", 1]
    # ir+oidn is ir with its picture denoised: the same light, less noise (rMAE 0.141 -> 0.108 at 256 VPLs)
    combined = {(r["method"], int(r["budget"])): float(r["rmae"]) for r in rows if r["pass"] == "Combined"}
    assert combined["ir+oidn", 256] < 0.9 * combined["ir", 256]
    clean = {(r["method"], int(r["budget"])): float(r["clean_rrmse"]) for r in rows if r["pass"] == "Combined"}
    assert 0.0 < clean["cycles", 4] < 0.7 * clean["cycles", 1]  # noise: 1/2 at 4x the samples
    assert (out / "cornell_area.png").stat().st_size > 5000
    summary = (out / "summary.txt").read_text()
    assert "relative RMSE with the references' own noise taken out" in summary
    assert summary.count("the references' floor: a perfect image scores about") == 2  # rMAE and block rMAE
    assert "equal time 2 s" in summary and "equal time 30 s" in summary and "equal error" in summary and "against cycles+oidn" in summary
    assert "gather shadow rays" in summary and "% of raw" in summary and "disagree" not in summary
    with open(out / "scaling.csv", newline="") as f:
        scaling = list(csv.DictReader(f))
    assert {r["sweep"] for r in scaling} == {"triangles", "pixels", "vpls", "lights"}
    assert [int(r["count"]) for r in scaling if r["sweep"] == "triangles"] == [34 * 4 ** 4, 34 * 4 ** 5]
    assert [int(r["count"]) for r in scaling if r["sweep"] == "pixels"] == [32 * 32, 64 * 36]
    assert [int(r["count"]) for r in scaling if r["sweep"] == "lights"] == [1, 10]
    assert all(0.0 < float(r["share_of_raw"]) < 2.0 and float(r["peak_rss_mb"]) > 0 for r in scaling)
    assert summary.count("fitted exponent") == 4
    # a second run never replaces the results without --overwrite
    before = (out / "bench.csv").read_bytes()
    code, _, stderr = run_cli("bench", EXAMPLES / "cornell_area.blend", "--quick", "--out", out)
    assert_one_line_error(code, stderr, "--overwrite")
    assert (out / "bench.csv").read_bytes() == before


@pytest.mark.blender
def test_peak_memory_does_not_count_the_heap_earlier_runs_freed(ext):
    from vpl_gi.bench.runner import PeakMemory
    from vpl_gi.vpl_addon.core.memory import status_kb
    start = status_kb("VmRSS") / 1024
    big = np.ones(2_500_000)
    del big  # a freed 20 MB mapping: glibc now serves arrays up to that size from its heap
    chunks, pins = [], []
    for _ in range(40):  # 640 MB of arrays, each pinned in the heap by a small block after it
        chunks.append(np.ones(2_000_000))
        pins.append(bytearray(200_000))
    del chunks
    with PeakMemory() as memory:
        pass
    assert memory.peak_mb - start < 100  # 617 MB without handing the freed heap back


@pytest.mark.blender
def test_bench_runs_each_budget_with_every_seed(tmp_path):
    code, _, stderr = run_cli("bench", EXAMPLES / "cornell_area.blend", "--quick", "--methods", "ir",
                              "--budgets", "ir=64", "--seeds", "2", "--out", tmp_path)
    assert code == 0, stderr
    with open(tmp_path / "bench.csv", newline="") as f:
        rows = [r for r in csv.DictReader(f) if r["pass"] == "Diffuse Indirect"]
    assert sorted(int(r["seed"]) for r in rows) == [0, 1]
    assert rows[0]["rmae"] != rows[1]["rmae"]  # another seed, another draw of VPLs and camera samples


@pytest.mark.blender
def test_bench_rejects_an_unknown_method(tmp_path):
    code, _, stderr = run_cli("bench", EXAMPLES / "cornell_area.blend", "--methods", "ir,photons", "--out", tmp_path)
    assert_one_line_error(code, stderr, "photons")
