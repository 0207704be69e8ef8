"""Visual odometry: relative camera motion between consecutive RGB-D frames (front end).

:meth:`FrameOdometry.estimate` measures ``T_CkfromCk1`` (``p_Ck = R p_Ck-1 + t``, the
``(q_vo, t_vo)`` of D.-C. Dang's thesis (3.11)–(3.13)) and its covariance for the VO update
(3.21). The thesis aligns the frames densely (Kerl et al.'s photometric RGB-D odometry); OpenCV
5's dense ``cv.Odometry`` cannot be seeded with the IMU prediction (its ``compute`` starts from
the identity) and is wrong at walking speed (docs/vio.md), so this module tracks sparse corners
instead:

1. Shi–Tomasi corners in the previous frame where the depth is valid → 3-D points ``p_Ck-1``;
2. pyramidal Lucas–Kanade into the current frame, *started at the pixels the IMU-predicted
   motion* ``T_guess`` *gives them*, with a forward–backward check;
3. RANSAC PnP (the guess tried first) + Levenberg–Marquardt on the inliers
   (:mod:`gaitnet.vio.odometry_pose`) — the legs and shoes move on their own and fall out;
4. covariance ``σ² (JᵀJ)⁻¹`` over ``(dφ, dt)`` from the inlier reprojections, ``σ`` the inlier
   residual RMS (floored): the thesis's residual-scaled noise. Directions the corners barely
   constrain (eigenvalues of the information below a floor) get a large variance, so the
   filter lets the IMU carry them. Then a floor proportional to the motion
   (:func:`motion_floor`) for the errors that neither the corners of a pair nor consecutive
   pairs average out (motion blur above all);
5. checks: enough depth, corners, tracks and inliers, and a result near the guess — else
   ``ok = False`` with the reason, and the filter skips the update.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from gaitnet.errors import InputError
from gaitnet.geometry.rotation import so3_log
from gaitnet.io.types import Frame
from gaitnet.vio.odometry_pose import fit_pose, pose_information
from gaitnet.vio.odometry_tracking import (
    NOISE_GRADIENT_GAIN,
    PreparedImage,
    detect_corners,
    predict_pixels,
    prepare_image,
    structure_tensors,
    track_corners,
)

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]

__all__ = ["FrameOdometry", "OdometryParams", "VoResult"]


@dataclass(frozen=True)
class OdometryParams:
    """Settings of :class:`FrameOdometry` (pixel values at the working resolution).

    ``scale``: working resolution as a fraction of the frame's. ``max_corners``,
    ``corner_quality``, ``corner_min_distance_px``: Shi–Tomasi detection. ``min_depth_m``,
    ``max_depth_m``: depth range of usable corners. ``lk_window_px``, ``lk_levels``,
    ``lk_min_eig``: Lucas–Kanade window, pyramid levels, and minimum normalised eigenvalue of
    the patch's gradient matrix. ``image_noise_grey``: image noise standard deviation [grey
    levels] at full resolution; ``texture_snr``: a corner is kept only if its window's
    structure tensor has both eigenvalues ≥ ``texture_snr`` × that of pure noise — the
    texture test that makes a texture-poor floor fail instead of returning the IMU guess
    (seeded tracks on noise stay where they were started). ``fb_max_px``: largest
    forward–backward tracking error (0 = no check). ``ransac_px``, ``ransac_iterations``,
    ``inlier_chi2``: RANSAC threshold, iterations, and the final inlier gate on the
    Mahalanobis residual (χ²(2) 99 %: 9.21). ``min_inliers``:
    fewer → ``ok = False``. ``sigma_min_px``: floor of the residual-scaled pixel noise;
    ``common_px``: standard deviation of an image shift shared by all corners [px, full
    resolution]; ``cov_scale``: multiplies the covariance (tracking errors are correlated, so
    the least-squares covariance is optimistic). ``motion_std``: the errors that grow with the
    motion (:func:`motion_floor`: motion blur, rolling shutter, frame time, depth scale), as a
    standard deviation per unit of motion, added after ``cov_scale``. ``weak_std_rad``: a
    direction of the information whose standard deviation exceeds this (translation measured
    in radians at the median corner depth) is weakly constrained and gets ``weak_variance``
    (rad² / m² at 1 m);
    all six weak → ``ok = False``. ``max_guess_rotation_rad``, ``max_guess_translation_m``:
    a result farther than this from the guess is implausible → ``ok = False`` (inf = no check).
    """

    scale: float = 0.5
    max_corners: int = 300
    corner_quality: float = 0.001
    corner_min_distance_px: float = 10.0
    corner_border_px: int = 8
    min_depth_m: float = 0.3
    max_depth_m: float = 5.0
    lk_window_px: int = 21
    lk_levels: int = 3
    lk_min_eig: float = 1e-4
    image_noise_grey: float = 2.0
    texture_snr: float = 2.0
    fb_max_px: float = 0.5
    ransac_px: float = 2.0
    ransac_iterations: int = 100
    inlier_chi2: float = 9.21
    min_inliers: int = 20
    sigma_min_px: float = 0.3
    common_px: float = 1.0
    motion_std: float = 0.3
    cov_scale: float = 4.0
    weak_std_rad: float = 0.05
    weak_variance: float = 1.0
    max_guess_rotation_rad: float = math.radians(5.0)
    max_guess_translation_m: float = 0.05

    def __post_init__(self) -> None:
        if not 0.1 <= self.scale <= 1.0:
            raise InputError(f"odometry scale must be in [0.1, 1], got {self.scale}")
        if self.min_inliers < 6:
            raise InputError(f"odometry min_inliers must be ≥ 6, got {self.min_inliers}")


@dataclass(frozen=True)
class VoResult:
    """Relative camera motion ``p_Ck = R p_Ck-1 + t`` and its 6×6 covariance.

    ``cov6`` is over ``(dφ, dt)`` with ``R_true = exp([dφ]x) R``, ``t_true = t + dt``
    (rotation first; rad², m²). ``residual``: RMS inlier reprojection error [px, full
    resolution] (the thesis's ``J_vo`` analogue). ``reason``: why ``ok`` is False, or notes
    (e.g. weak directions) when True. On failure ``R``/``t`` are the guess and ``cov6`` is inf.
    """

    ok: bool
    R: FloatArray
    t: FloatArray
    cov6: FloatArray
    residual: float
    reason: str
    n_corners: int = 0
    n_tracked: int = 0
    n_inliers: int = 0
    weak_dirs: int = 0
    timings_ms: dict = field(default_factory=dict)


def _check_frame(frame: Frame, name: str) -> None:
    rgb, depth = np.asarray(frame.rgb), np.asarray(frame.depth_m)
    if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.dtype != np.uint8:
        raise InputError(
            f"{name} frame {frame.index}: rgb must be uint8 (H, W, 3), got {rgb.dtype} {rgb.shape}"
        )
    if depth.shape != rgb.shape[:2]:
        raise InputError(
            f"{name} frame {frame.index}: depth {depth.shape} does not match rgb {rgb.shape[:2]}"
        )


def _check_inputs(
    prev: Frame, cur: Frame, K: np.ndarray, T: np.ndarray
) -> tuple[FloatArray, FloatArray]:
    _check_frame(prev, "previous")
    _check_frame(cur, "current")
    if prev.rgb.shape != cur.rgb.shape:
        raise InputError(
            f"frames {prev.index} and {cur.index} differ in size: "
            f"{prev.rgb.shape[:2]} vs {cur.rgb.shape[:2]}"
        )
    K = np.asarray(K, dtype=np.float64)
    if K.shape != (3, 3) or not np.all(np.isfinite(K)) or K[0, 0] <= 0 or K[1, 1] <= 0:
        raise InputError(
            f"K must be a finite 3×3 camera matrix with positive focal lengths, got {K.tolist()}"
        )
    T = np.asarray(T, dtype=np.float64)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise InputError(f"T_guess_CkfromCk1 must be a finite 4×4 transform, got shape {T.shape}")
    R = T[:3, :3]
    if np.abs(R @ R.T - np.eye(3)).max() > 1e-5 or np.linalg.det(R) < 0:
        raise InputError("T_guess_CkfromCk1 is not a rigid transform (rotation not orthonormal)")
    return K, T


def _scaled_K(K: FloatArray, s: float) -> FloatArray:
    """Camera matrix of the images resized by ``s`` (pixel-centre model, as CameraIntrinsics)."""
    Ks = K.copy()
    Ks[0, 0] *= s
    Ks[1, 1] *= s
    Ks[0, 1] *= s
    Ks[0, 2] = (K[0, 2] + 0.5) * s - 0.5
    Ks[1, 2] = (K[1, 2] + 0.5) * s - 0.5
    return Ks


def covariance_from_information(
    info: FloatArray, depth_m: float, weak_std_rad: float, weak_variance: float
) -> tuple[FloatArray, int]:
    """Invert the 6×6 information over ``(dφ, dt)``, flooring its weak directions.

    Translation is measured in radians at ``depth_m`` (``dt / depth_m``) so that both blocks
    have one unit; eigen-directions with a standard deviation above ``weak_std_rad`` get the
    variance ``weak_variance`` (in those units). Returns the covariance and the number of weak
    directions.
    """
    D = np.diag([1.0, 1.0, 1.0, depth_m, depth_m, depth_m])
    info_s = D @ info @ D  # information over (dφ, dt / depth)
    info_s = 0.5 * (info_s + info_s.T)
    w, V = np.linalg.eigh(info_s)
    weak = w < 1.0 / weak_std_rad**2
    var = np.where(weak, weak_variance, 1.0 / np.maximum(w, 1e-300))
    cov_s = (V * var) @ V.T
    cov = D @ cov_s @ D
    return 0.5 * (cov + cov.T), int(weak.sum())


def motion_floor(t: FloatArray, depth_m: float, std: float) -> FloatArray:
    """Covariance floor (6×6 over ``(dφ, dt)``) of the errors that grow with the motion, added
    to the VO noise ``R_vo`` of (3.21).

    Standard deviation ``std · |t|`` per translation axis and ``std · |t| / depth_m`` per
    rotation axis (the rotation that moves the image as much as that translation at the
    corners' median depth). Motion blur (the tracked displacement between two blurred images
    is off by a fraction of the blur, alike for all corners of a pair and for consecutive
    pairs), rolling shutter, a frame-time error and a depth-scale error act so: per pair they
    are small, but they do not average out over the corners of a pair nor over consecutive
    pairs, and a filter fed them as white noise of their per-pair size drifts beyond its
    covariance.
    """
    s2 = (std * float(np.linalg.norm(t))) ** 2
    return np.diag([s2 / depth_m**2] * 3 + [s2] * 3)


class FrameOdometry:
    """Relative motion of consecutive RGB-D frames seeded by the IMU prediction.

    Keeps the last current frame's prepared image so that, called on consecutive pairs, each
    frame is converted to grey (and resized) once.
    """

    def __init__(self, params: OdometryParams | None = None) -> None:
        self.params = params or OdometryParams()
        self._cache_key: tuple | None = None
        self._cache: PreparedImage | None = None

    def _prepare(self, frame: Frame) -> PreparedImage:
        key = (frame.index, frame.t_ns, id(frame.rgb), id(frame.depth_m))
        if key == self._cache_key and self._cache is not None:
            return self._cache
        p = self.params
        return prepare_image(frame.rgb, frame.depth_m, p.scale)

    def estimate(
        self, prev: Frame, cur: Frame, K: np.ndarray, T_guess_CkfromCk1: np.ndarray
    ) -> VoResult:
        """Measure ``T_CkfromCk1`` between ``prev`` and ``cur`` (the VO measurement of (3.21)).

        ``K``: 3×3 camera matrix of the (depth-aligned) colour image; ``T_guess_CkfromCk1``:
        4×4 predicted motion (from the IMU propagation, or the identity). ``InputError`` on
        malformed inputs (frames of different sizes, bad shapes); measurement failures are
        ``ok = False`` with a reason.
        """
        p = self.params
        K, T_g = _check_inputs(prev, cur, K, T_guess_CkfromCk1)
        R_g, t_g = T_g[:3, :3], T_g[:3, 3]
        times: dict[str, float] = {}
        t0 = time.perf_counter()

        def fail(reason: str, **counts: int) -> VoResult:
            log.debug("VO %d→%d skipped: %s", prev.index, cur.index, reason)
            return VoResult(
                False,
                R_g.copy(),
                t_g.copy(),
                np.full((6, 6), np.inf),
                math.nan,
                reason,
                timings_ms=times,
                **counts,
            )

        img_prev = self._prepare(prev)
        img_cur = self._prepare(cur)
        self._cache_key = (cur.index, cur.t_ns, id(cur.rgb), id(cur.depth_m))
        self._cache = img_cur
        t1 = time.perf_counter()
        times["prepare"] = 1e3 * (t1 - t0)

        Kw = _scaled_K(K, p.scale)
        valid = (prev.depth_m >= p.min_depth_m) & (prev.depth_m <= p.max_depth_m)
        if not valid.any():
            return fail("no valid depth in the previous frame")
        uv_prev, p_prev = detect_corners(
            img_prev,
            Kw,
            max_corners=p.max_corners,
            quality=p.corner_quality,
            min_distance_px=p.corner_min_distance_px,
            min_depth_m=p.min_depth_m,
            max_depth_m=p.max_depth_m,
            border_px=p.corner_border_px,
        )
        t2 = time.perf_counter()
        times["detect"] = 1e3 * (t2 - t1)
        n_corners = len(uv_prev)
        if n_corners < p.min_inliers:
            return fail(
                f"too few corners with depth ({n_corners} < {p.min_inliers})", n_corners=n_corners
            )

        # Texture above the image noise (per corner, over the Lucas–Kanade window).
        sigma_w2 = (p.image_noise_grey * p.scale) ** 2  # INTER_AREA averages the noise down
        G = structure_tensors(img_prev.gray, uv_prev, p.lk_window_px)
        g_noise = p.lk_window_px**2 * NOISE_GRADIENT_GAIN * sigma_w2
        tr, det = G[:, 0, 0] + G[:, 1, 1], G[:, 0, 0] * G[:, 1, 1] - G[:, 0, 1] ** 2
        lam_min = 0.5 * tr - np.sqrt(np.maximum(0.25 * tr**2 - det, 0.0))
        textured = lam_min >= p.texture_snr * g_noise
        uv_prev, p_prev, G = uv_prev[textured], p_prev[textured], G[textured]
        if len(uv_prev) < p.min_inliers:
            return fail(
                f"too few textured corners ({len(uv_prev)} of {n_corners} < {p.min_inliers})",
                n_corners=n_corners,
            )
        # Lucas–Kanade displacement noise 2σ² G_s⁻¹, G_s = G less the noise's own part.
        G_signal = G - g_noise * np.eye(2)
        cov_lk = 2.0 * sigma_w2 * np.linalg.inv(G_signal)

        uv_guess = predict_pixels(Kw, R_g, t_g, p_prev)
        uv_cur, good = track_corners(
            img_prev,
            img_cur,
            uv_prev,
            uv_guess,
            window_px=p.lk_window_px,
            levels=p.lk_levels,
            min_eig=p.lk_min_eig,
            fb_max_px=p.fb_max_px,
        )
        t3 = time.perf_counter()
        times["track"] = 1e3 * (t3 - t2)
        n_tracked = int(good.sum())
        if n_tracked < p.min_inliers:
            return fail(
                f"too few tracked corners ({n_tracked} of {n_corners} < {p.min_inliers})",
                n_corners=n_corners,
                n_tracked=n_tracked,
            )

        fit = fit_pose(
            Kw,
            p_prev[good],
            uv_cur[good],
            cov_lk[good],
            R_g,
            t_g,
            ransac_px=p.ransac_px,
            ransac_iterations=p.ransac_iterations,
            sigma_min_px=p.sigma_min_px,
            gate_chi2=p.inlier_chi2,
            min_inliers=p.min_inliers,
        )
        t4 = time.perf_counter()
        times["pose"] = 1e3 * (t4 - t3)
        n_inliers = int(fit.inliers.sum())
        counts = dict(n_corners=n_corners, n_tracked=n_tracked, n_inliers=n_inliers)
        if fit.R is None:
            return fail(f"too few inliers for a pose ({n_inliers} of {n_tracked} tracks)", **counts)
        R, t = fit.R, fit.t

        dphi = float(np.linalg.norm(so3_log(R @ R_g.T)))
        dt = float(np.linalg.norm(t - t_g))
        if dphi > p.max_guess_rotation_rad or dt > p.max_guess_translation_m:
            return fail(
                f"implausible: {math.degrees(dphi):.2f}° / {1e3 * dt:.1f} mm "
                "from the IMU prediction",
                **counts,
            )

        # (3.21) noise: per corner, the pixel variance scaled by the alignment residual
        # (floored) plus the Lucas–Kanade noise of its texture (fit.weights).
        p_in = p_prev[good][fit.inliers]
        info = pose_information(Kw, R, t, p_in, fit.weights, p.common_px * p.scale)
        depth = float(np.median(p_in[:, 2]))
        cov6, n_weak = covariance_from_information(info, depth, p.weak_std_rad, p.weak_variance)
        cov6 = p.cov_scale * cov6 + motion_floor(t, depth, p.motion_std)
        times["total"] = 1e3 * (time.perf_counter() - t0)
        residual = math.sqrt(float((fit.residuals**2).sum()) / max(n_inliers, 1)) / p.scale
        if n_weak == 6:
            return fail("no direction of the motion is constrained", **counts)
        reason = f"{n_weak} weakly constrained direction(s) inflated" if n_weak else ""
        return VoResult(
            True, R, t, cov6, residual, reason, weak_dirs=n_weak, timings_ms=times, **counts
        )
