"""Per-class logit bias of a trained segmenter, chosen on a validation set.

Class-weighted focal loss (per-class ``alpha``) trains a net whose arg-max over-predicts the
up-weighted classes: with the committed config's alpha (background 0.25, foot 1.0, leg 0.5) most
foot errors are background pixels called foot. The arg-max of ``logits + bias`` with a
per-class ``bias`` (``model.logit_bias``, :class:`~gaitnet.segmentation.segmenter_net.
SegmenterNet`) moves the decision boundaries without retraining. :func:`fit_logit_bias` picks
the bias that maximises the mean IoU of labelled pixels by coordinate search on a grid: class 0
keeps bias 0 (only differences matter), each other class in turn takes the grid value that
maximises the mIoU given the others, until a full round changes nothing. Chosen on the
validation split, never on the sets it is then scored on.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from gaitnet.errors import InputError

__all__ = ["BiasFit", "PixelSample", "fit_logit_bias", "mean_iou"]

#: Default search grid of the bias (logit units) and the most rounds of coordinate search.
DEFAULT_GRID = tuple(np.round(np.arange(-4.0, 4.0 + 1e-9, 0.125), 3).tolist())
MAX_ROUNDS = 8


@dataclass(frozen=True)
class BiasFit:
    """The chosen bias (one per class, ``bias[0] == 0``) and the mIoU before and after."""

    bias: tuple[float, ...]
    miou_before: float
    miou_after: float
    rounds: int


class PixelSample:
    """Logits and labels of labelled pixels gathered batch by batch, at most ``max_pixels``
    kept (a uniform random subset, drawn with ``seed``, when a set has more)."""

    def __init__(self, num_classes: int, ignore_index: int, max_pixels: int, seed: int = 0):
        if max_pixels < 1:
            raise InputError(f"calibration: max_pixels must be ≥ 1, got {max_pixels}")
        self.num_classes = num_classes
        self.ignore_index = ignore_index
        self.max_pixels = max_pixels
        self._rng = np.random.default_rng(seed)
        self._logits: list[np.ndarray] = []
        self._labels: list[np.ndarray] = []
        self.seen = 0

    def add(self, logits: np.ndarray, labels: np.ndarray) -> None:
        """``logits`` (B, C, H, W) and ``labels`` (B, H, W) of one batch."""
        logits, labels = np.asarray(logits), np.asarray(labels)
        if logits.ndim != 4 or logits.shape[1] != self.num_classes:
            raise InputError(
                f"calibration: logits must be (B, {self.num_classes}, H, W), got {logits.shape}"
            )
        if labels.shape != (logits.shape[0], *logits.shape[2:]):
            raise InputError(
                f"calibration: labels {labels.shape} do not match logits {logits.shape}"
            )
        keep = labels != self.ignore_index
        flat = np.moveaxis(logits, 1, -1)[keep].astype(np.float32)
        self._logits.append(flat)
        self._labels.append(labels[keep].astype(np.int64))
        self.seen += len(flat)
        if sum(len(x) for x in self._labels) > 2 * self.max_pixels:
            self._shrink()

    def _shrink(self) -> None:
        logits, labels = np.concatenate(self._logits), np.concatenate(self._labels)
        pick = np.sort(self._rng.choice(len(labels), self.max_pixels, replace=False))
        self._logits, self._labels = [logits[pick]], [labels[pick]]

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """(N, C) float32 logits and (N,) int64 labels, N ≤ ``max_pixels``."""
        if not self._labels or self.seen == 0:
            raise InputError("calibration: no labelled pixel to calibrate on")
        if sum(len(x) for x in self._labels) > self.max_pixels:
            self._shrink()
        return np.concatenate(self._logits), np.concatenate(self._labels)


def mean_iou(logits: np.ndarray, labels: np.ndarray, bias: Sequence[float]) -> float:
    """Mean IoU over the classes present (in the labels or the prediction) of the arg-max of
    ``logits + bias``; ``logits`` (N, C), ``labels`` (N,) in [0, C)."""
    n = logits.shape[1]
    pred = np.argmax(logits + np.asarray(bias, dtype=np.float32), axis=1)
    conf = np.bincount(labels * n + pred, minlength=n * n).reshape(n, n).astype(np.float64)
    union = conf.sum(0) + conf.sum(1) - np.diag(conf)
    present = union > 0
    return float(np.mean(np.diag(conf)[present] / union[present]))


def fit_logit_bias(
    logits: np.ndarray,
    labels: np.ndarray,
    grid: Iterable[float] = DEFAULT_GRID,
    max_rounds: int = MAX_ROUNDS,
) -> BiasFit:
    """The per-class bias (module docstring) of ``logits`` (N, C) and ``labels`` (N,)."""
    logits = np.asarray(logits, dtype=np.float32)
    labels = np.asarray(labels, dtype=np.int64)
    if logits.ndim != 2 or labels.shape != (logits.shape[0],) or logits.shape[0] == 0:
        raise InputError(f"calibration: need (N, C) logits and (N,) labels, got "
                         f"{logits.shape} and {labels.shape}")  # fmt: skip
    n = logits.shape[1]
    if labels.min() < 0 or labels.max() >= n:
        raise InputError(f"calibration: labels must lie in [0, {n}), got {labels.min()}…"
                         f"{labels.max()}")  # fmt: skip
    if not np.isfinite(logits).all():
        raise InputError("calibration: the logits contain NaN or infinity")
    values = sorted(set(float(g) for g in grid) | {0.0})
    bias = [0.0] * n
    before = best = mean_iou(logits, labels, bias)
    rounds = 0
    while rounds < max_rounds:
        rounds += 1
        changed = False
        for c in range(1, n):
            for v in values:
                trial = bias[:c] + [v] + bias[c + 1 :]
                score = mean_iou(logits, labels, trial)
                if score > best + 1e-12:
                    best, bias, changed = score, trial, True
        if not changed:
            break
    return BiasFit(tuple(bias), before, best, rounds)
