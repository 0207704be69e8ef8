"""Segmentation scores (thesis sec. 4.1, its three metrics): pixel accuracy, mean IoU and
frequency-weighted IoU, as defined by Long, Shelhamer and Darrell ("Fully Convolutional Networks
for Semantic Segmentation", CVPR 2015, sec. 5), plus per-class IoU and mean class accuracy.

With ``n_ij`` the number of pixels of true class ``i`` predicted as class ``j`` (the confusion
matrix, rows true, columns predicted) and ``t_i = Σ_j n_ij`` the pixels of class ``i``::

    pixel accuracy     Σ_i n_ii / Σ_i t_i
    mean accuracy      (1 / n_cl) Σ_i n_ii / t_i
    IoU_i              n_ii / (t_i + Σ_j n_ji - n_ii)
    mean IoU           (1 / n_cl) Σ_i IoU_i
    frequency-weighted IoU   (Σ_k t_k)^-1 Σ_i t_i IoU_i

A class absent from both the target and the prediction has no IoU (``None``) and is left out of
the means (``n_cl`` counts the classes that have one); a class only predicted has IoU 0 and
counts in the mean IoU (and weighs 0 in the frequency-weighted IoU); mean accuracy averages
over the classes present in the target. Pixels whose target is ``ignore_index`` (255,
labelme's ``__ignore__``) are not counted. Pure numpy; no file io.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from gaitnet.errors import InputError

__all__ = ["confusion_matrix", "segmentation_scores"]


def confusion_matrix(
    pred: np.ndarray, target: np.ndarray, num_classes: int, ignore_index: int = 255
) -> np.ndarray:
    """(num_classes, num_classes) int64 counts ``[true, predicted]`` over the pixels whose
    target is not ``ignore_index``. ``pred`` and ``target`` are integer label arrays of one
    shape (any shape: an image, a batch); a label outside ``[0, num_classes)`` (other than the
    ignored target) is an :class:`~gaitnet.errors.InputError`. Matrices of several images add.
    """
    if isinstance(num_classes, bool) or not isinstance(num_classes, (int, np.integer)):
        raise InputError(f"confusion matrix: num_classes must be an integer, got {num_classes!r}")
    if num_classes < 1:
        raise InputError(f"confusion matrix: num_classes must be ≥ 1, got {num_classes}")
    pred, target = np.asarray(pred), np.asarray(target)
    if pred.shape != target.shape:
        raise InputError(
            f"confusion matrix: prediction {pred.shape} and target {target.shape} differ in shape"
        )
    for name, a in (("prediction", pred), ("target", target)):
        if not np.issubdtype(a.dtype, np.integer):
            raise InputError(f"confusion matrix: {name} labels must be integers, got {a.dtype}")
    keep = target != ignore_index
    t = target[keep].astype(np.int64)
    p = pred[keep].astype(np.int64)
    for name, a in (("target", t), ("prediction", p)):
        bad = (a < 0) | (a >= num_classes)
        if bad.any():
            raise InputError(
                f"confusion matrix: {name} holds label {int(a[bad][0])}, outside "
                f"[0, {num_classes})"
                + (f" and not {ignore_index} (ignore)" if name == "target" else "")
            )
    counts = np.bincount(t * num_classes + p, minlength=num_classes * num_classes)
    return counts.reshape(num_classes, num_classes).astype(np.int64)


def segmentation_scores(
    conf: np.ndarray, class_names: Sequence[str] | None = None
) -> dict[str, Any]:
    """Scores of a confusion matrix (:func:`confusion_matrix`, summed over a data set).

    Returns ``pixel_acc``, ``mean_acc``, ``miou``, ``fw_iou`` (floats), ``iou`` and ``acc``
    (class name → float, or ``None`` where undefined; names default to ``"0"``, ``"1"``, ...)
    and ``n_pixels``. A matrix without any counted pixel is an
    :class:`~gaitnet.errors.InputError` (nothing to score).
    """
    conf = np.asarray(conf)
    if conf.ndim != 2 or conf.shape[0] != conf.shape[1] or conf.shape[0] == 0:
        raise InputError(
            f"segmentation scores: expected a square confusion matrix, got {conf.shape}"
        )
    if not np.issubdtype(conf.dtype, np.integer) or (conf < 0).any():
        raise InputError("segmentation scores: the confusion matrix must hold counts ≥ 0")
    n = conf.shape[0]
    names = [str(i) for i in range(n)] if class_names is None else [str(c) for c in class_names]
    if len(names) != n:
        raise InputError(f"segmentation scores: {len(names)} class names for {n} classes")
    conf = conf.astype(np.float64)
    total = conf.sum()
    if total == 0:
        raise InputError("segmentation scores: no labelled pixel to score")
    hit = np.diag(conf)
    true_count = conf.sum(axis=1)  # t_i
    union = true_count + conf.sum(axis=0) - hit
    has_iou = union > 0
    iou = np.where(has_iou, hit / np.where(has_iou, union, 1.0), np.nan)
    present = true_count > 0
    acc = np.where(present, hit / np.where(present, true_count, 1.0), np.nan)
    return {
        "pixel_acc": float(hit.sum() / total),
        "mean_acc": float(acc[present].mean()),
        "miou": float(iou[has_iou].mean()),
        "fw_iou": float((true_count[has_iou] * iou[has_iou]).sum() / total),
        "iou": {k: (float(v) if h else None) for k, v, h in zip(names, iou, has_iou, strict=True)},
        "acc": {k: (float(v) if h else None) for k, v, h in zip(names, acc, present, strict=True)},
        "n_pixels": int(total),
    }
