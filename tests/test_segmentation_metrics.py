"""Segmentation metrics (gaitnet.evaluation.segmentation): confusion matrices and the scores of
Long et al. (pixel accuracy, mean IoU, frequency-weighted IoU) against hand computations."""

from __future__ import annotations

import numpy as np
import pytest

from gaitnet.errors import InputError
from gaitnet.evaluation.segmentation import confusion_matrix, segmentation_scores

#  target        prediction
#  0 0 1 2       0 1 1 2
#  0 0 1 2       0 0 2 2
#  255 0 0 1     1 0 0 1
TARGET = np.array([[0, 0, 1, 2], [0, 0, 1, 2], [255, 0, 0, 1]])
PRED = np.array([[0, 1, 1, 2], [0, 0, 2, 2], [1, 0, 0, 1]])
# counted pixels (11): true 0: 6 (pred 0 ×5, 1 ×1); true 1: 3 (pred 1 ×2, 2 ×1); true 2: 2
CONF = np.array([[5, 1, 0], [0, 2, 1], [0, 0, 2]])


def test_confusion_matrix_by_hand() -> None:
    conf = confusion_matrix(PRED, TARGET, 3)
    assert conf.dtype == np.int64
    np.testing.assert_array_equal(conf, CONF)
    # batches add; the ignored pixel is not counted whatever it is predicted as
    both = confusion_matrix(np.stack([PRED, PRED]), np.stack([TARGET, TARGET]), 3)
    np.testing.assert_array_equal(both, 2 * CONF)
    other = PRED.copy()
    other[2, 0] = 2
    np.testing.assert_array_equal(confusion_matrix(other, TARGET, 3), CONF)


def test_scores_by_hand() -> None:
    s = segmentation_scores(CONF, ["background", "foot", "leg"])
    assert s["pixel_acc"] == pytest.approx(9 / 11)
    # IoU_i = n_ii / (t_i + Σ_j n_ji - n_ii)
    iou = {"background": 5 / (6 + 5 - 5), "foot": 2 / (3 + 3 - 2), "leg": 2 / (2 + 3 - 2)}
    assert s["iou"] == pytest.approx(iou)
    assert s["miou"] == pytest.approx((5 / 6 + 2 / 4 + 2 / 3) / 3)
    assert s["fw_iou"] == pytest.approx((6 * 5 / 6 + 3 * 2 / 4 + 2 * 2 / 3) / 11)
    assert s["mean_acc"] == pytest.approx((5 / 6 + 2 / 3 + 2 / 2) / 3)
    assert s["n_pixels"] == 11


def test_perfect_prediction() -> None:
    s = segmentation_scores(confusion_matrix(TARGET, TARGET, 3))
    assert s["pixel_acc"] == s["miou"] == s["fw_iou"] == s["mean_acc"] == 1.0
    assert list(s["iou"]) == ["0", "1", "2"]


def test_absent_classes() -> None:
    # class 2 neither in target nor prediction: no IoU, left out of the mean
    target = np.array([0, 0, 1, 1])
    pred = np.array([0, 1, 1, 1])
    s = segmentation_scores(confusion_matrix(pred, target, 3))
    assert s["iou"]["2"] is None and s["acc"]["2"] is None
    assert s["miou"] == pytest.approx((1 / 2 + 2 / 3) / 2)
    # class 2 only predicted (a false positive): IoU 0, counted in the mean, weighs 0 in FW IoU
    pred = np.array([0, 2, 1, 1])
    s = segmentation_scores(confusion_matrix(pred, target, 3))
    assert s["iou"] == pytest.approx({"0": 1 / 2, "1": 1.0, "2": 0.0})
    assert s["miou"] == pytest.approx((1 / 2 + 1 + 0) / 3)
    assert s["fw_iou"] == pytest.approx((2 * 1 / 2 + 2 * 1) / 4)
    assert s["acc"]["2"] is None and s["mean_acc"] == pytest.approx((1 / 2 + 1) / 2)


def test_other_ignore_index() -> None:
    target = np.array([0, 1, -1, -1])
    pred = np.array([0, 0, 1, 1])
    np.testing.assert_array_equal(
        confusion_matrix(pred, target, 2, ignore_index=-1), [[1, 0], [1, 0]]
    )


@pytest.mark.parametrize(
    ("pred", "target", "match"),
    [
        (np.array([0, 3]), np.array([0, 1]), "prediction holds label 3"),
        (np.array([0, 1]), np.array([0, 7]), "target holds label 7"),
        (np.array([0, 1]), np.array([0, 1, 1]), "differ in shape"),
        (np.array([0.0, 1.0]), np.array([0, 1]), "integers"),
    ],
)
def test_bad_labels(pred: np.ndarray, target: np.ndarray, match: str) -> None:
    with pytest.raises(InputError, match=match):
        confusion_matrix(pred, target, 3)


def test_bad_confusion_matrices() -> None:
    with pytest.raises(InputError, match="no labelled pixel"):
        segmentation_scores(np.zeros((3, 3), dtype=np.int64))
    with pytest.raises(InputError, match="square"):
        segmentation_scores(np.zeros((3, 2), dtype=np.int64))
    with pytest.raises(InputError, match="2 class names for 3"):
        segmentation_scores(CONF, ["a", "b"])
    with pytest.raises(InputError, match="counts"):
        segmentation_scores(-CONF)
