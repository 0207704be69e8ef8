"""gaitnet.training.calibration: the per-class logit bias chosen on a validation set."""

from __future__ import annotations

import numpy as np
import pytest

from gaitnet.errors import InputError
from gaitnet.evaluation.segmentation import confusion_matrix, segmentation_scores
from gaitnet.training.calibration import PixelSample, fit_logit_bias, mean_iou


def _logits(n: int, classes: int = 3, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).normal(size=(n, classes)).astype(np.float32)


def test_mean_iou_matches_the_evaluation_module() -> None:
    logits = _logits(5000)
    labels = np.random.default_rng(1).integers(0, 3, 5000)
    bias = (0.0, -0.3, 0.7)
    pred = np.argmax(logits + np.array(bias, dtype=np.float32), axis=1)
    expected = segmentation_scores(confusion_matrix(pred, labels, 3))["miou"]
    assert mean_iou(logits, labels, bias) == pytest.approx(expected, abs=1e-12)


def test_fit_recovers_the_bias_that_made_the_labels() -> None:
    """Labels are the arg-max of logits + a known bias: the fit finds that bias (to the grid's
    step, class 0 at zero) and a perfect mIoU."""
    logits = _logits(60_000)
    truth = np.array([0.0, -0.75, 0.5], dtype=np.float32)
    labels = np.argmax(logits + truth, axis=1)
    fit = fit_logit_bias(logits, labels)
    assert fit.bias[0] == 0.0
    np.testing.assert_allclose(fit.bias, truth, atol=0.125)
    assert fit.miou_after > 0.99 and fit.miou_before < 0.9
    assert fit.miou_after == pytest.approx(mean_iou(logits, labels, fit.bias))


def test_fit_keeps_zero_when_the_net_is_already_calibrated() -> None:
    logits = _logits(20_000, classes=4, seed=3)
    fit = fit_logit_bias(logits, np.argmax(logits, axis=1))
    assert fit.bias == (0.0, 0.0, 0.0, 0.0) and fit.miou_after == 1.0 and fit.rounds == 1


def test_only_differences_matter() -> None:
    """A bias added to every class's logits changes nothing: the fit is the same."""
    logits = _logits(20_000, seed=4)
    labels = np.argmax(logits + np.array([0.0, 0.4, -0.6], dtype=np.float32), axis=1)
    shifted = logits + np.float32(2.5)
    assert fit_logit_bias(shifted, labels).bias == fit_logit_bias(logits, labels).bias


def test_pixel_sample_drops_ignored_pixels_and_bounds_its_size() -> None:
    sample = PixelSample(num_classes=3, ignore_index=255, max_pixels=50)
    logits = _logits(2 * 4 * 6).reshape(2, 4, 6, 3).transpose(0, 3, 1, 2)
    labels = np.zeros((2, 4, 6), dtype=np.int64)
    labels[0, 0, :] = 255  # 6 ignored pixels
    labels[1] = 2
    sample.add(logits, labels)
    kept_logits, kept_labels = sample.arrays()
    assert kept_labels.shape == (42,) and kept_logits.shape == (42, 3)
    np.testing.assert_array_equal(kept_logits[-1], logits[1, :, 3, 5])  # pixel order kept
    for seed in range(3):
        sample.add(_logits(48, seed=seed).reshape(2, 3, 4, 6), np.ones((2, 4, 6), dtype=np.int64))
    assert sample.seen == 42 + 3 * 48
    assert sample.arrays()[1].shape == (50,)


def test_pixel_sample_is_uniform_over_all_batches() -> None:
    """20 equal batches into a sample of 1000: each batch keeps about a twentieth of it (the
    batch index is stored in the labels' place to count)."""
    sample = PixelSample(num_classes=20, ignore_index=255, max_pixels=1000, seed=1)
    for k in range(20):
        sample.add(np.zeros((1, 20, 25, 20), np.float32), np.full((1, 25, 20), k))
    shares = np.bincount(sample.arrays()[1], minlength=20) / 1000
    assert sample.seen == 10_000 and len(sample.arrays()[1]) == 1000
    assert shares.min() > 0.03 and shares.max() < 0.07  # binomial sd 0.007 around 0.05


def test_a_class_the_set_lacks_is_refused_and_a_clamped_bias_flagged() -> None:
    logits = _logits(3000)
    with pytest.raises(InputError, match=r"class\(es\) \[2\] have no labelled pixel"):
        fit_logit_bias(logits, np.argmax(logits[:, :2], axis=1))
    labels = np.argmax(logits + np.array([0.0, -6.0, 0.0], np.float32), axis=1)
    labels[:3] = 1  # a rare class, far below the grid's reach
    fit = fit_logit_bias(logits, labels, grid=np.arange(-2.0, 2.01, 0.5))
    assert fit.at_grid_edge and fit.bias[1] == -2.0
    assert not fit_logit_bias(logits, np.argmax(logits, axis=1)).at_grid_edge


def test_bad_input_is_named() -> None:
    sample = PixelSample(3, 255, 100)
    with pytest.raises(InputError, match="no labelled pixel"):
        sample.arrays()
    with pytest.raises(InputError, match=r"logits must be \(B, 3, H, W\)"):
        sample.add(np.zeros((1, 2, 4, 4)), np.zeros((1, 4, 4)))
    with pytest.raises(InputError, match="do not match"):
        sample.add(np.zeros((1, 3, 4, 4)), np.zeros((1, 4, 5)))
    with pytest.raises(InputError, match="max_pixels"):
        PixelSample(3, 255, 0)
    logits = _logits(10)
    with pytest.raises(InputError, match="NaN"):
        fit_logit_bias(
            np.where(np.arange(30).reshape(10, 3) == 4, np.nan, logits), np.zeros(10, int)
        )
    with pytest.raises(InputError, match=r"labels must lie in \[0, 3\)"):
        fit_logit_bias(logits, np.full(10, 3))
    with pytest.raises(InputError, match=r"\(N, C\) logits"):
        fit_logit_bias(logits, np.zeros(9, int))


def test_joint_start_finds_a_bias_far_off(monkeypatch) -> None:
    """Both non-background classes 3 logits too high: moving one at a time only swaps foot for
    leg everywhere; the joint coarse start reaches the planted bias."""
    import gaitnet.training.calibration as calibration

    noise = 0.3 * _logits(30_000, seed=5)
    labels = np.argmax(noise + np.array([0.8, 0.0, 0.0], np.float32), axis=1)
    skewed = noise + np.array([0.8, 3.0, 3.0], np.float32)
    fit = fit_logit_bias(skewed, labels)
    np.testing.assert_allclose(fit.bias, [0.0, -3.0, -3.0], atol=0.125)
    assert fit.miou_after > 0.99
    monkeypatch.setattr(calibration, "MAX_COARSE", 0)  # coordinate search alone
    assert fit_logit_bias(skewed, labels).miou_after < 0.9
