"""Visual-odometry measurement: the relative camera motion between the clone (previous frame)
and the current IMU pose (thesis (3.11)–(3.21), corrected per thesis-notes).

The odometry reports ``(R_vo, t_vo)`` with ``p_Ck = R_vo p_Ck−1 + t_vo`` (a point's coordinates in
camera frame k from those in frame k−1; thesis ``C(q_vo)``, ``t_vo`` of (3.11), (3.12)). With
``R_j``, ``p_j`` the clone (IMU pose at frame k−1), ``R_k``, ``p_k`` the current IMU pose
(``R = R_WfromI``), ``(R_CI, t_CI) = T_CfromI`` and ``p_CinI = −R_CIᵀ t_CI`` the camera centre in
the IMU frame (thesis ``[t_C]_B``)::

    R_vo = R_CI R_kᵀ R_j R_CIᵀ                                            (3.11)
    t_vo = R_CI R_kᵀ ((p_j + R_j p_CinI) − (p_k + R_k p_CinI))             (3.12)

Residual (6): ``[log(R_meas R_voᵀ), t_meas − t_vo]``: the rotation part is the rotation vector
of the left error (instead of the thesis's quaternion vector part ``z_vo,q`` of (3.15), which is
half of it to first order); the translation part is (3.18). With the body-frame attitude errors
``dθ = 2 q̄_e`` (``R ≈ R̂ (I + [dθ×])``) the Jacobians (thesis (3.17), (3.19) with the fixes of
thesis-notes: pure-quaternion perturbations, ``C(q̂_k)``; ours = thesis/2 per attitude column)::

    rotation:    ∂/∂dθ_k = −R_CI,   ∂/∂dθ_j = R_CI R_kᵀ R_j
    translation: ∂/∂dθ_k = R_CI [(R_kᵀ d + p_CinI)×],   ∂/∂δp_k = −R_CI R_kᵀ,
                 ∂/∂dθ_j = −R_CI R_kᵀ R_j [p_CinI×],    ∂/∂δp_j = R_CI R_kᵀ

with ``d = (p_j + R_j p_CinI) − (p_k + R_k p_CinI)``. Noise: ``R_cov6`` (rotation then
translation; thesis ``R_vo = J_vo diag(r_vo,q I3, r_vo,t I3)`` of (3.21) is one choice the
caller makes).
"""

from __future__ import annotations

import numpy as np

from gaitnet.geometry import rotmat_from_quat, skew, so3_log
from gaitnet.vio.measurement import Measurement
from gaitnet.vio.state import FilterState


def vo_predict(
    q_k: np.ndarray,
    p_k: np.ndarray,
    q_j: np.ndarray,
    p_j: np.ndarray,
    T_CfromI: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """``(R_vo, t_vo)`` (3.11), (3.12) from the current IMU pose ``(q_k, p_k)`` and the previous
    one ``(q_j, p_j)`` (thesis attitudes, ``R(q) = R_WfromI``)."""
    R_CI, t_CI = T_CfromI[:3, :3], T_CfromI[:3, 3]
    p_CinI = -R_CI.T @ t_CI
    R_k, R_j = rotmat_from_quat(q_k), rotmat_from_quat(q_j)
    d = (p_j + R_j @ p_CinI) - (p_k + R_k @ p_CinI)
    return R_CI @ R_k.T @ R_j @ R_CI.T, R_CI @ R_k.T @ d


def vo_measurement(
    state: FilterState,
    T_CfromI: np.ndarray,
    R_meas: np.ndarray,
    t_meas: np.ndarray,
    R_cov6: np.ndarray,
) -> Measurement:
    """The VO update (3.21) for the relative motion ``(R_meas, t_meas)`` measured between the
    clone's frame and the current frame (module docstring); blocks on ``att``, ``pos``,
    ``clone_att``, ``clone_pos``. The state must hold a clone."""
    if state.clone is None:
        raise ValueError("the VO measurement needs the previous pose: clone the state first")
    imu, cl = state.imu, state.clone
    R_CI, t_CI = T_CfromI[:3, :3], T_CfromI[:3, 3]
    p_CinI = -R_CI.T @ t_CI
    R_k, R_j = rotmat_from_quat(imu.q), rotmat_from_quat(cl.q)
    d = (cl.p_IinW + R_j @ p_CinI) - (imu.p_IinW + R_k @ p_CinI)
    R_pred = R_CI @ R_k.T @ R_j @ R_CI.T
    t_pred = R_CI @ R_k.T @ d
    residual = np.concatenate([so3_log(R_meas @ R_pred.T), t_meas - t_pred])
    A = R_CI @ R_k.T  # R_CfromW at frame k
    zero = np.zeros((3, 3))
    H = {
        "att": np.vstack([-R_CI, R_CI @ skew(R_k.T @ d + p_CinI)]),
        "pos": np.vstack([zero, -A]),
        "clone_att": np.vstack([A @ R_j, -A @ R_j @ skew(p_CinI)]),
        "clone_pos": np.vstack([zero, A]),
    }
    return Measurement(residual, H, np.asarray(R_cov6, dtype=np.float64), "vo")
