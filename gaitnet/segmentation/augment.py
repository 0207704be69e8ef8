"""Training augmentations that keep RGB, HHA, label and side maps aligned (thesis sec. 4.1.3).

:func:`augment_sample` applies, in this order, with one random generator:

1. **Horizontal flip** (probability ``hflip_prob``): every map is mirrored, and left and right
   swap in the side map (1 ↔ 2), since a mirrored left foot looks like a right one. The HHA
   image is mirrored as it is, which equals the HHA of the mirrored depth image: mirroring the
   image is the camera frame's reflection ``x → −x`` with ``cx → W − 1 − cx``; depth ``z``,
   hence disparity, is unchanged; the floor normal and every surface normal are reflected the
   same way, so heights above the floor (``h + n·p``) and angles between normals and gravity are
   unchanged for every surface point, and each point moves to the mirrored pixel.
2. **Random scale and crop**: a scale factor drawn uniformly in ``[scale_min, scale_max]``
   resizes every map (RGB bilinear; HHA, labels and sides nearest-neighbour, so no value is
   invented across a silhouette or between valid and invalid depth), then a window of the crop
   size (``crop_height`` × ``crop_width``; 0 keeps the input's size) is cut at a random place.
   Where the scaled image is smaller than the window it is padded: RGB 0, HHA 0 (= no depth),
   label 255 (ignored by the loss), side 0. Resizing equals a change of focal length: each
   pixel's HHA values (disparity ``1/z``, height, angle) belong to the surface point and do not
   depend on the intrinsics, so they stay right.
3. **Colour jitter, RGB only**: brightness (a factor in ``[1 − b, 1 + b]``), contrast (around the
   image's mean grey, factor in ``[1 − c, 1 + c]``) and saturation (blend with the grey image,
   factor in ``[1 − s, 1 + s]``), then clipped to ``[0, 1]``.

The depth is not augmented (no depth noise): HHA is computed once per frame and cached
(:mod:`gaitnet.segmentation.dataset`); the simulator's sensor model already adds depth noise.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from gaitnet.checks import check_int_range, check_range

__all__ = ["AugmentParams", "Sample", "augment_sample", "flip_sides"]

IGNORE = 255
LUMA = np.array([0.299, 0.587, 0.114], np.float32)  # ITU-R BT.601, as torchvision's grayscale


@dataclass(frozen=True)
class AugmentParams:
    """Augmentation settings (module docstring); every one checked in ``__post_init__``."""

    hflip_prob: float = 0.5
    """Probability of a horizontal flip (sides swap)."""
    scale_min: float = 0.8
    """Smallest random scale factor (1 with ``scale_max`` 1: no scaling)."""
    scale_max: float = 1.25
    """Largest random scale factor."""
    crop_height: int = 0
    """Height of the random crop [px]; 0 = the input's height."""
    crop_width: int = 0
    """Width of the random crop [px]; 0 = the input's width."""
    brightness: float = 0.25
    """Brightness jitter ``b``: factor in ``[1 − b, 1 + b]`` (0: none)."""
    contrast: float = 0.25
    """Contrast jitter ``c``: factor in ``[1 − c, 1 + c]`` (0: none)."""
    saturation: float = 0.25
    """Saturation jitter ``s``: factor in ``[1 − s, 1 + s]`` (0: none)."""

    def __post_init__(self) -> None:
        check_range("hflip_prob", self.hflip_prob, 0.0, 1.0)
        check_range("scale_min", self.scale_min, 0.1, 10.0)
        check_range("scale_max", self.scale_max, self.scale_min, 10.0)
        check_int_range("crop_height", self.crop_height, 0, 16384)
        check_int_range("crop_width", self.crop_width, 0, 16384)
        for name in ("brightness", "contrast", "saturation"):
            check_range(name, getattr(self, name), 0.0, 0.99)


@dataclass
class Sample:
    """One frame's aligned maps: ``rgb`` (H, W, 3) uint8 or float32 in [0, 1], ``hha`` (H, W,
    3) uint8, ``label`` (H, W) uint8 (255 ignore), ``side`` (H, W) uint8 (0 none, 1 left,
    2 right)."""

    rgb: np.ndarray
    hha: np.ndarray
    label: np.ndarray
    side: np.ndarray


_SWAP = np.arange(256, dtype=np.uint8)
_SWAP[1], _SWAP[2] = 2, 1


def flip_sides(side: np.ndarray) -> np.ndarray:
    """Side map with left (1) and right (2) swapped; other values kept."""
    return _SWAP[side]


def _flip(s: Sample) -> Sample:
    return Sample(
        np.ascontiguousarray(s.rgb[:, ::-1]),
        np.ascontiguousarray(s.hha[:, ::-1]),
        np.ascontiguousarray(s.label[:, ::-1]),
        flip_sides(np.ascontiguousarray(s.side[:, ::-1])),
    )


def _resize(s: Sample, scale: float) -> Sample:
    h, w = s.label.shape
    size = (max(1, round(w * scale)), max(1, round(h * scale)))
    if size == (w, h):
        return s
    near = cv2.INTER_NEAREST_EXACT
    return Sample(
        cv2.resize(s.rgb, size, interpolation=cv2.INTER_LINEAR),
        cv2.resize(s.hha, size, interpolation=near),
        cv2.resize(s.label, size, interpolation=near),
        cv2.resize(s.side, size, interpolation=near),
    )


def _window(a: np.ndarray, top: int, left: int, h: int, w: int, fill: int) -> np.ndarray:
    """The ``h`` × ``w`` window of ``a`` at (top, left), which may reach outside (``fill``)."""
    out = np.full((h, w, *a.shape[2:]), fill, a.dtype)
    H, W = a.shape[:2]
    y0, x0 = max(top, 0), max(left, 0)
    y1, x1 = min(top + h, H), min(left + w, W)
    if y1 > y0 and x1 > x0:
        out[y0 - top : y1 - top, x0 - left : x1 - left] = a[y0:y1, x0:x1]
    return out


def _crop(s: Sample, h: int, w: int, rng: np.random.Generator) -> Sample:
    H, W = s.label.shape
    # the window's top-left corner relative to the image: inside when the image is larger,
    # a negative offset (padding) when it is smaller
    top = int(rng.integers(min(0, H - h), max(0, H - h) + 1))
    left = int(rng.integers(min(0, W - w), max(0, W - w) + 1))
    return Sample(
        _window(s.rgb, top, left, h, w, 0),
        _window(s.hha, top, left, h, w, 0),
        _window(s.label, top, left, h, w, IGNORE),
        _window(s.side, top, left, h, w, 0),
    )


def _jitter(rgb: np.ndarray, p: AugmentParams, rng: np.random.Generator) -> np.ndarray:
    x = rgb.astype(np.float32)
    if rgb.dtype == np.uint8:
        x /= np.float32(255.0)  # as the data set's uint8 → float conversion
    b, c, s = (float(rng.uniform(1 - v, 1 + v)) for v in (p.brightness, p.contrast, p.saturation))
    if b != 1.0:
        x *= np.float32(b)
    if c != 1.0:
        mean = np.float32((x @ LUMA).mean())
        x = (x - mean) * np.float32(c) + mean
    if s != 1.0:
        grey = (x @ LUMA)[..., None]
        x = grey + (x - grey) * np.float32(s)
    return np.clip(x, 0.0, 1.0, out=x)


def augment_sample(s: Sample, params: AugmentParams, rng: np.random.Generator) -> Sample:
    """The augmented sample (module docstring); ``rgb`` comes back float32 in [0, 1].

    The input's maps must share their height and width (uint8 RGB or float32 in [0, 1]).
    """
    if rng.random() < params.hflip_prob:
        s = _flip(s)
    H, W = s.label.shape
    scale = float(rng.uniform(params.scale_min, params.scale_max))
    s = _resize(s, scale)
    s = _crop(s, params.crop_height or H, params.crop_width or W, rng)
    return Sample(_jitter(s.rgb, params, rng), s.hha, s.label, s.side)
