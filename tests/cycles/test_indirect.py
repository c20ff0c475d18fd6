"""Indirect light (Instant Radiosity, Bidirectional Instant Radiosity) against converged Cycles references:
``Diffuse Indirect`` in Cycles' meaning at the scene's bounce limit."""
import json
import re

import pytest

from conftest import EXAMPLES, REFERENCES, run_cli

pytestmark = pytest.mark.blender


def render_and_compare(tmp_path, scene, reference, *flags):
    out = tmp_path / f"{scene}-{'-'.join(map(str, flags)).replace('--', '')}.exr"
    code, stdout, stderr = run_cli("render", EXAMPLES / f"{scene}.blend", "-o", out, "--overwrite", *flags)
    assert code == 0, stderr
    code, result, stderr = run_cli("compare", out, REFERENCES / reference, "--passes", "Diffuse Indirect")
    assert code == 0, stderr
    errors = json.loads(result)["Diffuse Indirect"]
    print(f"{scene} {' '.join(map(str, flags))}: rMAE {errors['rmae']:.4f}, mean ratio {errors['mean_ratio']:.4f}"
          f" | {stdout.strip().splitlines()[-1]}")
    return errors, stdout


def test_cornell_box_every_method_at_default_settings(tmp_path):
    """The default method (vbnl) within 0.05 rMAE and 3 % of Cycles' brightness, and more accurate than bidir
    at their defaults (the equal-time comparison is the benchmark's: docs/benchmarks.md)."""
    vbnl, _ = render_and_compare(tmp_path, "cornell_area", "cornell_area.exr")
    bidir, _ = render_and_compare(tmp_path, "cornell_area", "cornell_area.exr", "--method", "bidir")
    ir, _ = render_and_compare(tmp_path, "cornell_area", "cornell_area.exr", "--method", "ir")
    assert vbnl["rmae"] <= 0.05
    assert abs(vbnl["mean_ratio"] - 1) <= 0.03
    assert vbnl["rmae"] < bidir["rmae"] <= 0.08
    assert abs(bidir["mean_ratio"] - 1) <= 0.05
    assert abs(ir["mean_ratio"] - 1) <= 0.10


@pytest.mark.parametrize("method", ["ir", "bidir"])
def test_exact_gather_converges_with_the_budget(tmp_path, method):
    """Every pixel sees every VPL (no interleaving): the error falls as the budget grows (and d_min shrinks)."""
    rmae = [render_and_compare(tmp_path, "cornell_area", "cornell_area_25pct.exr", "--method", method,
                               "--vpls", budget, "--interleave", 1, "--percentage", 25, "--samples", 16,
                               "--light-samples", 0)[0]["rmae"] for budget in (256, 1024, 4096)]
    assert rmae[0] > rmae[1] > rmae[2]


def test_corridor_camera_driven_methods_beat_ir_where_light_comes_through_a_door(tmp_path):
    """The U-office case of Segovia et al.: at equal VPL budget bidir wins over ir by 2x or more, and the share
    of kept VPLs that came from the camera is reported (their Table 1); vbnl, placed from the camera too, wins
    over bidir."""
    bidir, stdout = render_and_compare(tmp_path, "corridor", "corridor.exr", "--method", "bidir")
    ir, _ = render_and_compare(tmp_path, "corridor", "corridor.exr", "--method", "ir")
    vbnl, _ = render_and_compare(tmp_path, "corridor", "corridor.exr", "--method", "vbnl")
    share = re.search(r"\((\d+) % reverse\)", stdout)
    assert share, stdout
    print(f"corridor: kept reverse VPLs {share.group(1)} %, ir/bidir rMAE {ir['rmae'] / bidir['rmae']:.2f}")
    assert 2 * bidir["rmae"] <= ir["rmae"]
    assert abs(bidir["mean_ratio"] - 1) <= 0.15
    assert vbnl["rmae"] < bidir["rmae"] and abs(vbnl["mean_ratio"] - 1) <= 0.10
