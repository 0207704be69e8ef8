"""HHA depth encoding (Gupta et al., ECCV 2014) for a camera pitched down at the floor (sec. 4.1.2).

Three 8-bit channels per pixel, the segmenter's depth input (thesis sec. 4.1.2):

1. **Horizontal disparity** ``1/z``, mapped linearly from ``[1/max_depth_m, 1/min_depth_m]`` to
   ``[1, 255]``. The published encoding (``31000/z`` with ``z`` clamped to ≥ 1 m, z in mm)
   saturates at 255 for every pixel closer than about 1.2 m, i.e. all of a waist camera's feet;
   scaling to the camera's working range (default 0.3–3 m) keeps the channel strictly monotone
   there.
2. **Height above the floor** ``h + n·p`` (thesis (3.23), corrected sign; the plane ``n·p + h =
   0`` of :mod:`gaitnet.geometry.floor_plane`), mapped from ``[min_height_m, max_height_m]`` to
   ``[1, 255]``. The published encoding measures height above the lowest point along gravity;
   here the floor plane is fitted (:func:`~gaitnet.geometry.floor_plane.fit_floor_depth`) with
   the IMU's gravity as prior, so height 0 is the floor even where the floor is not the lowest
   point in view.
3. **Angle** between the local surface normal (oriented towards the camera) and the up
   direction, mapped from ``[0°, 180°]`` to ``[1, 255]`` (0° floor and box tops → 1, 90°
   vertical faces → 128 as in the published ``angle + 38`` offset's spirit, 180° → 255).

Invalid depth (``≤ 0`` or non-finite) is 0 in every channel; a valid code is never 0, so the
network can tell "no data" from any measured value.

Up direction and floor (the published method estimates gravity iteratively from a
forward-looking camera's normals, which fails for a camera pitched 40–80° down):

* ``gravity_C`` given (the IMU's gravity in the camera frame, unit, pointing down): up =
  ``-gravity_C``; the floor is the RANSAC plane whose normal lies within
  ``floor.max_angle_from_prior_deg`` of it.
* ``gravity_C`` None (no IMU): the floor is the plane with the most inliers among hypotheses
  within ``no_imu_max_angle_deg`` of the up direction of a camera pitched ``no_imu_pitch_deg``
  down without roll (``(0, -cos p, -sin p)`` in the OpenCV camera frame), and up is the fitted
  floor normal. With the defaults (60°, 45°) this covers pitches 15°–105° while a wall facing
  the camera (90° from up) stays out of the cone. It fails where the floor is not the dominant
  plane in that cone (a large table or box top filling the view, too few floor pixels): height
  and angle are then 0 (unknown), as they are for every pixel when no plane is found.
* ``plane`` given: used as the floor as it is (no fit), e.g. the filter's estimate.
* gravity given but no floor found: height is measured from the ``lowest_point_percentile``
  of the heights along up (the published fallback); angle uses gravity.

Normals (vectorised, no per-pixel plane fits): for a depth image ``z(u, v)`` the back-projected
point is ``p = z r`` with ``r = ((u − cx)/fx, (v − cy)/fy, 1)``; the cross product of
``∂p/∂u`` and ``∂p/∂v`` is, up to a positive factor ``z/(fx fy)``,
``n ∝ (fx z_u, fy z_v, −(z + fx z_u r_x + fy z_v r_y))`` (oriented towards the camera), with
``z_u``, ``z_v`` central differences over ``±normal_step_px``. Differences across a depth
jump larger than ``max_depth_jump`` × z per pixel (an object's silhouette) or touching invalid
depth are dropped; the unit normals are then averaged over a ``normal_window_px`` box (OpenCV) and
renormalised. A pixel whose window holds no usable difference has angle 0 (unknown). Skew in
``K`` is ignored.

``stride`` > 1 encodes every ``stride``-th pixel of every ``stride``-th row (the depth sampled,
not averaged: no mixing across a silhouette; ``K``, ``normal_step_px`` and ``normal_window_px``
scaled to match) and repeats each code over its ``stride × stride`` block, so the result keeps
the frame's size. A segmenter whose streams see the frame resized by ``input_scale`` 0.5 sees
exactly that half-resolution HHA (its bilinear halving averages 2 × 2 equal codes):
:func:`hha_stride` gives the stride that matches a model, at a quarter of the cost.
"""

from __future__ import annotations

import hashlib
import json
import logging
import math
from dataclasses import asdict, dataclass, field, replace

import cv2
import numpy as np

from gaitnet.checks import check_int_range, check_positive, check_range
from gaitnet.errors import InputError
from gaitnet.geometry.floor_plane import FloorParams, FloorPlane, fit_floor_depth, height_map

log = logging.getLogger(__name__)

__all__ = [
    "HHA_VERSION",
    "HhaParams",
    "find_floor",
    "hha_decode",
    "hha_encode",
    "hha_stride",
    "surface_normals",
]

HHA_VERSION = 1
"""Bumped whenever the encoding changes; part of :meth:`HhaParams.fingerprint` (caches)."""

ANGLE_RANGE_DEG = 180.0


@dataclass(frozen=True)
class HhaParams:
    """HHA encoding settings (module docstring). Checked in ``__post_init__``."""

    min_depth_m: float = 0.3
    """Depth coded 255 in the disparity channel [m]; closer depths saturate at 255."""
    max_depth_m: float = 3.0
    """Depth coded 1 [m]; farther depths saturate at 1 (D455 noise ≈ 1 cm at 3 m)."""
    min_height_m: float = -0.05
    """Height coded 1 [m] (a little below the floor: depth noise and floor relief)."""
    max_height_m: float = 1.2
    """Height coded 255 [m] (a waist camera at ~1 m sees legs up to about its own height)."""
    normal_step_px: int = 3
    """Half baseline of the central depth differences [px]: D455-like depth noise makes 1-px
    differences useless (on simulated 640×480 frames, floor angle median / p95: 1 px and a 5 px
    window 10.4° / 23.4°, 3 px and a 9 px window 5.2° / 11.5°)."""
    normal_window_px: int = 9
    """Side of the box over which unit normals are averaged [px] (odd); with the step above a
    normal describes about ``normal_window_px + 2 normal_step_px`` pixels (15 px ≈ 2.5 cm at
    1 m for a 640×480 D455)."""
    max_depth_jump: float = 0.05
    """Largest relative depth change per pixel of a usable difference (a floor seen at 3 m,
    1 m below a 385 px camera pitched 20°, changes 0.7 % per pixel; a foot's edge > 5 %)."""
    floor: FloorParams = field(default_factory=FloorParams)
    """RANSAC floor fit (:class:`~gaitnet.geometry.floor_plane.FloorParams`)."""
    no_imu_pitch_deg: float = 60.0
    """Without gravity: the assumed camera pitch below the horizon [deg] of the prior up."""
    no_imu_max_angle_deg: float = 45.0
    """Without gravity: the floor normal's largest angle from that prior [deg]."""
    lowest_point_percentile: float = 1.0
    """Gravity given but no floor found: this percentile of the heights is height 0 [%]."""

    def __post_init__(self) -> None:
        check_positive("min_depth_m", self.min_depth_m, " m")
        check_range("max_depth_m", self.max_depth_m, self.min_depth_m * 1.01, 100.0, " m")
        check_range("min_height_m", self.min_height_m, -10.0, 10.0, " m")
        check_range("max_height_m", self.max_height_m, self.min_height_m + 0.01, 20.0, " m")
        check_int_range("normal_step_px", self.normal_step_px, 1, 16)
        window = check_int_range("normal_window_px", self.normal_window_px, 1, 63)
        if window % 2 == 0:
            raise ValueError(f"normal_window_px must be odd, got {window}")
        check_range("max_depth_jump", self.max_depth_jump, 1e-4, 1.0)
        if not isinstance(self.floor, FloorParams):
            raise ValueError(f"floor must be FloorParams, got {type(self.floor).__name__}")
        check_range("no_imu_pitch_deg", self.no_imu_pitch_deg, 0.0, 90.0, "°")
        check_range("no_imu_max_angle_deg", self.no_imu_max_angle_deg, 1.0, 89.0, "°")
        check_range("lowest_point_percentile", self.lowest_point_percentile, 0.0, 50.0, " %")

    def fingerprint(self) -> str:
        """A short hash of every setting and :data:`HHA_VERSION` (stale-cache detection)."""
        text = json.dumps({"version": HHA_VERSION, **asdict(self)}, sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


def _code(x: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """``[lo, hi]`` → 1..255 (uint8, clipped), the HHA codes of valid pixels."""
    scale = np.float32(254.0 / (hi - lo))
    y = (x - np.float32(lo)) * scale
    np.clip(y, 0.0, 254.0, out=y)
    y += np.float32(1.5)  # 1 + round-half-up
    return y.astype(np.uint8)


def _uncode(c: np.ndarray, lo: float, hi: float) -> np.ndarray:
    out = lo + (c.astype(np.float32) - 1.0) * np.float32((hi - lo) / 254.0)
    out[c == 0] = np.nan
    return out


def _check_inputs(depth_m, K, gravity_C) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    depth = np.asarray(depth_m)
    if depth.ndim != 2 or depth.shape[0] < 2 or depth.shape[1] < 2:
        raise InputError(f"HHA: depth must be an (H, W) image, got shape {depth.shape}")
    if not np.issubdtype(depth.dtype, np.floating):
        raise InputError(f"HHA: depth must be float metres, got dtype {depth.dtype}")
    K = np.asarray(K, dtype=np.float64)
    if K.shape != (3, 3) or not np.isfinite(K).all() or K[0, 0] <= 0 or K[1, 1] <= 0:
        raise InputError("HHA: K must be a finite 3×3 camera matrix with positive fx, fy")
    up = None
    if gravity_C is not None:
        g = np.asarray(gravity_C, dtype=np.float64).reshape(-1)
        norm = float(np.linalg.norm(g)) if g.shape == (3,) and np.isfinite(g).all() else 0.0
        if norm < 1e-6:
            raise InputError(f"HHA: gravity must be a finite non-zero 3-vector, got {gravity_C!r}")
        up = -g / norm
    z = np.where(np.isfinite(depth) & (depth > 0), depth, 0).astype(np.float32)
    return z, K, up


def surface_normals(
    depth_m: np.ndarray,
    K: np.ndarray,
    window_px: int = 9,
    max_depth_jump: float = 0.05,
    step_px: int = 3,
) -> np.ndarray:
    """Unit surface normals (H, W, 3) float32 in the camera frame, oriented towards the camera.

    ``depth_m`` float metres, 0 = invalid; ``step_px`` the half baseline of the central
    differences. Zero vectors where no normal is known (invalid depth, or no usable difference
    in the window). Module docstring for the method.
    """
    z = np.asarray(depth_m, dtype=np.float32)
    H, W = z.shape
    k = int(step_px)
    fx, fy, cx, cy = (np.float32(K[0, 0]), np.float32(K[1, 1]), K[0, 2], K[1, 2])
    valid = z > 0
    zu = np.zeros_like(z)
    zv = np.zeros_like(z)
    half = np.float32(0.5 / k)
    zu[:, k:-k] = (z[:, 2 * k :] - z[:, : -2 * k]) * half
    zv[k:-k, :] = (z[2 * k :, :] - z[: -2 * k, :]) * half
    ok = np.zeros_like(valid)
    ok[k:-k, k:-k] = (
        valid[k:-k, k:-k]
        & valid[k:-k, 2 * k :]
        & valid[k:-k, : -2 * k]
        & valid[2 * k :, k:-k]
        & valid[: -2 * k, k:-k]
    )
    jump = np.float32(max_depth_jump) * z
    ok &= (np.abs(zu) <= jump) & (np.abs(zv) <= jump)
    rx = ((np.arange(W, dtype=np.float32) - np.float32(cx)) / fx)[None, :]
    ry = ((np.arange(H, dtype=np.float32) - np.float32(cy)) / fy)[:, None]
    n = np.empty((H, W, 3), np.float32)
    a = zu * fx
    b = zv * fy
    n[..., 0] = a
    n[..., 1] = b
    n[..., 2] = -(z + a * rx + b * ry)
    norm = np.sqrt(np.einsum("ijk,ijk->ij", n, n))
    scale = np.where(ok, 1.0 / np.maximum(norm, np.float32(1e-12)), np.float32(0.0))
    n *= scale[..., None].astype(np.float32)
    if window_px > 1:
        n = cv2.blur(n, (window_px, window_px), borderType=cv2.BORDER_CONSTANT)
    norm = np.sqrt(np.einsum("ijk,ijk->ij", n, n))
    known = valid & (norm > np.float32(1e-3))
    n *= np.where(known, 1.0 / np.maximum(norm, np.float32(1e-12)), 0.0)[..., None].astype(
        np.float32
    )
    return n


def find_floor(
    depth_m: np.ndarray, K: np.ndarray, up_C: np.ndarray | None, params: HhaParams
) -> FloorPlane | None:
    """The floor plane for HHA: gravity prior when ``up_C`` is given, else the no-IMU prior."""
    if up_C is not None:
        return fit_floor_depth(depth_m, K, up_C, params.floor)
    p = math.radians(params.no_imu_pitch_deg)
    prior = np.array([0.0, -math.cos(p), -math.sin(p)])
    floor = replace(params.floor, max_angle_from_prior_deg=params.no_imu_max_angle_deg)
    return fit_floor_depth(depth_m, K, prior, floor)


def hha_stride(input_scale: float) -> int:
    """The HHA ``stride`` for a segmenter that resizes its input by ``input_scale``: the whole
    number of frame pixels per stream pixel, rounded down (1 for scales above 1/2)."""
    if not (isinstance(input_scale, (int, float)) and 0 < input_scale <= 1):
        raise InputError(f"HHA: input_scale must be in (0, 1], got {input_scale!r}")
    return max(1, int(1.0 / input_scale + 1e-6))


def _strided(
    depth_m: np.ndarray, K: np.ndarray, params: HhaParams, stride: int
) -> tuple[np.ndarray, np.ndarray, HhaParams]:
    """Every ``stride``-th depth pixel, the camera matrix of that grid and the normal window
    scaled to it (odd, ≥ 1)."""
    K_s = np.array(K, dtype=np.float64)
    K_s[:2] /= stride
    window = 2 * round((params.normal_window_px / stride - 1) / 2) + 1
    scaled = replace(
        params,
        normal_step_px=max(1, round(params.normal_step_px / stride)),
        normal_window_px=max(1, window),
    )
    return np.asarray(depth_m)[::stride, ::stride], K_s, scaled


def hha_encode(
    depth_m: np.ndarray,
    K: np.ndarray,
    gravity_C: np.ndarray | None = None,
    params: HhaParams | None = None,
    plane: FloorPlane | None = None,
    stride: int = 1,
) -> np.ndarray:
    """HHA image (H, W, 3) uint8 of a depth image in metres (0 or non-finite = invalid).

    ``gravity_C``: unit gravity (pointing down) in the camera frame, or None without an IMU;
    ``plane``: a known floor (skips the fit); ``stride``: encode every ``stride``-th pixel and
    repeat it (module docstring). Module docstring for the channels and fallbacks. Bad arrays
    raise :class:`~gaitnet.errors.InputError`.
    """
    params = params or HhaParams()
    if isinstance(stride, bool) or not isinstance(stride, int) or stride < 1:
        raise InputError(f"HHA: stride must be a whole number ≥ 1, got {stride!r}")
    if stride > 1:
        shape = np.shape(depth_m)
        if len(shape) != 2:
            raise InputError(f"HHA: depth must be an (H, W) image, got shape {shape}")
        small_depth, K_s, small_params = _strided(depth_m, K, params, stride)
        small = hha_encode(small_depth, K_s, gravity_C, small_params, plane)
        big = np.repeat(np.repeat(small, stride, axis=0), stride, axis=1)
        return np.ascontiguousarray(big[: shape[0], : shape[1]])
    z, K, up = _check_inputs(depth_m, K, gravity_C)
    H, W = z.shape
    valid = z > 0
    out = np.zeros((H, W, 3), np.uint8)
    if not valid.any():
        return out
    # 1. disparity
    inv = np.divide(np.float32(1.0), z, out=np.zeros_like(z), where=valid)
    out[..., 0] = _code(inv, 1.0 / params.max_depth_m, 1.0 / params.min_depth_m)
    # 2. height above the floor
    if plane is None:
        plane = find_floor(z, K, up, params)
    if up is None and plane is not None:
        up = np.asarray(plane.n_C, dtype=np.float64)
    height: np.ndarray | None = None
    if plane is not None:
        height = height_map(z, K, plane)
    elif up is not None:
        log.debug("HHA: no floor found; height from the lowest points along gravity")
        along = height_map(z, K, FloorPlane(n_C=up, h=0.0))
        height = along - np.float32(np.nanpercentile(along, params.lowest_point_percentile))
    if height is not None:
        out[..., 1] = _code(np.nan_to_num(height), params.min_height_m, params.max_height_m)
    # 3. angle between the surface normal and up
    if up is not None:
        n = surface_normals(
            z, K, params.normal_window_px, params.max_depth_jump, params.normal_step_px
        )
        cos = n @ up.astype(np.float32)
        known = np.einsum("ijk,ijk->ij", n, n) > 0.5
        angle = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
        out[..., 2] = np.where(known, _code(angle, 0.0, ANGLE_RANGE_DEG), 0)
    out[~valid] = 0
    return out


def hha_decode(
    hha: np.ndarray, params: HhaParams | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Invert the coding: (depth from disparity [m], height [m], angle [deg]), float32,
    NaN where a channel is 0 (unknown). Saturated codes decode to the range ends."""
    params = params or HhaParams()
    hha = np.asarray(hha)
    if hha.ndim != 3 or hha.shape[2] != 3 or hha.dtype != np.uint8:
        raise InputError(f"HHA: expected an (H, W, 3) uint8 image, got {hha.dtype} {hha.shape}")
    inv = _uncode(hha[..., 0], 1.0 / params.max_depth_m, 1.0 / params.min_depth_m)
    height = _uncode(hha[..., 1], params.min_height_m, params.max_height_m)
    angle = _uncode(hha[..., 2], 0.0, ANGLE_RANGE_DEG)
    return 1.0 / inv, height, angle
