"""Segmentation scores of a folder of predicted label maps against reference labels.

``gaitnet evaluate`` uses it when a result folder has ``labels/`` (written by ``gaitnet
segment``): every ``labels/<name>.png`` is compared with the reference of the same name, and the
confusion matrix summed over all frames gives ``pixel_acc``, ``miou``, ``fw_iou`` and per-class
``iou`` (:func:`gaitnet.evaluation.segmentation.segmentation_scores`, thesis sec. 4.1.5). The
reference is, in this order:

1. a simulated session's ``groundtruth/labels/<t_ns>.png``;
2. a labelled set's ``labels/<id>.png`` (``gaitnet simulate-dataset``);
3. a labelled set's labelme annotations ``images/<id>.json`` (rasterised with labelme's own
   ``shapes_to_label``, :func:`gaitnet.io.labelme_io.read_labelme`; classes from
   ``labels.txt`` when present).

Label values: 0 background, 1 foot, 2 leg, 255 ignored (docs/design.md).
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from gaitnet.errors import InputError, SessionError
from gaitnet.evaluation.segmentation import confusion_matrix, segmentation_scores
from gaitnet.io.labelme_io import read_labelme, read_labels_txt

__all__ = ["CLASS_NAMES", "LABELS_DIR", "evaluate_label_maps", "reference_labels"]

LABELS_DIR = "labels"
CLASS_NAMES = ("background", "foot", "leg")


def _read_label_png(path: Path, error: type[InputError] | type[SessionError]) -> np.ndarray:
    image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if image is None:
        raise error(f"{path}: not a readable PNG label map")
    if image.ndim != 2 or image.dtype != np.uint8:
        raise error(
            f"{path}: a label map must be 8-bit single-channel, got {image.dtype} "
            f"with shape {image.shape}"
        )
    bad = ~np.isin(image, (0, 1, 2, 255))
    if bad.any():
        raise error(f"{path}: label value {int(image[bad][0])} is not 0, 1, 2 or 255")
    return image


def reference_labels(reference_dir: Path) -> tuple[dict[str, Path], str]:
    """Reference label files by name (stem) and their kind (``png`` or ``labelme``)."""
    for folder in (reference_dir / "groundtruth" / LABELS_DIR, reference_dir / LABELS_DIR):
        if folder.is_dir():
            return {p.stem: p for p in sorted(folder.glob("*.png"))}, "png"
    images = reference_dir / "images"
    if images.is_dir():
        found = {p.stem: p for p in sorted(images.glob("*.json"))}
        if found:
            return found, "labelme"
    raise SessionError(
        f"{reference_dir}: no ground truth for label maps: no reference labels (expected "
        "groundtruth/labels/ of a simulated session, or labelme annotations in labels/ or "
        "images/*.json)"
    )


def evaluate_label_maps(
    result_labels: Path, reference_dir: Path
) -> tuple[dict[str, float | dict[str, float]], dict[str, int]]:
    """Scores of ``result_labels/*.png`` against ``reference_dir`` (module docstring).

    Returns the metrics (``pixel_acc``, ``miou``, ``fw_iou``, ``iou`` per class) and counts
    (``label_frames`` compared, ``label_frames_unmatched`` predicted maps without a reference).
    """
    predicted = {p.stem: p for p in sorted(result_labels.glob("*.png"))}
    if not predicted:
        raise InputError(f"{result_labels}: no label maps (*.png)")
    reference, kind = reference_labels(reference_dir)
    names = [name for name in predicted if name in reference]
    if not names:
        raise InputError(
            f"{result_labels}: no label map has a reference of the same name in {reference_dir}"
        )
    class_values = None
    if kind == "labelme" and (reference_dir / "labels.txt").is_file():
        class_values = read_labels_txt(reference_dir / "labels.txt")
    conf = np.zeros((len(CLASS_NAMES), len(CLASS_NAMES)), np.int64)
    for name in names:
        pred = _read_label_png(predicted[name], InputError)
        if kind == "png":
            ref = _read_label_png(reference[name], SessionError)
        else:
            ref = read_labelme(reference[name], class_values)[0]
        if pred.shape != ref.shape:
            raise InputError(
                f"{predicted[name]}: label map is {pred.shape[1]}×{pred.shape[0]}, the reference "
                f"{reference[name].name} is {ref.shape[1]}×{ref.shape[0]}"
            )
        conf += confusion_matrix(pred, ref, len(CLASS_NAMES))
    scores = segmentation_scores(conf, CLASS_NAMES)
    metrics: dict[str, float | dict[str, float]] = {
        "pixel_acc": float(scores["pixel_acc"]),
        "miou": float(scores["miou"]),
        "fw_iou": float(scores["fw_iou"]),
        "iou": {k: float(v) for k, v in dict(scores["iou"]).items() if v is not None},
    }
    counts = {"label_frames": len(names), "label_frames_unmatched": len(predicted) - len(names)}
    return metrics, counts
