"""A segmenter exported for one frame size, run on frames of another size.

An exported segmenter takes frames of one size ``H_m × W_m`` (640 × 480 for the committed
model); a RealSense D455 also records 848 × 480 and 1280 × 720. Such a frame is

1. scaled by ``s = H_m / H`` so that its height is the model's (bilinear up, area down): the
   D455's 16:9 colour modes then have about the pixel scale of its 640 × 480 frames (a focal
   length of about 425 px against 386 px for the simulator's 640 × 480, inside the ±25 % scale
   augmentation of training);
2. covered across its scaled width ``W' = round(W s)`` by ``n`` windows of the model's width
   (:func:`window_starts`: the fewest that overlap by at least :data:`MIN_OVERLAP` columns
   or half a window, spread evenly), or, narrower than the model, padded on the right by
   repeating its last column;
3. run through the network as one batch (``n`` windows per frame);
4. joined: each column's logits are the mean of the windows over it, weighted by the
   column's distance to the window's nearest edge inside the frame
   (:func:`window_weights`: a window's seam, where the network saw no context, weighs least;
   the frame's own edges are no seam);
5. scaled back to ``H × W`` (bilinear).

For a network whose output at a pixel depends on that pixel alone the result is exactly the
network on the scaled frame, scaled back; for a convolutional network the windows' context
differs near their seams, which the weights keep out of the joined logits.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import cv2
import numpy as np

__all__ = ["MIN_OVERLAP", "window_starts", "window_weights", "windowed_logits"]

MIN_OVERLAP = 64
"""Fewest columns two neighbouring windows share [px, at the model's scale]."""


def window_starts(width: int, window: int, min_overlap: int = MIN_OVERLAP) -> list[int]:
    """First columns of the windows of width ``window`` that cover ``width`` columns (one at
    0 when ``width <= window``): the fewest overlapping by at least ``min_overlap`` (at most
    half a window), spread evenly from 0 to ``width − window``."""
    if width <= window:
        return [0]
    overlap = min(min_overlap, window // 2)
    n = max(2, math.ceil((width - overlap) / (window - overlap)))
    return [round(i * (width - window) / (n - 1)) for i in range(n)]


def window_weights(starts: list[int], window: int, width: int) -> np.ndarray:
    """(n, width) float32 weights of the windows (zero outside each), summing to 1 in every
    column: a column's weight in a window is its distance (+½) to the window's nearest edge
    that is not the frame's edge."""
    x = np.arange(width, dtype=np.float64) + 0.5
    weights = np.zeros((len(starts), width))
    for i, a in enumerate(starts):
        b = min(a + window, width)
        left = x - a if a > 0 else np.full(width, np.inf)
        right = b - x if b < width else np.full(width, np.inf)
        w = np.minimum(left, right)
        w[np.isinf(w)] = 1.0  # a window that spans the frame
        inside = (x > a) & (x < b)
        weights[i, inside] = w[inside]
    return (weights / weights.sum(axis=0)).astype(np.float32)


def _resize(x: np.ndarray, height: int, width: int) -> np.ndarray:
    """(batch, C, h, w) float32 resized to (batch, C, height, width): area when shrinking
    both ways, else bilinear."""
    if x.shape[2:] == (height, width):
        return x
    shrink = height <= x.shape[2] and width <= x.shape[3]
    interpolation = cv2.INTER_AREA if shrink else cv2.INTER_LINEAR
    out = np.empty((*x.shape[:2], height, width), np.float32)
    for b in range(x.shape[0]):
        for c in range(x.shape[1]):
            out[b, c] = cv2.resize(x[b, c], (width, height), interpolation=interpolation)
    return out


def windowed_logits(
    run: Callable[[np.ndarray], np.ndarray], x: np.ndarray, height: int, width: int
) -> np.ndarray:
    """Logits (batch, classes, H, W) of the frames ``x`` (batch, C, H, W) float32 for a network
    ``run`` that takes (k, C, ``height``, ``width``) and returns (k, classes, ``height``,
    ``width``) (module docstring)."""
    batch, _, h, w = x.shape
    scaled_w = max(1, round(w * height / h))
    scaled = _resize(x, height, scaled_w)
    if scaled_w < width:  # narrower than the model: the last column repeated
        scaled = np.pad(scaled, ((0, 0), (0, 0), (0, 0), (0, width - scaled_w)), mode="edge")
    starts = window_starts(scaled_w, width)
    windows = np.concatenate([scaled[..., a : a + width] for a in starts])
    logits = run(np.ascontiguousarray(windows))  # window i of frame b at i * batch + b
    weights = window_weights(starts, width, max(scaled_w, width))
    joined = np.zeros((batch, logits.shape[1], height, max(scaled_w, width)), np.float32)
    for i, a in enumerate(starts):
        part = logits[i * batch : (i + 1) * batch]
        joined[..., a : a + width] += part * weights[i, a : a + width]
    return _resize(joined[..., :scaled_w], h, w)
