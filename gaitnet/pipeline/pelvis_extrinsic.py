"""The camera-to-pelvis extrinsic ``T_PfromC`` from the standing frames at the start of a walk.

The filter tracks the camera; the pose correction needs the pelvis (SMPL joint 0; x forward,
y left, z up), so ``T_WfromP = T_WfromC T_PfromC⁻¹``. While the subject stands still at the
start, the pelvis pose is taken from a standing pose of the skeleton placed in the world:

1. the standing pose (default: the rest pose, upright with straight legs; or the poses the
   caller gives) with its feet points (ankle plus the marker offset, as in the correction)
   is rotated about the vertical by the yaw ``ψ`` and shifted by ``t`` so that its two foot
   points best match the measured ones (least squares: ``t`` is the difference of the means
   once ``ψ`` is fixed);
2. ``ψ`` comes from the camera (``yaw_from="camera"``, the default: the optical axis projected
   on the floor is the pelvis's forward direction, i.e. the mount has no yaw of its own) or from
   the feet (``yaw_from="feet"``: the body's left axis is the right-to-left foot direction,
   which toe-out and a staggered stance tilt);
3. per standing frame ``T_PfromC,i = T_WfromP⁻¹ T_WfromC,i``; the result is their mean (the
   chordal mean of the rotations, by SVD, and the mean translation), with the spread reported.

The height comes from the feet, so a pelvis that sags or a knee that bends while standing
shows up as a vertical offset of the extrinsic (sub-centimetre for a relaxed stance).

The standing frames are those before the camera moves (:func:`standing_frames`); the
standing feet the points measured over them, else the filter's landmark seen while standing
(:func:`standing_feet`). A foot that was not seen while standing (a camera pitched up too far
to see the feet, a foot outside the image) is placed by :func:`complete_standing_feet`: beside
the other foot at the skeleton's stance width, or, when neither was seen, both a nominal
distance behind the camera along its horizontal viewing direction; the extrinsic is then only
as good as that guess.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gaitnet.errors import InputError
from gaitnet.geometry import invert_T, so3_exp, so3_log
from gaitnet.motion.skeleton import LowerBodySkeleton
from gaitnet.pipeline.pose_residuals import ChainGeometry, ChainState, chain_points
from gaitnet.pipeline.pose_types import PoseCorrectionParams, R_PfromSMPL
from gaitnet.vio.gait import SIDES
from gaitnet.vio.result import VioResult

FloatArray = NDArray[np.float64]

__all__ = [
    "PelvisExtrinsic",
    "complete_standing_feet",
    "estimate_T_PfromC",
    "pelvis_from_camera",
    "standing_T_WfromP",
    "standing_feet",
    "standing_frames",
    "standing_model_feet",
]


@dataclass(frozen=True, eq=False)
class PelvisExtrinsic:
    """``T_PfromC`` (4, 4), the pelvis pose it was solved against ``T_WfromP`` (4, 4), and the
    RMS spread of the per-frame estimates (``spread_rot_rad``, ``spread_pos_m``)."""

    T_PfromC: FloatArray
    T_WfromP: FloatArray
    spread_rot_rad: float
    spread_pos_m: float
    n_frames: int


def _yaw_rotation(psi: float) -> FloatArray:
    return so3_exp(np.array([0.0, 0.0, psi]))


def _yaw_of(v: FloatArray) -> float:
    return float(np.arctan2(v[1], v[0]))


def standing_model_feet(
    skeleton: LowerBodySkeleton,
    joint_aa: ArrayLike | None = None,
    params: PoseCorrectionParams | None = None,
) -> tuple[FloatArray, FloatArray]:
    """The foot points (2, 3) (left, right: ankle plus the marker offset, as in the correction)
    of the standing pose ``joint_aa`` (6, 3) (default zeros: straight legs) with the pelvis at
    the origin, facing +x (``R_WfromP = I``), and the pelvis joint's position ``J0`` (3,) in
    that frame."""
    aa = np.zeros((6, 3)) if joint_aa is None else np.asarray(joint_aa, dtype=np.float64)
    if aa.shape != (6, 3) or not np.all(np.isfinite(aa)):
        raise InputError("standing joint_aa: expected finite (6, 3) local rotations")
    geo = ChainGeometry.build(skeleton, params or PoseCorrectionParams())
    model = ChainState(
        R0=R_PfromSMPL[None].copy(), t=np.zeros((1, 3)), a=aa[None], l=geo.lengths[None].copy()
    )
    return chain_points(geo, model)["foot"][0], np.asarray(geo.J0, dtype=np.float64)


def _camera_yaw(T_WfromC: ArrayLike) -> float:
    z_C = np.asarray(T_WfromC, dtype=np.float64)[:3, 2]
    if np.hypot(z_C[0], z_C[1]) < 1e-3:
        raise InputError("standing pelvis: the camera looks straight down; use yaw_from='feet'")
    return _yaw_of(z_C)


def standing_T_WfromP(
    skeleton: LowerBodySkeleton,
    foot_W: ArrayLike,
    T_WfromC: ArrayLike | None = None,
    *,
    joint_aa: ArrayLike | None = None,
    params: PoseCorrectionParams | None = None,
    yaw_from: Literal["camera", "feet"] = "camera",
) -> FloatArray:
    """The pelvis pose (4, 4) of the standing skeleton fitted to the measured feet (see module).

    ``foot_W`` (2, 3): the measured foot points (left, right), e.g. averaged over the standing
    frames; ``T_WfromC`` (4, 4) a camera pose (needed for ``yaw_from="camera"``);
    ``joint_aa`` (6, 3) the standing pose's local rotations (default zeros); ``params`` gives
    the marker offset (the correction's default parameters when None).
    """
    foot = np.asarray(foot_W, dtype=np.float64)
    if foot.shape != (2, 3) or not np.all(np.isfinite(foot)):
        raise InputError(
            "standing foot_W: expected finite (2, 3) points of the left and right foot"
        )
    f_model, J0 = standing_model_feet(skeleton, joint_aa, params)
    if yaw_from == "feet":
        psi = _yaw_of(foot[0] - foot[1]) - _yaw_of(f_model[0] - f_model[1])
    elif yaw_from == "camera":
        if T_WfromC is None:
            raise InputError("standing pelvis: yaw_from='camera' needs a camera pose")
        psi = _camera_yaw(T_WfromC)
    else:
        raise InputError(f"standing pelvis: yaw_from must be 'camera' or 'feet', got {yaw_from!r}")
    Rz = _yaw_rotation(psi)
    t = foot.mean(axis=0) - Rz @ f_model.mean(axis=0)
    T = np.eye(4)
    T[:3, :3] = Rz
    T[:3, 3] = Rz @ J0 + t
    return T


def complete_standing_feet(
    foot_W: ArrayLike,
    skeleton: LowerBodySkeleton,
    T_WfromC: ArrayLike,
    marker_height_m: float,
    behind_camera_m: float,
    params: PoseCorrectionParams | None = None,
) -> tuple[FloatArray, str | None]:
    """Standing foot points (2, 3) with the feet that were not seen (NaN rows of ``foot_W``,
    left then right) placed, and a sentence saying what was placed (None: nothing).

    One foot missing: beside the other, offset by the standing skeleton's right-to-left (or
    left-to-right) foot vector turned to the camera's heading, at the seen foot's height. Both
    missing: their midpoint ``behind_camera_m`` behind the camera (the standing ``T_WfromC``,
    along its optical axis projected on the floor), at ``marker_height_m``, spread by the
    skeleton's stance width across that heading.
    """
    foot = np.array(foot_W, dtype=np.float64)
    if foot.shape != (2, 3):
        raise InputError("standing foot_W: expected (2, 3) points of the left and right foot")
    missing = [i for i in range(2) if not np.all(np.isfinite(foot[i]))]
    if not missing:
        return foot, None
    f_model, _ = standing_model_feet(skeleton, params=params)
    T = np.asarray(T_WfromC, dtype=np.float64)
    Rz = _yaw_rotation(_camera_yaw(T))
    if len(missing) == 1:
        lost = missing[0]
        seen = 1 - lost
        foot[lost] = foot[seen] + Rz @ (f_model[lost] - f_model[seen]) * [1.0, 1.0, 0.0]
        return foot, (
            f"the {SIDES[lost]} foot was not seen while standing: placed beside the "
            f"{SIDES[seen]} foot at the skeleton's stance width"
        )
    forward = Rz[:, 0]
    middle = T[:3, 3] - behind_camera_m * forward
    for i in range(2):
        foot[i] = middle + Rz @ (f_model[i] - f_model.mean(axis=0))
        foot[i, 2] = marker_height_m
    return foot, (
        f"neither foot was seen while standing: the standing feet are placed "
        f"{behind_camera_m:.2f} m behind the camera (pipeline.standing_feet_behind_camera_m); "
        f"the pelvis position is only as good as that guess"
    )


def estimate_T_PfromC(T_WfromC: ArrayLike, T_WfromP: ArrayLike) -> PelvisExtrinsic:
    """Mean rigid offset ``T_PfromC`` of camera poses (n, 4, 4) from a still pelvis (4, 4)."""
    T_C = np.asarray(T_WfromC, dtype=np.float64)
    T_P = np.asarray(T_WfromP, dtype=np.float64)
    if T_C.ndim != 3 or T_C.shape[1:] != (4, 4) or len(T_C) == 0 or T_P.shape != (4, 4):
        raise InputError(
            "extrinsic: expected camera poses (n, 4, 4) with n > 0 and a (4, 4) pelvis"
        )
    if not (np.all(np.isfinite(T_C)) and np.all(np.isfinite(T_P))):
        raise InputError("extrinsic: poses must be finite")
    R_P, p_P = T_P[:3, :3], T_P[:3, 3]
    R_each = R_P.T @ T_C[:, :3, :3]  # (n, 3, 3) R_PfromC per frame
    p_each = (T_C[:, :3, 3] - p_P) @ R_P  # R_Pᵀ (p_C − p_P)
    U, _, Vt = np.linalg.svd(R_each.sum(axis=0))
    R = U @ np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))]) @ Vt
    p = p_each.mean(axis=0)
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, p
    rot_err = so3_log(R.T @ R_each)
    return PelvisExtrinsic(
        T_PfromC=T,
        T_WfromP=T_P.copy(),
        spread_rot_rad=float(np.sqrt(np.mean(np.sum(rot_err**2, axis=1)))),
        spread_pos_m=float(np.sqrt(np.mean(np.sum((p_each - p) ** 2, axis=1)))),
        n_frames=len(T_C),
    )


def pelvis_from_camera(T_WfromC: ArrayLike, T_PfromC: ArrayLike) -> FloatArray:
    """Pelvis poses ``T_WfromP = T_WfromC T_PfromC⁻¹`` (..., 4, 4); both inputs may be batched."""
    return np.asarray(T_WfromC, dtype=np.float64) @ invert_T(T_PfromC)


def standing_frames(
    t_s: np.ndarray, T_WfromC: np.ndarray, standing_s: float, max_speed_mps: float
) -> int:
    """Frames at the start before the camera moves faster than ``max_speed_mps`` (or
    ``standing_s`` ends: ``pipeline.standing_s``, ``pipeline.standing_max_speed_mps``); at
    least 1."""
    if len(t_s) < 2:
        return len(t_s)
    speed = np.linalg.norm(np.diff(T_WfromC[:, :3, 3], axis=0), axis=1) / np.maximum(
        np.diff(t_s), 1e-6
    )
    n = 1
    while n < len(t_s) and t_s[n] - t_s[0] <= standing_s and speed[n - 1] <= max_speed_mps:
        n += 1
    return n


def standing_feet(
    measured: np.ndarray, vio: VioResult, skeleton_marker_height: float, n_standing: int
) -> np.ndarray:
    """(2, 3) standing foot points: the mean of the measured ones over the standing frames,
    else the stance landmark of that side that the filter saw during the standing phase (a
    later one is a step, not the standing foot) at the marker's standing height, else NaN."""
    feet = np.full((2, 3), np.nan)
    t_end = vio.t_s[n_standing - 1]
    for i, side in enumerate(SIDES):
        seen = measured[:n_standing, i]
        seen = seen[~np.isnan(seen[:, 0])]
        if len(seen):
            feet[i] = seen.mean(axis=0)
            continue
        standing = [f for f in vio.stance_feet if f.side == side and f.t_first_s <= t_end]
        if standing:
            xy = min(standing, key=lambda f: f.t_first_s).xy
            feet[i] = [xy[0], xy[1], skeleton_marker_height]
    return feet
