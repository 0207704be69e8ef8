"""The one place that changes the error-state covariance and the state layout.

After OpenVINS' ``StateHelper``: :func:`propagate` (time update, thesis (3.8)–(3.10)),
:func:`update` (Kalman update in Joseph form, then error injection and reset), :func:`clone`
(stochastic cloning of the IMU pose, thesis (3.10)), :func:`augment_landmark` (thesis
(3.38)–(3.41)), :func:`marginalise_landmark`, :func:`inflate_to_pass` (a diverged filter's
covariance widened to take a trusted measurement) and :func:`check_healthy`. Every function changes
the state in place. Layout and conventions: :mod:`gaitnet.vio.state`.
"""

from __future__ import annotations

import functools
import logging
from dataclasses import dataclass

import numpy as np
from scipy.linalg import cho_factor, cho_solve

from gaitnet.vio.errors import FilterDivergedError
from gaitnet.vio.measurement import Augmentation, Measurement, stack_jacobian
from gaitnet.vio.state import CLONE_DIM, IMU_DIM, LM_DIM, FilterState, PoseClone

logger = logging.getLogger(__name__)

#: Smallest eigenvalue tolerated, relative to the largest diagonal entry, before ``P`` counts as
#: not positive semi-definite (round-off in a Joseph update is ~1e-16 relative).
PSD_TOL = 1e-9
#: Largest tolerated asymmetry ``|P - Pᵀ|``, relative to the largest diagonal entry.
SYM_TOL = 1e-9


@dataclass(frozen=True)
class UpdateResult:
    """``accepted``; ``chi2`` the innovation's Mahalanobis distance ``rᵀ S⁻¹ r`` (NaN when it
    could not be computed); ``dof`` the residual dimension; ``reason`` why it was rejected
    (empty when accepted)."""

    accepted: bool
    chi2: float
    dof: int
    reason: str = ""


@functools.lru_cache(maxsize=256)
def chi2_gate(dof: int, probability: float) -> float:
    """The ``probability`` quantile of χ²(``dof``): the gate of :func:`update` (e.g. 0.99).

    ``scipy.special.chdtri(dof, 1 − probability)`` (the inverse of the upper tail; the same
    value as ``scipy.stats.chi2.ppf``, without importing ``scipy.stats``, which takes seconds),
    cached: a run asks for the same few gates thousands of times."""
    from scipy.special import chdtri

    return float(chdtri(dof, 1.0 - probability))


def _symmetrise(P: np.ndarray) -> np.ndarray:
    return 0.5 * (P + P.T)


def propagate(state: FilterState, Phi15: np.ndarray, Q15: np.ndarray) -> None:
    """Time update of ``P`` with the IMU block's transition ``Phi15`` and noise ``Q15``
    (15×15, lifted to the frame rate: thesis (3.8), :mod:`gaitnet.vio.imu_propagation`).

    The clone and the landmarks are static (thesis (3.10): the clone row is the identity), so
    ``P_II ← Φ P_II Φᵀ + Q`` and ``P_I,rest ← Φ P_I,rest``. The nominal state is propagated by
    :mod:`gaitnet.vio.imu_propagation`.
    """
    P = state.P
    s = slice(0, IMU_DIM)
    P[s, :] = Phi15 @ P[s, :]
    P[:, s] = P[:, s] @ Phi15.T
    P[s, s] += Q15
    state.P = _symmetrise(P)


def update(state: FilterState, m: Measurement, *, gate_chi2: float | None = None) -> UpdateResult:
    """Kalman update with measurement ``m``, error injection and reset (thesis ch. 2 and
    (3.21), (3.33), (3.47)).

    ``S = H P Hᵀ + R``, ``K = P Hᵀ S⁻¹``; with ``gate_chi2`` set, a measurement whose
    ``rᵀ S⁻¹ r`` exceeds it is rejected (state unchanged). ``P ← (I − K H) P (I − K H)ᵀ +
    K R Kᵀ`` (Joseph form; ch. 2 omits the ``K R Kᵀ`` term, thesis-notes). ``δx = K r`` is
    injected into the nominal state (:meth:`FilterState.boxplus`: attitudes by
    ``quat_boxplus``, the rest additively) and the error reset to zero; the reset Jacobian
    ``I − [½δθ×]`` is taken as the identity (first order, as in OpenVINS). A non-finite
    residual or an ``S`` that is not positive definite is rejected with the reason, not raised.
    """
    r = np.asarray(m.residual, dtype=np.float64)
    dof = int(r.shape[0])
    if not np.all(np.isfinite(r)):
        return UpdateResult(False, float("nan"), dof, f"{m.name}: non-finite residual")
    H = stack_jacobian(m, state)
    P = state.P
    PHt = P @ H.T
    S = _symmetrise(H @ PHt + m.R)
    try:
        cho = cho_factor(S)
    except np.linalg.LinAlgError:
        return UpdateResult(
            False, float("nan"), dof, f"{m.name}: innovation covariance not positive definite"
        )
    chi2 = float(r @ cho_solve(cho, r))
    if gate_chi2 is not None and chi2 > gate_chi2:
        return UpdateResult(False, chi2, dof, f"{m.name}: chi2 {chi2:.3g} > gate {gate_chi2:.3g}")
    K = cho_solve(cho, PHt.T).T
    IKH = np.eye(state.dim) - K @ H
    state.P = _symmetrise(IKH @ P @ IKH.T + K @ m.R @ K.T)
    injected = state.boxplus(K @ r)
    state.imu = injected.imu
    state.clone = injected.clone
    state.landmarks = injected.landmarks
    return UpdateResult(True, chi2, dof)


NAV_DIM = 9  # dθ, δp, δv: the navigation block of the IMU error state (gaitnet.vio.state)


def mahalanobis2(S: np.ndarray, r: np.ndarray) -> float:
    """``rᵀ S⁻¹ r`` (NaN when ``S`` is singular): an innovation's χ² for its covariance ``S``."""
    try:
        return float(np.asarray(r) @ np.linalg.solve(S, np.asarray(r)))
    except np.linalg.LinAlgError:
        return float("nan")


def inflate_to_pass(
    state: FilterState, m: Measurement, target_chi2: float, max_factor: float = 1e8
) -> float:
    """Scale the navigation block of ``P`` (attitude, position, velocity; ``P_nav ← f P_nav``,
    i.e. ``P + (f − 1) blockdiag(P_nav, 0)``, which keeps ``P`` positive semi-definite) by the
    smallest factor ``f ≥ 1`` that brings ``m``'s ``rᵀ S⁻¹ r`` to ``target_chi2`` (bisection
    on ``log f``); returns ``f`` (1: it passes already, nothing changed; ``inf``: not even
    ``max_factor`` does, nothing changed). For a filter whose covariance no longer covers its
    error (``gaitnet.vio.run``: a sheet refused frame after frame); the update with ``m``
    follows as usual."""
    r = np.asarray(m.residual, dtype=np.float64)
    H = stack_jacobian(m, state)
    nav = np.zeros_like(state.P)
    nav[:NAV_DIM, :NAV_DIM] = state.P[:NAV_DIM, :NAV_DIM]

    def chi2(f: float) -> float:
        return mahalanobis2(_symmetrise(H @ (state.P + (f - 1.0) * nav) @ H.T + m.R), r)

    if not np.all(np.isfinite(r)) or chi2(1.0) <= target_chi2:
        return 1.0
    if not chi2(max_factor) <= target_chi2:  # unreachable (or NaN)
        return float("inf")
    lo, hi = 0.0, float(np.log(max_factor))
    while hi - lo > 1e-3:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if chi2(float(np.exp(mid))) > target_chi2 else (lo, mid)
    f = float(np.exp(hi))
    state.P = _symmetrise(state.P + (f - 1.0) * nav)
    return f


def clone(state: FilterState) -> None:
    """Copy the current IMU pose into the clone slot, with its covariance (stochastic cloning:
    thesis (3.10), ``U_{k−1} ← U_k``; velocity is not cloned because no measurement uses it).

    The clone's rows of ``P`` become copies of the attitude and position rows, so the clone is
    fully correlated with the current pose; the first call inserts the clone block after the
    IMU block (landmark blocks move down by 6).
    """
    n_old = state.dim
    has_clone = state.clone is not None
    pose = np.r_[0:6]  # att, pos rows of the IMU block
    if has_clone:
        A = np.eye(n_old)
        A[IMU_DIM : IMU_DIM + CLONE_DIM, :] = 0.0
        A[IMU_DIM + np.arange(CLONE_DIM), pose] = 1.0
    else:
        n_new = n_old + CLONE_DIM
        A = np.zeros((n_new, n_old))
        A[:IMU_DIM, :IMU_DIM] = np.eye(IMU_DIM)
        A[IMU_DIM + np.arange(CLONE_DIM), pose] = 1.0
        A[IMU_DIM + CLONE_DIM :, IMU_DIM:] = np.eye(n_old - IMU_DIM)
    state.P = _symmetrise(A @ state.P @ A.T)
    state.clone = PoseClone(state.imu.q.copy(), state.imu.p_IinW.copy(), float(state.imu.t_s))


def augment_landmark(state: FilterState, lm_id: int, aug: Augmentation) -> None:
    """Append landmark ``lm_id`` with value ``aug.value`` (2,) (thesis (3.38)–(3.41)).

    ``P_new = G P Gᵀ + R`` (3.40, with ``R = r_foot G_y G_yᵀ``), cross terms ``G P`` with every
    existing variable (3.41): ``G`` is the augmentation Jacobian ``G_X`` of (3.42) (corrected
    sign, :func:`gaitnet.vio.foot_model.landmark_from_observation`).
    """
    if lm_id in state.landmarks:
        raise ValueError(f"landmark {lm_id} is already in the state")
    value = np.asarray(aug.value, dtype=np.float64)
    if value.shape != (LM_DIM,) or aug.R.shape != (LM_DIM, LM_DIM):
        raise ValueError(f"{aug.name}: a landmark is {LM_DIM}-D, got {value.shape}")
    G = stack_jacobian(
        Measurement(residual=value, H=aug.G, R=aug.R, name=aug.name), state
    )  # (2, n)
    P = state.P
    cross = G @ P
    P_ll = cross @ G.T + aug.R
    n = state.dim
    P_new = np.empty((n + LM_DIM, n + LM_DIM))
    P_new[:n, :n] = P
    P_new[n:, :n] = cross
    P_new[:n, n:] = cross.T
    P_new[n:, n:] = P_ll
    state.P = _symmetrise(P_new)
    state.landmarks[lm_id] = value.copy()


def marginalise_landmark(state: FilterState, lm_id: int) -> None:
    """Remove landmark ``lm_id`` and its rows/columns of ``P`` (marginalisation of a Gaussian)."""
    sl = state.index(("lm", lm_id))
    keep = np.r_[0 : sl.start, sl.stop : state.dim]
    state.P = state.P[np.ix_(keep, keep)]
    del state.landmarks[lm_id]


def _block_name(state: FilterState, i: int) -> str:
    names = ["att", "pos", "vel", "bg", "ba"]
    if i < IMU_DIM:
        return names[i // 3]
    if state.clone is not None and i < IMU_DIM + CLONE_DIM:
        return "clone_att" if i < IMU_DIM + 3 else "clone_pos"
    k = (i - state.landmark_offset) // LM_DIM
    return f"landmark {list(state.landmarks)[k]}"


def check_healthy(state: FilterState) -> None:
    """Raise :class:`FilterDivergedError` if the nominal state or ``P`` has a NaN/inf, or ``P``
    is not symmetric positive semi-definite (smallest eigenvalue below ``-PSD_TOL`` times the
    largest variance); the message names the time and the block that failed."""
    t = state.imu.t_s
    nominal = {
        "attitude": state.imu.q,
        "position": state.imu.p_IinW,
        "velocity": state.imu.v_IinW,
        "gyro bias": state.imu.b_g,
        "accel bias": state.imu.b_a,
    }
    if state.clone is not None:
        nominal["clone attitude"] = state.clone.q
        nominal["clone position"] = state.clone.p_IinW
    for lm_id, xy in state.landmarks.items():
        nominal[f"landmark {lm_id}"] = xy
    for name, value in nominal.items():
        if not np.all(np.isfinite(value)):
            raise FilterDivergedError(f"filter diverged at t={t:.3f} s: non-finite {name}")
    P = state.P
    if P.shape != (state.dim, state.dim):
        raise FilterDivergedError(
            f"filter diverged at t={t:.3f} s: covariance shape {P.shape} does not match the "
            f"state dimension {state.dim}"
        )
    bad = ~np.isfinite(P)
    if bad.any():
        i = int(np.argwhere(bad)[0][0])
        raise FilterDivergedError(
            f"filter diverged at t={t:.3f} s: non-finite covariance in the "
            f"{_block_name(state, i)} block"
        )
    scale = max(float(np.max(np.abs(np.diag(P)))), 1e-300)
    asym = float(np.max(np.abs(P - P.T)))
    if asym > SYM_TOL * scale:
        raise FilterDivergedError(
            f"filter diverged at t={t:.3f} s: covariance not symmetric (|P - Pᵀ| = {asym:.3g})"
        )
    diag = np.diag(P)
    if np.any(diag < -PSD_TOL * scale):
        i = int(np.argmin(diag))
        raise FilterDivergedError(
            f"filter diverged at t={t:.3f} s: negative variance in the "
            f"{_block_name(state, i)} block"
        )
    w, V = np.linalg.eigh(_symmetrise(P))
    if w[0] < -PSD_TOL * scale:
        i = int(np.argmax(np.abs(V[:, 0])))
        raise FilterDivergedError(
            f"filter diverged at t={t:.3f} s: covariance not positive semi-definite "
            f"(eigenvalue {w[0]:.3g}, mostly in the {_block_name(state, i)} block)"
        )
