"""Hedman et al.'s |E| and |E'| of a sequence, and ``compare`` over two folders of frames."""
import numpy as np
import pytest

from conftest import run_cli
from vpl_addon.core.exr import write_passes
from vpl_addon.evaluation.temporal import reinhard, temporal_errors, tracked_pixels


def frames(values, shape=(4, 4)):
    return [np.full((*shape, 3), v, np.float32) for v in values]


def test_a_constant_offset_has_error_but_no_flicker_and_a_flicker_has_both():
    refs = frames([1.0, 1.0, 1.0, 1.0])
    steady = temporal_errors(frames([3.0] * 4), refs)
    assert steady["frame"]["E"] == pytest.approx(0.75 - 0.5) and steady["frame"]["E_prime"] == 0.0
    flicker = temporal_errors(frames([3.0, 1.0, 3.0, 1.0]), refs)
    assert flicker["frame"]["E"] == pytest.approx(0.125)
    assert flicker["frame"]["E_prime"] == pytest.approx(0.25)
    assert flicker["tracked"] == flicker["frame"] and len(flicker["tracked_pixels"]) == 8
    assert flicker["E_per_frame"] == pytest.approx([0.25, 0, 0.25, 0])


def test_error_follows_the_reference_over_time_and_is_tone_mapped():
    """A method that lags one frame behind a changing reference flickers less than it errs."""
    ref_values = [0.5, 1.0, 1.5, 2.0, 2.5]
    lag = temporal_errors(frames([0.5] + ref_values[:-1]), frames(ref_values))
    assert lag["frame"]["E"] > 0 and lag["frame"]["E_prime"] < 2 * lag["frame"]["E"]
    assert reinhard(np.array([-1.0, 0.0, 1.0])) == pytest.approx([0.0, 0.0, 0.5])


def test_only_masked_pixels_count_and_tracked_pixels_are_spread_and_fixed():
    mask = np.zeros((8, 8), bool)
    mask[2:6, 2:6] = True
    picked = tracked_pixels(mask)
    assert len(picked) == 8 and len(set(picked)) == 8 and mask.reshape(-1)[picked].all()
    assert np.array_equal(picked, tracked_pixels(mask)) and picked.min() < 30 and picked.max() > 35
    image = frames([1.0, 1.0], (8, 8))
    image[1][0, 0] = 100.0  # outside the mask: ignored
    assert temporal_errors(image, frames([1.0, 1.0], (8, 8)), mask)["frame"]["E_prime"] == 0.0
    with pytest.raises(ValueError):
        temporal_errors(frames([1.0]), frames([1.0, 1.0]))
    with pytest.raises(ValueError):
        temporal_errors(frames([1.0]), frames([1.0]), np.zeros((4, 4), bool))


def test_compare_over_two_folders_reports_sequence_errors(tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "r").mkdir()
    for f, (value, ref) in enumerate(zip([3.0, 1.0, 3.0], [1.0, 1.0, 1.0]), start=5):
        alpha = np.ones((4, 4, 1), np.float32)
        write_passes(str(tmp_path / "a" / f"frame_{f:04d}.exr"), {"Diffuse Indirect": frames([value])[0]})
        write_passes(str(tmp_path / "r" / f"frame_{f:04d}.exr"),
                     {"Combined": np.concatenate([frames([ref])[0], alpha], 2), "Diffuse Indirect": frames([ref])[0]})
    code, stdout, stderr = run_cli("compare", tmp_path / "a", tmp_path / "r")
    assert code == 0, stderr
    import json
    result = json.loads(stdout)["Diffuse Indirect"]
    assert result["frames"] == 3 and result["first_frame"] == 5
    assert result["frame"]["E_prime"] == pytest.approx(0.25) and len(result["rmae_per_frame"]) == 3
    (tmp_path / "a" / "frame_0006.exr").unlink()
    code, _, stderr = run_cli("compare", tmp_path / "a", tmp_path / "r")
    assert code != 0 and "not consecutive" in stderr
    code, _, stderr = run_cli("compare", tmp_path / "a", tmp_path / "r" / "frame_0005.exr")
    assert code != 0 and "two folders" in stderr
