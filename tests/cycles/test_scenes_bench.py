"""Slow: every converted public scene through ``python -m vpl_addon bench`` with every engine method and Cycles at
a small resolution, against a Cycles reference rendered (and cached by hash) when missing. Minutes per scene on 2
cores: `make test-all` and the benchmark runs, not CI.

The assertions are the ones a broken conversion or a broken method on a real scene would fail: every method and
Cycles produce finite errors, rays and a peak memory; Cycles converges towards the reference; and each engine
method's mean Diffuse Indirect at its largest budget is near Cycles': within 25 % on the scenes whose materials the
engine represents exactly (diffuse only; the hotel room's textured Principled materials at roughness 1), within
[0.4, 2.5] on the others (rough conductors and plastics approximated, glass as thin glass; a light unit off by pi or
4 pi, an emitter on the wrong side or a camera looking elsewhere still falls outside). On the helmet, whose Diffuse
Indirect is the sun's caustics, Combined is judged instead. Known engine issues are xfail with their reason, so a
fix shows up as XPASS."""
from __future__ import annotations

import csv
import math

import pytest

from conftest import ROOT, pass_errors, run_cli

SHARED = ROOT.parent / "shared" / "scenes"
SCENES = ("cornell_measured", "cornell_bitterli", "veach_bidir", "veach_ajar", "veach_ajar_diffuse", "living_room",
          "helmet_hdri", "hotel_room", "veach_mis", "cornell_usd", "cornell_obj")
EXACT = {"cornell_measured", "cornell_bitterli", "veach_ajar_diffuse", "hotel_room", "cornell_usd", "cornell_obj"}
# no 1024-spp image of the helmet's caustics is converged (Cycles' Diffuse Indirect rMAE rises from 4 to 64 spp)
CAUSTIC = {"helmet_hdri"}
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
    judged = "Combined" if name in CAUSTIC else "Diffuse Indirect"
    indirect = {(r["method"], int(r["budget"])): r for r in rows if r["pass"] == judged}
    assert float(indirect[("cycles", 64)]["rmae"]) < float(indirect[("cycles", 4)]["rmae"])
    low, high = (0.75, 1.33) if name in EXACT | CAUSTIC else (0.4, 2.5)
    failed = []
    for method in ("ir", "bidir", "vbnl"):
        largest = max(b for (m, b) in indirect if m == method)
        ratio = float(indirect[(method, largest)]["mean_ratio"])
        if not low <= ratio <= high:
            failed.append(f"{method}: mean {judged} {ratio:.3f} x Cycles'")
    known = [KNOWN[(name, f.split(':')[0])] for f in failed if (name, f.split(":")[0]) in KNOWN]
    if failed and len(known) == len(failed):
        pytest.xfail("; ".join(known))
    assert not failed, (failed, {k: (v["rmae"], v["mean_ratio"]) for k, v in indirect.items()})


def test_helmet_under_the_hdri_matches_cycles(converted, tmp_path):
    """Issue 21: the glTF helmet (every PBR map) on a ground plane under the HDR's sun, 128 x 128, vbnl at 64 spp
    against Cycles at 8192 spp (cached): Diffuse Direct's mean within 2 % and its rMAE within 1.5x of Cycles' at equal
    samples (the sun's shadow and the helmet's normal-mapped shading where Cycles puts them); Combined's mean within
    2 % over two seeds (the ground's caustics from the metal make any single 64-spp draw, Cycles' included, vary by a
    few per cent)."""
    blend = converted / "helmet_hdri.blend"
    ref, cycles = tmp_path / "ref.exr", tmp_path / "cycles.exr"
    for out, samples in ((ref, 8192), (cycles, 64)):
        code, _, err = run_cli("reference", blend, "-o", out, "--samples", samples, "--percentage", 50,
                               timeout=1800)
        assert code == 0, err
    combined = []
    for seed in (0, 1):
        ours = tmp_path / f"ours{seed}.exr"
        code, _, err = run_cli("render", blend, "-o", ours, "--method", "vbnl", "--samples", 64, "--seed", seed,
                               "--percentage", 50, timeout=1800)
        assert code == 0, err
        combined.append(pass_errors(ours, ref, "Combined")["mean_ratio"])
        if seed == 0:
            direct, theirs = pass_errors(ours, ref), pass_errors(cycles, ref)
            assert abs(direct["mean_ratio"] - 1) < 0.02, direct
            assert direct["rmae"] < 1.5 * theirs["rmae"], (direct, theirs)
    assert abs(sum(combined) / len(combined) - 1) < 0.02, combined


def test_no_light_pass_of_the_helmet_holds_a_flat_square(converted, ext):
    """Issue 70: the helmet under its HDR at its own 256 px, every method at the defaults with denoise off: no flat
    2t x 2t window (``evaluation.flat_blocks``) in any light pass. The filter once spread the sun's rare glints on
    the ground, and their faint tails on its dark far side, into such squares."""
    import bpy
    from vpl_gi.operators.scene.extract import extract
    from vpl_gi.vpl_addon.evaluation.flat_blocks import flat_blocks
    from vpl_gi.vpl_addon.methods import METHODS
    from vpl_gi.vpl_addon.render import RenderSettings, render
    bpy.ops.wm.open_mainfile(filepath=str(converted / "helmet_hdri.blend"))
    scene, _ = extract(bpy.context.evaluated_depsgraph_get())
    light = ("Diffuse Direct", "Diffuse Indirect", "Glossy Direct", "Glossy Indirect", "Emit", "Environment")
    found = {}
    for method in METHODS:
        settings = RenderSettings(method=method, denoise=False, passes=light)
        passes = render(scene, settings).passes
        found[method] = {name: len(flat_blocks(passes[name], 2 * settings.gather.interleave)) for name in light}
        assert passes["Diffuse Indirect"][..., :3].mean() > 0.0
    assert not any(n for counts in found.values() for n in counts.values()), found
