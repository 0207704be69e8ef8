"""Stance-foot landmark: initialisation (augmentation) and re-observation updates
(thesis (3.35)–(3.48), corrected per thesis-notes).

A stance foot is a floor point ``L = (x, y, 0)`` in the world (thesis ``r̄_foot``); the
detector measures it in the camera frame, ``p_FinC`` (thesis ``ŷ_foot``), as a point ON the
floor plane (thesis-notes: the ellipse centre projected onto the fitted plane, or the camera
height is biased by the foot's thickness). With ``R = R_WfromI`` (thesis ``C(q)ᵀ``),
``(R_CI, t_CI) = T_CfromI``::

    p_FinC = R_CI R_ᵀ (L − p_IinW) + t_CI                                   (3.35)

Re-observation (3.45)–(3.48): residual ``p_FinC,meas − p_FinC(x̂)``, Jacobians (ours =
thesis/2 per attitude column, ``dθ = 2 q̄_e``)::

    ∂/∂dθ = R_CI [(Rᵀ (L − p))×],   ∂/∂δp = −R_CI Rᵀ,   ∂/∂δL = R_CI Rᵀ E12ᵀ

the last placed at the columns of the landmark actually observed (thesis-notes on (3.48)).

Initialisation (3.42)–(3.44): ``L_xy = E12 (p + R p_FinI)`` with ``p_FinI = R_CIᵀ (p_FinC − t_CI)``
(thesis ``[t_C]_B + C_C^B ŷ_foot``); ``G_X``: ``∂/∂dθ = −E12 R [p_FinI×]`` (the corrected sign of
(3.42); the printed ``+2`` contradicts (3.44)), ``∂/∂δp = E12``; ``G_y = E12 R R_CIᵀ`` (3.43).
"""

from __future__ import annotations

import numpy as np

from gaitnet.geometry import rotmat_from_quat, skew
from gaitnet.vio.measurement import Augmentation, Measurement
from gaitnet.vio.state import FilterState

E12 = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def partial_foot_noise(
    std_m: float, width_m: float, full_width_m: float, axis_C: np.ndarray, up_C: np.ndarray
) -> np.ndarray:
    """Noise (3, 3) of a measured stance-foot point in the camera frame when only part of the
    foot shows: ``std_m²`` per axis (the thesis's ``r_foot I3`` of (3.26)) plus, across the
    foot's main floor axis ``axis_C`` on the floor (``up_C`` the floor's normal), the square
    of half the hidden width, ``(full_width_m − width_m) / 2``. A thigh that hides one side of
    a planted foot moves its centroid sideways as the camera passes: on a CMU walker looped to
    20 s the walking landmarks were seen 5–7.5 cm wide against 11.5 cm standing, and their
    points moved 2 cm sideways within 4–5 frames, which the filter took for the camera's
    motion (16.7 cm sideways mid-walk). Along the foot nothing is added: the stride length
    rests on it."""
    R3 = np.eye(3) * float(std_m) ** 2
    up = np.asarray(up_C, dtype=np.float64) / np.linalg.norm(up_C)
    along = np.asarray(axis_C, dtype=np.float64)
    along = along - (along @ up) * up
    norm = np.linalg.norm(along)
    if norm < 1e-9:
        return R3
    across = np.cross(up, along / norm)
    hidden = max(float(full_width_m) - float(width_m), 0.0) / 2.0
    return R3 + hidden**2 * np.outer(across, across)


class FootNoise:
    """The noise of each measured stance-foot point of a session: ``std_m²`` per axis, and with
    ``partial`` the hidden width of :func:`partial_foot_noise` against the whole foot's width
    as the session shows it, the 90th percentile of the widths seen so far (the standing
    start shows both feet whole), once :attr:`MIN_VIEWS` have been seen."""

    MIN_VIEWS = 10

    def __init__(self, std_m: float, partial: bool) -> None:
        self.std_m = float(std_m)
        self.partial = bool(partial)
        self._widths: list[float] = []

    def of(self, width_m: float, axis_C: np.ndarray, up_C: np.ndarray) -> np.ndarray:
        """The noise (3, 3) of a point measured on a foot seen ``width_m`` wide."""
        if not self.partial:
            return np.eye(3) * self.std_m**2
        self._widths.append(float(width_m))
        if len(self._widths) < self.MIN_VIEWS:
            return np.eye(3) * self.std_m**2
        full = float(np.percentile(self._widths, 90))
        return partial_foot_noise(self.std_m, width_m, full, axis_C, up_C)


def foot_predict(
    q: np.ndarray, p_IinW: np.ndarray, xy: np.ndarray, T_CfromI: np.ndarray
) -> np.ndarray:
    """``f_foot`` (3.35): the floor point ``(x, y, 0)`` in the camera frame of the IMU pose
    ``(q, p_IinW)``."""
    R_CI, t_CI = T_CfromI[:3, :3], T_CfromI[:3, 3]
    L = np.array([xy[0], xy[1], 0.0])
    return R_CI @ rotmat_from_quat(q).T @ (L - p_IinW) + t_CI


def foot_measurement(
    state: FilterState,
    T_CfromI: np.ndarray,
    lm_id: int,
    p_FinC: np.ndarray,
    R3: np.ndarray,
) -> Measurement:
    """Re-observation of landmark ``lm_id`` at ``p_FinC`` (3,) in the current camera frame with
    noise ``R3`` (3, 3) (thesis ``r_foot I3`` of (3.26)); blocks on ``att``, ``pos`` and
    ``("lm", lm_id)`` (3.45)–(3.48)."""
    xy = state.landmarks[lm_id]
    R_CI = T_CfromI[:3, :3]
    R = rotmat_from_quat(state.imu.q)
    A = R_CI @ R.T  # R_CfromW
    L = np.array([xy[0], xy[1], 0.0])
    pred = foot_predict(state.imu.q, state.imu.p_IinW, xy, T_CfromI)
    H = {
        "att": R_CI @ skew(R.T @ (L - state.imu.p_IinW)),
        "pos": -A,
        ("lm", lm_id): A @ E12.T,
    }
    return Measurement(
        np.asarray(p_FinC, dtype=np.float64) - pred,
        H,
        np.asarray(R3, dtype=np.float64),
        f"foot {lm_id}",
    )


def landmark_xy(
    q: np.ndarray, p_IinW: np.ndarray, p_FinC: np.ndarray, T_CfromI: np.ndarray
) -> np.ndarray:
    """(3.44) without errors: the world ``(x, y)`` of the camera-frame floor point ``p_FinC``."""
    R_CI, t_CI = T_CfromI[:3, :3], T_CfromI[:3, 3]
    p_FinI = R_CI.T @ (np.asarray(p_FinC, dtype=np.float64) - t_CI)
    return E12 @ (p_IinW + rotmat_from_quat(q) @ p_FinI)


def landmark_from_observation(
    state: FilterState, T_CfromI: np.ndarray, p_FinC: np.ndarray, R3: np.ndarray
) -> Augmentation:
    """A new landmark from its first observation ``p_FinC`` (noise ``R3``): value (3.44), ``G_X``
    (3.42, corrected sign) on ``att`` and ``pos``, noise ``G_y R3 G_yᵀ`` (3.40), (3.43). Feed it
    to :func:`gaitnet.vio.covariance.augment_landmark`."""
    R_CI, t_CI = T_CfromI[:3, :3], T_CfromI[:3, 3]
    R = rotmat_from_quat(state.imu.q)
    p_FinI = R_CI.T @ (np.asarray(p_FinC, dtype=np.float64) - t_CI)
    value = E12 @ (state.imu.p_IinW + R @ p_FinI)
    G = {"att": -E12 @ R @ skew(p_FinI), "pos": E12.copy()}
    G_y = E12 @ R @ R_CI.T
    return Augmentation(value, G, G_y @ np.asarray(R3, dtype=np.float64) @ G_y.T, "foot landmark")
