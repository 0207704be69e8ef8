"""Sparse feature tracking between two RGB-D frames for the visual odometry (front end).

Corners are detected in the previous frame where the depth is valid (so each one has a 3-D
point), and tracked into the current frame by pyramidal Lucas–Kanade optical flow started at
the positions the IMU-predicted motion gives them. A forward–backward check and Lucas–Kanade's
own minimum-eigenvalue test drop tracks that slid or sit on texture-poor patches.

All pixel coordinates here are at the *working* resolution (``scale`` × the frame's).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2 as cv
import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

__all__ = [
    "NOISE_GRADIENT_GAIN",
    "PreparedImage",
    "detect_corners",
    "predict_pixels",
    "prepare_image",
    "sample_depth",
    "structure_tensors",
    "track_corners",
]


@dataclass(frozen=True)
class PreparedImage:
    """One frame at the working resolution: grey image and the depth [m].

    ``depth_m`` stays at the full resolution (sampled at the scaled-up corner positions).
    """

    gray: NDArray[np.uint8]
    depth_m: NDArray[np.float32]
    scale: float


def prepare_image(rgb: np.ndarray, depth_m: np.ndarray, scale: float) -> PreparedImage:
    """Grey image at ``scale`` × the frame size (OpenCV's Python binding takes no prebuilt
    optical-flow pyramid, so Lucas–Kanade builds its own)."""
    gray = cv.cvtColor(rgb, cv.COLOR_RGB2GRAY)
    if scale != 1.0:
        size = (round(gray.shape[1] * scale), round(gray.shape[0] * scale))
        gray = cv.resize(gray, size, interpolation=cv.INTER_AREA)
    return PreparedImage(gray=gray, depth_m=depth_m, scale=scale)


def sample_depth(depth_m: np.ndarray, uv: FloatArray, scale: float) -> FloatArray:
    """Depth [m] at working-resolution pixels ``uv`` (n, 2), nearest full-resolution pixel."""
    h, w = depth_m.shape
    col = np.clip(np.rint((uv[:, 0] + 0.5) / scale - 0.5).astype(np.int64), 0, w - 1)
    row = np.clip(np.rint((uv[:, 1] + 0.5) / scale - 0.5).astype(np.int64), 0, h - 1)
    return depth_m[row, col].astype(np.float64)


def valid_depth_mask(
    depth_m: np.ndarray, shape: tuple[int, int], min_m: float, max_m: float, erode_px: int
) -> NDArray[np.uint8]:
    """Mask (255 = usable) at the working size ``shape`` of pixels with depth in
    ``[min_m, max_m]``, eroded by ``erode_px`` so that corners keep away from depth edges."""
    valid = ((depth_m >= min_m) & (depth_m <= max_m)).astype(np.uint8) * 255
    if valid.shape != shape:
        valid = cv.resize(valid, (shape[1], shape[0]), interpolation=cv.INTER_NEAREST)
    if erode_px > 0:
        kernel = np.ones((2 * erode_px + 1, 2 * erode_px + 1), np.uint8)
        valid = cv.erode(valid, kernel)
    return valid


def detect_corners(
    image: PreparedImage,
    K: FloatArray,
    *,
    max_corners: int,
    quality: float,
    min_distance_px: float,
    min_depth_m: float,
    max_depth_m: float,
    border_px: int,
) -> tuple[FloatArray, FloatArray]:
    """Shi–Tomasi corners where the depth is valid, and their 3-D points in the camera frame.

    ``K`` is the working-resolution camera matrix. Returns ``uv`` (n, 2) and ``p_C`` (n, 3).
    """
    gray = image.gray
    mask = valid_depth_mask(image.depth_m, gray.shape, min_depth_m, max_depth_m, 2)
    if border_px > 0:
        mask[:border_px] = 0
        mask[-border_px:] = 0
        mask[:, :border_px] = 0
        mask[:, -border_px:] = 0
    if not mask.any():
        return np.zeros((0, 2)), np.zeros((0, 3))
    corners = cv.goodFeaturesToTrack(
        gray, max_corners, quality, min_distance_px, mask=mask, blockSize=5
    )
    if corners is None:
        return np.zeros((0, 2)), np.zeros((0, 3))
    uv = corners.reshape(-1, 2).astype(np.float64)
    z = sample_depth(image.depth_m, uv, image.scale)
    keep = (z >= min_depth_m) & (z <= max_depth_m)
    uv, z = uv[keep], z[keep]
    x = (uv[:, 0] - K[0, 2]) / K[0, 0] * z
    y = (uv[:, 1] - K[1, 2]) / K[1, 1] * z
    return uv, np.stack([x, y, z], axis=1)


def predict_pixels(K: FloatArray, R: FloatArray, t: FloatArray, p: FloatArray) -> FloatArray:
    """Pixels of points ``p`` (n, 3) after the motion ``R p + t`` (NaN behind the camera)."""
    q = p @ R.T + t
    z = np.where(q[:, 2] > 1e-6, q[:, 2], np.nan)
    return np.stack([K[0, 0] * q[:, 0] / z + K[0, 2], K[1, 1] * q[:, 1] / z + K[1, 2]], axis=1)


def track_corners(
    prev: PreparedImage,
    cur: PreparedImage,
    uv_prev: FloatArray,
    uv_guess: FloatArray,
    *,
    window_px: int,
    levels: int,
    min_eig: float,
    fb_max_px: float,
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Pyramidal Lucas–Kanade from ``uv_prev`` into ``cur``, started at ``uv_guess``.

    Returns the tracked positions (n, 2) and a mask of good tracks: LK converged, the patch's
    normalised minimum eigenvalue is at least ``min_eig`` (texture), inside the image, and
    (when ``fb_max_px`` > 0) tracking back lands within ``fb_max_px`` of the start.
    """
    h, w = cur.gray.shape
    guess = np.where(np.isfinite(uv_guess), uv_guess, uv_prev)
    guess = np.clip(guess, 0.0, [w - 1.0, h - 1.0])
    p0 = uv_prev.astype(np.float32).reshape(-1, 1, 2)
    p1 = guess.astype(np.float32).reshape(-1, 1, 2)
    criteria = (cv.TERM_CRITERIA_COUNT | cv.TERM_CRITERIA_EPS, 30, 0.01)
    p1, status, _ = cv.calcOpticalFlowPyrLK(
        prev.gray,
        cur.gray,
        p0,
        p1,
        winSize=(window_px, window_px),
        maxLevel=levels,
        criteria=criteria,
        flags=cv.OPTFLOW_USE_INITIAL_FLOW,
        minEigThreshold=min_eig,
    )
    good = status.reshape(-1).astype(bool)
    uv_cur = p1.reshape(-1, 2).astype(np.float64)
    inside = (
        (uv_cur[:, 0] >= 0)
        & (uv_cur[:, 0] <= w - 1)
        & (uv_cur[:, 1] >= 0)
        & (uv_cur[:, 1] <= h - 1)
    )
    good &= inside
    if fb_max_px > 0 and good.any():
        idx = np.flatnonzero(good)
        back, status_b, _ = cv.calcOpticalFlowPyrLK(
            cur.gray,
            prev.gray,
            p1[idx],
            p0[idx].copy(),
            winSize=(window_px, window_px),
            maxLevel=levels,
            criteria=criteria,
            flags=cv.OPTFLOW_USE_INITIAL_FLOW,
            minEigThreshold=min_eig,
        )
        fb = np.linalg.norm(back.reshape(-1, 2) - uv_prev[idx], axis=1)
        good[idx] = status_b.reshape(-1).astype(bool) & (fb <= fb_max_px)
    return uv_cur, good


NOISE_GRADIENT_GAIN = 12.0 / 64.0
"""Mean square of the Sobel(3)/8 derivative of white noise of unit variance (per axis):
``(1² + 2² + 1²) · 2 / 8²``."""


def structure_tensors(gray: np.ndarray, uv: FloatArray, window_px: int) -> FloatArray:
    """Gradient structure tensors ``G = Σ ∇I ∇Iᵀ`` (n, 2, 2) over the ``window_px`` square
    around each pixel ``uv`` (n, 2, rounded); gradients by Sobel(3)/8 in grey levels per pixel.

    Lucas–Kanade solves ``G d = b`` over the same window, so with image noise of variance
    ``σ²`` its displacement error has covariance ``≈ 2 σ² G⁻¹`` (both images noisy), and a
    patch of pure noise has ``G ≈ N · NOISE_GRADIENT_GAIN · σ² · I`` (N pixels).
    """
    h, w = gray.shape
    gx = cv.Sobel(gray, cv.CV_32F, 1, 0, ksize=3, scale=1.0 / 8.0)
    gy = cv.Sobel(gray, cv.CV_32F, 0, 1, ksize=3, scale=1.0 / 8.0)
    box = (window_px, window_px)
    col = np.clip(np.rint(uv[:, 0]).astype(np.int64), 0, w - 1)
    row = np.clip(np.rint(uv[:, 1]).astype(np.int64), 0, h - 1)
    G = np.empty((len(uv), 2, 2))
    for (i, j), prod in (((0, 0), gx * gx), ((1, 1), gy * gy), ((0, 1), gx * gy)):
        summed = cv.boxFilter(prod, -1, box, normalize=False, borderType=cv.BORDER_REFLECT)
        G[:, i, j] = summed[row, col]
    G[:, 1, 0] = G[:, 0, 1]
    return G
