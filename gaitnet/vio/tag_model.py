"""AprilTag board measurement: IMU pose from a camera pose measured on a tag board, its
covariance from the corner projections, and the position update
(thesis (3.27)–(3.34), corrected per thesis-notes).

Tag corner ``X_W`` in the camera frame (3.28), (3.31), with ``R = R_WfromI`` (thesis ``C(q)ᵀ``)
and ``(R_CI, t_CI) = T_CfromI``: ``p_C = R_CI Rᵀ (X_W − p_IinW) + t_CI``. Its Jacobian (3.32)
with respect to ``[dθ, δp]`` of the IMU (``dθ = 2 q̄_e``, ours = thesis/2 per attitude column;
the position block has the corrected sign ``−C'(q_C^B) C(q̂)``)::

    J_tag = [R_CI [(Rᵀ (X_W − p))×],  −R_CI Rᵀ]

The image Jacobian (3.30) (``ẑ_j`` in the denominator, thesis-notes), here in pixels:
``H̄_j = diag(f_x, f_y) (1/ẑ²) [[ẑ, 0, −x̂], [0, ẑ, −ŷ]] J_tag,j`` and
``R_tag = σ_px² (Σ_j H̄_jᵀ H̄_j)⁻¹`` (thesis ``ε1`` is ``σ²`` in normalised image units,
``σ_px² / f²``): the covariance of the IMU pose ``[dθ, δp]`` computed from the board.

Use: the first detection initialises attitude and position (:func:`imu_pose_from_camera_pose`,
with ``R_tag`` as their prior covariance); afterwards only the position is used (3.33), (3.34):
residual ``p̂_tag − p̂``, ``H = [0, I3, 0, …]``, noise ``R_tag(4:6, 4:6)``, plus
``diag(ε2, ε2, 0)`` at the end sheet (its place is known only through the tape-measured L).
"""

from __future__ import annotations

import numpy as np

from gaitnet.geometry import quat_boxminus, quat_from_rotmat, rotmat_from_quat, skew
from gaitnet.vio.measurement import Measurement
from gaitnet.vio.state import FilterState


def imu_pose_from_camera_pose(
    T_WfromC: np.ndarray, T_CfromI: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The IMU's thesis attitude ``q`` and position ``p_IinW`` for the camera pose
    ``T_WfromC`` (``T_WfromI = T_WfromC T_CfromI``)."""
    T_WfromI = np.asarray(T_WfromC, dtype=np.float64) @ np.asarray(T_CfromI, dtype=np.float64)
    return quat_from_rotmat(T_WfromI[:3, :3]), T_WfromI[:3, 3].copy()


def tag_corners_in_camera(
    q: np.ndarray, p_IinW: np.ndarray, T_CfromI: np.ndarray, corners_W: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Corners ``corners_W`` (N, 3) in the camera frame (N, 3) (3.28), (3.31) and their
    Jacobians ``J_tag`` (N, 3, 6) with respect to ``[dθ, δp]`` (3.32, corrected sign)."""
    R_CI, t_CI = T_CfromI[:3, :3], T_CfromI[:3, 3]
    R = rotmat_from_quat(q)
    X_I = (np.asarray(corners_W, dtype=np.float64) - p_IinW) @ R  # rows Rᵀ (X − p)
    p_C = X_I @ R_CI.T + t_CI
    J = np.empty((len(p_C), 3, 6))
    J[:, :, 0:3] = R_CI @ skew(X_I)
    J[:, :, 3:6] = -R_CI @ R.T
    return p_C, J


def tag_pose_covariance(
    q: np.ndarray,
    p_IinW: np.ndarray,
    T_CfromI: np.ndarray,
    corners_W: np.ndarray,
    K: np.ndarray,
    sigma_px: float,
) -> np.ndarray:
    """``R_tag`` (6, 6) of (3.30): the covariance of the IMU pose error ``[dθ, δp]`` estimated
    from the corners ``corners_W`` (N, 3) seen with pixel noise ``sigma_px`` by a camera with
    intrinsics ``K`` (3, 3), linearised at the board pose ``(q, p_IinW)``. Needs at least 3
    corners in front of the camera (a board gives 4 per tag)."""
    p_C, J = tag_corners_in_camera(q, p_IinW, T_CfromI, corners_W)
    if len(p_C) < 3 or np.any(p_C[:, 2] <= 0.0):
        raise ValueError("tag_pose_covariance needs >= 3 corners in front of the camera")
    x, y, z = p_C[:, 0], p_C[:, 1], p_C[:, 2]
    proj = np.zeros((len(p_C), 2, 3))  # ∂(u, v)/∂p_C in pixels
    proj[:, 0, 0] = K[0, 0] / z
    proj[:, 0, 2] = -K[0, 0] * x / (z * z)
    proj[:, 1, 1] = K[1, 1] / z
    proj[:, 1, 2] = -K[1, 1] * y / (z * z)
    Hbar = (proj @ J).reshape(-1, 6)
    cov = sigma_px**2 * np.linalg.inv(Hbar.T @ Hbar)
    return 0.5 * (cov + cov.T)


def tag_measurement(
    state: FilterState,
    T_CfromI: np.ndarray,
    T_WfromC_meas: np.ndarray,
    cov6: np.ndarray,
    *,
    end_sheet_eps2: float = 0.0,
    use_attitude: bool = False,
) -> Measurement:
    """The tag update (3.33), (3.34): IMU position from the board's camera pose
    ``T_WfromC_meas`` against the state's; ``cov6`` is ``R_tag`` of (3.30) (rotation, then
    position; :func:`tag_pose_covariance`); ``end_sheet_eps2`` adds ``diag(ε2, ε2, 0)`` [m²]
    (the end sheet). ``use_attitude=True`` also uses the attitude (residual
    ``q_tag ⊟ q̂``, ``H = I`` on ``att``, the full ``R_tag``): an option the thesis uses only at
    the first detection."""
    q_tag, p_tag = imu_pose_from_camera_pose(T_WfromC_meas, T_CfromI)
    cov6 = np.asarray(cov6, dtype=np.float64)
    R_pos = cov6[3:6, 3:6] + np.diag([end_sheet_eps2, end_sheet_eps2, 0.0])
    r_pos = p_tag - state.imu.p_IinW
    if not use_attitude:
        return Measurement(r_pos, {"pos": np.eye(3)}, R_pos, "tag")
    R = cov6.copy()
    R[3:6, 3:6] = R_pos
    r = np.concatenate([quat_boxminus(q_tag, state.imu.q), r_pos])
    H = {
        "att": np.vstack([np.eye(3), np.zeros((3, 3))]),
        "pos": np.vstack([np.zeros((3, 3)), np.eye(3)]),
    }
    return Measurement(r, H, R, "tag pose")
