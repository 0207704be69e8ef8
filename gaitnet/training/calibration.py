"""Per-class logit bias of a trained segmenter, chosen on a validation set.

Class-weighted focal loss (per-class ``alpha``) trains a net whose arg-max over-predicts the
up-weighted classes: with the committed config's alpha (background 0.25, foot 1.0, leg 0.5) most
foot errors are background pixels called foot. The arg-max of ``logits + bias`` with a
per-class ``bias`` (``model.logit_bias``, :class:`~gaitnet.segmentation.segmenter_net.
SegmenterNet`) moves the decision boundaries without retraining. :func:`fit_logit_bias` picks
the bias that maximises the mean IoU of labelled pixels: class 0 keeps bias 0 (only
differences matter); a joint search over a coarse grid (steps of 1, on a random million of the
pixels, when the grid has at most :data:`MAX_COARSE` points) gives the start, then a coordinate
search on the fine grid over all pixels (each class other than 0 in turn takes the value that
maximises the mIoU given the others) until a full round changes nothing. The joint start
matters when the bias is far off: moving one class alone can then only trade one wrong class
for another. Chosen on the
validation split, never on the sets it is then scored on.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from gaitnet.errors import InputError

__all__ = ["BiasFit", "PixelSample", "fit_logit_bias", "mean_iou"]

#: Default search grid of the bias (logit units) and the most rounds of coordinate search.
DEFAULT_GRID = tuple(np.round(np.arange(-4.0, 4.0 + 1e-9, 0.125), 3).tolist())
MAX_ROUNDS = 8
#: The joint coarse grid, the most points it may have, and the pixels it is scored on.
COARSE_GRID = (-4.0, -3.0, -2.0, -1.0, 0.0, 1.0, 2.0, 3.0, 4.0)
MAX_COARSE = 1000
COARSE_PIXELS = 1_000_000


@dataclass(frozen=True)
class BiasFit:
    """The chosen bias (one per class, ``bias[0] == 0``) and the mIoU before and after."""

    bias: tuple[float, ...]
    miou_before: float
    miou_after: float
    rounds: int
    at_grid_edge: bool  # a class's bias is the grid's end: the best value may lie beyond it


class PixelSample:
    """Logits and labels of labelled pixels gathered batch by batch: all of them up to
    ``max_pixels``, beyond that a uniform random subset of all pixels seen (each pixel gets a
    random key drawn with ``seed``; the ``max_pixels`` smallest keys are kept)."""

    def __init__(self, num_classes: int, ignore_index: int, max_pixels: int, seed: int = 0):
        if max_pixels < 1:
            raise InputError(f"calibration: max_pixels must be ≥ 1, got {max_pixels}")
        self.num_classes = num_classes
        self.ignore_index = ignore_index
        self.max_pixels = max_pixels
        self._rng = np.random.default_rng(seed)
        self._logits: list[np.ndarray] = []
        self._labels: list[np.ndarray] = []
        self._keys: list[np.ndarray] = []
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
        self._keys.append(self._rng.random(len(flat)))
        self.seen += len(flat)
        if sum(len(x) for x in self._labels) > 2 * self.max_pixels:
            self._shrink()

    def _shrink(self) -> None:
        keys = np.concatenate(self._keys)
        if len(keys) <= self.max_pixels:
            return
        pick = np.sort(np.argpartition(keys, self.max_pixels - 1)[: self.max_pixels])
        self._logits = [np.concatenate(self._logits)[pick]]
        self._labels = [np.concatenate(self._labels)[pick]]
        self._keys = [keys[pick]]

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """(N, C) float32 logits and (N,) int64 labels, N ≤ ``max_pixels``."""
        if self.seen == 0:
            raise InputError("calibration: no labelled pixel to calibrate on")
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
    absent = np.flatnonzero(np.bincount(labels, minlength=n) == 0)
    if absent.size:
        raise InputError(
            f"calibration: class(es) {absent.tolist()} have no labelled pixel in the set; a bias "
            "for a class the set lacks cannot be chosen"
        )
    values = sorted(set(float(g) for g in grid) | {0.0})
    before = mean_iou(logits, labels, [0.0] * n)
    bias = _coarse_start(logits, labels, values[0], values[-1])
    best = mean_iou(logits, labels, bias)
    if best < before:  # the coarse start was scored on a subset
        bias, best = [0.0] * n, before
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
    edge = any(b <= values[0] or b >= values[-1] for b in bias[1:])
    return BiasFit(tuple(bias), before, best, rounds, edge)


def _coarse_start(logits: np.ndarray, labels: np.ndarray, lo: float, hi: float) -> list[float]:
    """The best bias on :data:`COARSE_GRID` (its values in [lo, hi]) jointly; zeros when that
    grid is too large."""
    n = logits.shape[1]
    coarse = [g for g in COARSE_GRID if lo <= g <= hi]
    if len(coarse) ** (n - 1) > MAX_COARSE:
        return [0.0] * n
    if len(labels) > COARSE_PIXELS:
        pick = np.random.default_rng(0).choice(len(labels), COARSE_PIXELS, replace=False)
        logits, labels = logits[pick], labels[pick]
    bias, best = [0.0] * n, mean_iou(logits, labels, [0.0] * n)
    for combo in itertools.product(coarse, repeat=n - 1):
        trial = [0.0, *combo]
        score = mean_iou(logits, labels, trial)
        if score > best + 1e-12:
            bias, best = trial, score
    return bias
