"""The metrics a render is judged by (``evaluation.metrics``): the errors on known images, block rMAE, the clean
relative RMSE of two references, the noise floor, and pixels the reference does not cover left out."""
import numpy as np
import pytest

from vpl_addon.evaluation.metrics import clean_rrmse, coverage_mask, errors, noise_floor


def test_metrics_on_known_images():
    ref = np.ones((4, 4, 3))
    img = ref * 1.1
    e = errors(img, ref)
    assert e["mean_ratio"] == pytest.approx(1.1)
    assert e["rmae"] == pytest.approx(0.1 / 1.01)
    assert e["relmse"] == pytest.approx(0.01 / (1 + 1e-4))
    assert errors(ref, ref)["rmae"] == 0.0


def test_block_rmae_forgives_a_checkerboard_of_noise_but_not_a_bias_and_keeps_to_whole_blocks():
    """rmae4: a +-10 % checkerboard averages out in 4 x 4 blocks, a +10 % bias does not; a block the mask cuts is
    left out, and an image smaller than a block falls back to the pixels' rMAE."""
    ref = np.ones((8, 12, 3))
    checker = ref * (1.0 + 0.1 * ((np.indices((8, 12)).sum(axis=0) % 2) * 2 - 1))[..., None]
    assert errors(checker, ref)["rmae"] == pytest.approx(0.1 / 1.01)
    assert errors(checker, ref)["rmae4"] == pytest.approx(0.0, abs=1e-12)
    assert errors(ref * 1.1, ref)["rmae4"] == pytest.approx(0.1 / 1.01)
    img = ref.copy()
    img[0, 0] = 100.0
    mask = np.ones((8, 12), bool)
    mask[0, 0] = False  # the first block is not whole: left out
    assert errors(img, ref, mask)["rmae4"] == 0.0 and errors(img, ref)["rmae4"] > 1.0
    small = errors(ref[:2, :2] * 1.1, ref[:2, :2])
    assert small["rmae4"] == small["rmae"]


def test_clean_rrmse_takes_the_references_own_noise_out_and_keeps_an_images_error():
    """Two references with independent noise (sigma 0.3 of a mean of 1) stand for the truth: an image with noise
    0.1 of its own measures 0.1 where its RMSE against one reference is sqrt(0.1^2 + 0.3^2) = 0.32; the truth
    itself measures about 0 and a 10 % bias 0.1. One of the references scores 0: its noise is theirs, the case the
    metric leaves out (a renderer's image is independent of the references)."""
    rng = np.random.default_rng(7)
    truth = np.ones((256, 256, 3))
    a, b = (truth + rng.normal(0.0, 0.3, truth.shape) for _ in range(2))
    image = truth + rng.normal(0.0, 0.1, truth.shape)
    assert np.sqrt(np.mean((image - a) ** 2)) == pytest.approx(0.316, rel=0.02)
    assert clean_rrmse(image, a, b) == pytest.approx(0.1, rel=0.05)
    assert clean_rrmse(truth, a, b) < 0.01
    assert clean_rrmse(1.1 * truth, a, b) == pytest.approx(0.1, rel=0.05)
    assert clean_rrmse(a, a, b) < 1e-6
    mask = np.zeros((256, 256), bool)
    mask[:, :128] = True
    dark = image.copy()
    dark[:, 128:] = 0.0  # outside the mask: ignored
    assert clean_rrmse(dark, a, b, mask) == pytest.approx(0.1, rel=0.05)
    with pytest.raises(ValueError):
        clean_rrmse(image, a, b[:8])


def test_the_noise_floor_is_what_the_truth_scores_and_no_image_scores_less():
    """Two references with independent Gaussian noise (sigma 0.05 over an image ramping from 0.2 to 2): the truth
    scores the twin's rMAE over sqrt 2 against the reference (pixels and 4 x 4 blocks, and over a mask of the dim
    side, where the relative noise is twice the mean); images independent of the reference, the truth with noise of
    its own or 3 % too bright, score more; a render with the reference's noise scores sqrt 2 times the floor."""
    rng = np.random.default_rng(11)
    truth = np.repeat(np.linspace(0.2, 2.0, 256)[None, :, None], 256, axis=0) * np.ones((1, 1, 3))
    a, b = (truth + rng.normal(0.0, 0.05, truth.shape) for _ in range(2))
    floor = noise_floor(a, b)
    assert floor["rmae"] == pytest.approx(errors(truth, a)["rmae"], rel=0.02)
    assert floor["rmae4"] == pytest.approx(errors(truth, a)["rmae4"], rel=0.03)
    assert floor["rmae_bound"] == pytest.approx(floor["rmae"] / np.sqrt(2.0))
    assert errors(b, a)["rmae"] == pytest.approx(np.sqrt(2.0) * floor["rmae"])
    assert errors(truth + rng.normal(0.0, 0.02, truth.shape), a)["rmae"] > 1.05 * floor["rmae"]
    assert errors(1.03 * truth, a)["rmae"] > 1.1 * floor["rmae"]
    mask = np.zeros((256, 256), bool)
    mask[:, :64] = True
    dim = noise_floor(a, b, mask)["rmae"]
    assert dim > 2.0 * floor["rmae"] and dim == pytest.approx(errors(truth, a, mask)["rmae"], rel=0.03)


def test_metrics_ignore_pixels_the_reference_does_not_cover_fully():
    ref = np.ones((2, 2, 3))
    img = ref.copy()
    img[0, 0] = 100.0
    alpha = np.array([[0.5, 1.0], [1.0, 0.9995]])
    mask = coverage_mask(alpha, (2, 2))
    assert mask.sum() == 3 and errors(img, ref, mask)["rmae"] == 0.0
