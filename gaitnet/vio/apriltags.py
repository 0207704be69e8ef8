"""AprilTag board detection and camera pose with its covariance (thesis (3.27)–(3.34)).

:func:`detect_board_pose` finds tag36h11 markers in one colour frame with one of two corner
detectors (``AprilTagParams.detector``): the AprilTag 3 library (package ``pupil-apriltags``,
the default) or OpenCV's ``cv.aruco``, in :mod:`gaitnet.vio.tag_detectors`. Both return the
corners in the same convention (aruco order, pixel centres at integers); the rest is shared:
the ids are matched to the session's boards (:attr:`SessionCalibration.apriltag_boards`,
corner convention :func:`gaitnet.io.types.tag_corners_in_board`) and the camera pose
``T_WfromC`` is estimated from all corners of all tags of the best-seen board:
``cv.solvePnP`` (IPPE, the planar solver) followed by a Levenberg–Marquardt refinement of the
reprojection error.

Covariance (3.30), corrected as in D.-C. Dang's thesis notes: with corner pixels
``r_img,j = f_img(p_j,C) + η``, ``η ~ N(0, ε1 I2)`` (3.27), the pose error covariance is
``ε1 (Σ_j H̄_jᵀ H̄_j)^{-1}`` where ``H̄_j = ∂r_img,j / ∂(δθ, δp)``. Here the error is that of
the *camera* pose, in the filter's convention (docs: module ``state``):
``R_WfromC = R̂_WfromC exp([δθ×])`` (rotation vector in the camera frame; the thesis's
``q̄_e`` is ``δθ / 2``) and ``p_CinW = p̂_CinW + δp``. Then
``p_C = R̂ᵀ (P_W − p̂) + [p̂_C×] δθ − R̂ᵀ δp`` to first order, so
``H̄_j = ∂π/∂p_C · [[p̂_C×], −R̂ᵀ]`` (the thesis (3.32) with the position block's sign fixed:
``−C'(q_C^B) C(q̂)``). The Jacobian is in pixels, so ``ε1`` is a pixel variance.
:func:`imu_pose_from_camera` moves pose and covariance to the IMU frame for the filter
(:mod:`gaitnet.vio.tag_model`).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Literal

import cv2 as cv
import numpy as np

from gaitnet.geometry.camera import project, projection_jacobian
from gaitnet.geometry.rotation import skew
from gaitnet.io.types import AprilTagBoard, Frame, SessionCalibration, tag_corners_in_board
from gaitnet.vio.tag_detectors import detect_tags

log = logging.getLogger(__name__)

__all__ = [
    "AprilTagParams",
    "TagObservation",
    "camera_pose_jacobian",
    "detect_board_pose",
    "imu_pose_from_camera",
    "pose_covariance",
]

_DETECTOR_NAMES = ("apriltag3", "aruco")


@dataclass(frozen=True)
class AprilTagParams:
    """Settings of the tag detector and the pose check.

    Defaults tuned on standing frames of simulated sessions det_s200–s205 (640×480, tags of
    4 cm seen from about 1.1 m: ~14 px per tag, under 2 px per code bit);
    ``benchmarks/bench_detectors.py`` prints the comparison.
    """

    detector: Literal["apriltag3", "aruco"] = "apriltag3"
    """Corner detector: ``apriltag3`` (AprilTag 3, package pupil-apriltags, at full resolution;
    ``APRILTAG3_SETTINGS`` in ``gaitnet/vio/tag_detectors.py``) or ``aruco`` (OpenCV's cv.aruco with
    the keys marked (aruco); set ``corner_sigma_px`` to 0.25 with it). On det_s200–s202 standing
    frames AprilTag 3 decodes 35.0 of a sheet's 35 tags per frame (aruco: 33.7), median camera
    position error 2.6 mm (3.3 mm), and takes 4 ms CPU per frame searching where the filter
    predicts the board (11 ms), 34 ms on a whole frame without a prediction (32 ms)."""
    upsample: int = 3
    """(aruco) Detect on the image enlarged by this integer factor (bicubic). At 640×480 the
    tags are ~14 px wide: OpenCV's defaults at ×1 decode ~13 of a sheet's 35, ×2 ~31, ×3 ~34;
    with contour refinement the median position error falls from 12 mm (×1) and 4.8 mm (×2) to
    3.3 mm (×3; ×4 is no better and slower). Tuned on det_s200–s202 standing frames."""
    adaptive_thresh_win_min: int = 3
    """(aruco) ``adaptiveThreshWinSizeMin`` (OpenCV default 3)."""
    adaptive_thresh_win_max: int = 23
    """(aruco) ``adaptiveThreshWinSizeMax`` (OpenCV default 23)."""
    adaptive_thresh_win_step: int = 10
    """(aruco) ``adaptiveThreshWinSizeStep`` (OpenCV default 10)."""
    min_marker_perimeter_rate: float = 0.03
    """(aruco) ``minMarkerPerimeterRate``: smallest marker perimeter / largest image side
    (OpenCV default 0.03; in the ×2 image a 14 px tag has 112 / 1280 = 0.09)."""
    corner_refinement: str = "contour"
    """(aruco) ``none``, ``subpix``, ``contour`` or ``apriltag`` (benchmark: ``contour`` gives
    the smallest pose error, ``subpix`` ~1.4× larger; ``apriltag`` loses most tags at this
    size)."""
    error_correction_rate: float = 0.8
    """(aruco) ``errorCorrectionRate`` (OpenCV default 0.6): accepting more bit errors decodes
    ~2 more tags per sheet; a wrong id is caught by the board-id and reprojection checks."""
    roi_margin_px: float = 40.0
    """With a pose guess, detect only in the boards' projected bounding box grown by this
    margin [px] (covers a guess off by ~4 cm at 1 m)."""
    max_tag_error_px: float = 3.0
    """A tag with a corner this far [px] from the first fit's reprojection is dropped and the
    pose refitted (a mis-decoded id or a corner on a shadow edge)."""
    min_tags: int = 2
    """Fewest decoded tags of one board for a pose (8 coplanar corners; 1 tag = 4 corners is
    ambiguous under IPPE's two solutions)."""
    max_reprojection_rms_px: float = 1.5
    """Reject a pose whose corner reprojection RMS is above this [px] (a wrong id or a blurred
    frame; standing frames in simulation give ~0.1–0.3 px)."""
    corner_sigma_px: float = 0.45
    """Smallest corner noise standard deviation [px] used for ``ε1`` (3.27). ``ε1`` is the
    larger of this squared and the fit's unbiased residual variance. On det_s200–s202 standing
    frames the mean normalised pose error (NEES, 6 dof; 6 when the covariance is honest) with
    ``apriltag3`` is 15 at 0.25 px, 7.7 at 0.35 px, 4.7 at 0.45 px, 3.8 at 0.5 px: 0.45 px is
    a little conservative, for the errors that are not white (blur, rendering, the sheet's
    print).
    ``aruco``'s corners want 0.25 px (NEES ~4; 0.5 px gives 1.0)."""

    def __post_init__(self) -> None:
        if self.detector not in _DETECTOR_NAMES:
            raise ValueError(
                f"detector must be one of {', '.join(_DETECTOR_NAMES)}, got {self.detector!r}"
            )


@dataclass(frozen=True)
class TagObservation:
    """A board seen in one frame: camera pose ``T_WfromC`` and its covariance.

    ``cov6`` is 6×6, rotation (camera-frame rotation vector δθ, rad) then position (δp of the
    camera centre in the world, m): ``R_WfromC = R̂ exp([δθ×])``, ``p = p̂ + δp`` (3.30).
    ``tag_ids`` (n,), ``corners_px`` (n, 4, 2) the detected corners and ``corners_W`` (n, 4, 3)
    their world points (for a re-linearised update), ``rms_px`` the reprojection RMS,
    ``eps1_px2`` the corner variance used.
    """

    board: str
    T_WfromC: np.ndarray
    cov6: np.ndarray
    n_tags: int
    rms_px: float
    eps1_px2: float
    tag_ids: np.ndarray = field(repr=False)
    corners_px: np.ndarray = field(repr=False)
    corners_W: np.ndarray = field(repr=False)


def camera_pose_jacobian(K: np.ndarray, T_WfromC: np.ndarray, P_W: np.ndarray) -> np.ndarray:
    """``H̄`` (n, 2, 6): pixel Jacobians of world points ``P_W`` (n, 3) w.r.t. the camera pose
    error ``[δθ, δp]`` (module docstring; thesis (3.30)–(3.32) with the corrected sign)."""
    R = T_WfromC[:3, :3]
    p_C = (np.asarray(P_W, dtype=np.float64) - T_WfromC[:3, 3]) @ R
    J_point = np.concatenate(
        [skew(p_C), np.broadcast_to(-R.T, (len(p_C), 3, 3))], axis=-1
    )  # (n, 3, 6): ∂p_C/∂[δθ, δp]
    return projection_jacobian(K, p_C) @ J_point


def pose_covariance(
    K: np.ndarray, T_WfromC: np.ndarray, P_W: np.ndarray, eps1: float
) -> np.ndarray:
    """``R_tag = ε1 (Σ_j H̄_jᵀ H̄_j)^{-1}`` (3.30) of the camera pose error ``[δθ, δp]`` (6×6)
    from the world points ``P_W`` (n, 3) seen with pixel noise variance ``eps1`` [px²]."""
    H = camera_pose_jacobian(K, T_WfromC, P_W)
    info = np.einsum("nij,nik->jk", H, H)
    cov = eps1 * np.linalg.inv(info)
    return 0.5 * (cov + cov.T)


def imu_pose_from_camera(
    T_WfromC: np.ndarray, cov6_C: np.ndarray, T_CfromI: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """IMU pose ``T_WfromI`` and its covariance from a camera pose and its covariance.

    Errors: camera ``R_WfromC = R̂ exp([δθ_C×])``, ``p_CinW = p̂ + δp_C``; IMU (the filter's)
    ``R_WfromI = R̂ exp([δθ_I×])``, ``p_IinW = p̂ + δp_I``. With ``R_WfromI = R_WfromC R_CfromI``
    and ``p_IinW = p_CinW + R_WfromC p_IinC``: ``δθ_I = R_IfromC δθ_C``,
    ``δp_I = δp_C − R̂_WfromC [p_IinC×] δθ_C``.
    """
    T_WfromI = T_WfromC @ T_CfromI
    R_CfromI = T_CfromI[:3, :3]
    p_IinC = T_CfromI[:3, 3]
    J = np.zeros((6, 6))
    J[:3, :3] = R_CfromI.T
    J[3:, :3] = -T_WfromC[:3, :3] @ skew(p_IinC)
    J[3:, 3:] = np.eye(3)
    return T_WfromI, J @ cov6_C @ J.T


def _board_roi(
    board: AprilTagBoard, K: np.ndarray, T_WfromC: np.ndarray, shape: tuple[int, int], margin: float
) -> tuple[int, int, int, int] | None:
    s, g = board.tag_size_m, board.gap_m
    w = board.cols * s + (board.cols - 1) * g
    h = board.rows * s + (board.rows - 1) * g
    P_B = np.array([[0, 0, 0], [w, 0, 0], [w, h, 0], [0, h, 0]], dtype=np.float64)
    P_W = P_B @ board.T_WfromBoard[:3, :3].T + board.T_WfromBoard[:3, 3]
    T_CfromW = np.linalg.inv(T_WfromC)
    p_C = P_W @ T_CfromW[:3, :3].T + T_CfromW[:3, 3]
    uv, valid = project(K, p_C, min_depth=0.05)
    if not valid.all():
        return None
    H, W = shape
    x0, y0 = np.floor(uv.min(axis=0) - margin).astype(int)
    x1, y1 = np.ceil(uv.max(axis=0) + margin).astype(int) + 1
    x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, W), min(y1, H)
    if x1 - x0 < 8 or y1 - y0 < 8:
        return None
    return int(x0), int(y0), int(x1), int(y1)


def _solve_pose(
    P_B: np.ndarray, corners_px: np.ndarray, K: np.ndarray, dist: np.ndarray
) -> tuple[np.ndarray, np.ndarray] | None:
    """IPPE + LM refinement: ``(T_CfromB, residuals (2n,) projected − detected)`` or None."""
    obj = P_B.reshape(-1, 3)
    img = corners_px.reshape(-1, 2)
    ok, rvec, tvec = cv.solvePnP(obj, img, K, dist, flags=cv.SOLVEPNP_IPPE)
    if not ok:
        return None
    rvec, tvec = cv.solvePnPRefineLM(obj, img, K, dist, rvec, tvec)
    T_CfromB = np.eye(4)
    T_CfromB[:3, :3] = cv.Rodrigues(rvec)[0]
    T_CfromB[:3, 3] = tvec.reshape(3)
    proj = cv.projectPoints(obj, rvec, tvec, K, dist)[0].reshape(-1, 2)
    return T_CfromB, (proj - img).reshape(-1)


def detect_board_pose(
    frame: Frame,
    calib: SessionCalibration,
    params: AprilTagParams | None = None,
    T_WfromC_guess: np.ndarray | None = None,
) -> TagObservation | None:
    """Camera pose from the AprilTag board best seen in ``frame`` (3.27)–(3.30), or None.

    Tags whose ids are on no board of ``calib`` are ignored; of several boards the one with
    the most decoded tags is used. With ``T_WfromC_guess`` (e.g. the filter's prediction) only
    the boards' projected areas are searched, and nothing is searched when no board can be in
    view. None (logged at debug level) when fewer than ``params.min_tags`` tags of one board are
    decoded or the reprojection RMS exceeds ``params.max_reprojection_rms_px``.
    """
    params = params or AprilTagParams()
    boards = calib.apriltag_boards
    if not boards:
        return None
    K = calib.color.K
    gray = frame.rgb if frame.rgb.ndim == 2 else cv.cvtColor(frame.rgb, cv.COLOR_RGB2GRAY)
    found: dict[int, np.ndarray] = {}
    for family in sorted({b.family for b in boards}):
        fam_boards = [b for b in boards if b.family == family]
        rois: list[tuple[int, int, int, int] | None] = [None]
        if T_WfromC_guess is not None:
            rois = [
                r
                for b in fam_boards
                if (r := _board_roi(b, K, T_WfromC_guess, gray.shape, params.roi_margin_px))
            ]
        for roi in rois:
            ids, corners = detect_tags(gray, params, family, roi)
            for i, c in zip(ids, corners, strict=True):
                found[(family, int(i))] = c
    best: tuple[AprilTagBoard, list[int]] | None = None
    for b in boards:
        ids = sorted(i for (fam, i) in found if fam == b.family and i in b.tag_ids)
        if ids and (best is None or len(ids) > len(best[1])):
            best = (b, ids)
    if best is None or len(best[1]) < params.min_tags:
        log.debug(
            "frame %d: %d tags of one board (need %d)",
            frame.index,
            0 if best is None else len(best[1]),
            params.min_tags,
        )
        return None
    board, ids = best
    corners_px = np.stack([found[(board.family, i)] for i in ids])
    P_B = np.stack([tag_corners_in_board(board, i) for i in ids])
    dist = np.asarray(calib.color.distortion, dtype=np.float64)
    sol = _solve_pose(P_B, corners_px, K, dist)
    if sol is not None:
        worst = np.abs(sol[1]).reshape(len(ids), 8).max(axis=1)
        keep = worst <= params.max_tag_error_px
        if not keep.all() and keep.sum() >= params.min_tags:
            log.debug("frame %d: dropped tags %s", frame.index, np.asarray(ids)[~keep].tolist())
            ids = [i for i, k in zip(ids, keep, strict=True) if k]
            corners_px, P_B = corners_px[keep], P_B[keep]
            sol = _solve_pose(P_B, corners_px, K, dist)
    if sol is None:
        log.debug("frame %d: solvePnP failed", frame.index)
        return None
    T_CfromB, res = sol
    n = len(res) // 2
    res = res.reshape(-1, 2)
    rms = float(np.sqrt(np.mean(np.sum(res**2, axis=1))))
    if not np.isfinite(rms) or rms > params.max_reprojection_rms_px:
        log.debug("frame %d: tag reprojection rms %.2f px rejected", frame.index, rms)
        return None
    T_WfromC = board.T_WfromBoard @ np.linalg.inv(T_CfromB)
    corners_W = P_B @ board.T_WfromBoard[:3, :3].T + board.T_WfromBoard[:3, 3]
    # ε1 (3.27): unbiased residual variance per pixel coordinate (2n values, 6 parameters),
    # floored by the configured corner noise.
    eps1 = max(params.corner_sigma_px**2, float(np.sum(res**2)) / max(2 * n - 6, 1))
    cov6 = pose_covariance(K, T_WfromC, corners_W.reshape(-1, 3), eps1)
    return TagObservation(
        board=board.name,
        T_WfromC=T_WfromC,
        cov6=cov6,
        n_tags=len(ids),
        rms_px=rms,
        eps1_px2=eps1,
        tag_ids=np.asarray(ids, dtype=np.int64),
        corners_px=corners_px,
        corners_W=corners_W,
    )
