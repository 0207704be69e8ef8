"""Error metrics against ground truth (pure math: no file io, no plotting).

- MPJPE: mean per-joint position error, thesis eq. (4.5), over matched frames and joints.
- ATE after a 4-DoF alignment (yaw about the gravity axis + translation), the usual alignment
  for visual-inertial estimates whose roll and pitch are observable (thesis-notes, NMATE).
"""

from __future__ import annotations

import numpy as np


def match_times(t_est_ns: np.ndarray, t_ref_ns: np.ndarray, tol_ns: int = 1_000_000):
    """Index pairs (i_est, i_ref) of timestamps equal within ``tol_ns`` (nearest neighbour)."""
    t_est_ns = np.asarray(t_est_ns, np.int64)
    t_ref_ns = np.asarray(t_ref_ns, np.int64)
    if len(t_ref_ns) == 0 or len(t_est_ns) == 0:
        return np.zeros(0, int), np.zeros(0, int)
    order = np.argsort(t_ref_ns)
    ref_sorted = t_ref_ns[order]
    if len(ref_sorted) == 1:
        nearest = np.zeros(len(t_est_ns), int)
    else:
        pos = np.clip(np.searchsorted(ref_sorted, t_est_ns), 1, len(ref_sorted) - 1)
        left, right = ref_sorted[pos - 1], ref_sorted[pos]
        nearest = np.where(np.abs(t_est_ns - left) <= np.abs(right - t_est_ns), pos - 1, pos)
    ok = np.abs(ref_sorted[nearest] - t_est_ns) <= tol_ns
    return np.flatnonzero(ok), order[nearest[ok]]


def mpjpe(est: np.ndarray, ref: np.ndarray) -> float:
    """Mean Euclidean distance between corresponding joints (eq. 4.5), any leading shape."""
    est, ref = np.asarray(est, np.float64), np.asarray(ref, np.float64)
    if est.shape != ref.shape:
        raise ValueError(f"shape mismatch {est.shape} vs {ref.shape}")
    return float(np.linalg.norm(est - ref, axis=-1).mean())


def align_yaw_translation(p_est: np.ndarray, p_ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation about z and translation minimising Σ|R p_est + t − p_ref|² (closed form)."""
    a = p_est - p_est.mean(0)
    b = p_ref - p_ref.mean(0)
    # maximise Σ b·(R a) over yaw: tan θ = Σ(a_x b_y − a_y b_x) / Σ(a_x b_x + a_y b_y)
    s = np.sum(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
    c = np.sum(a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1])
    yaw = np.arctan2(s, c)
    R = np.array([[np.cos(yaw), -np.sin(yaw), 0.0], [np.sin(yaw), np.cos(yaw), 0.0], [0, 0, 1.0]])
    t = p_ref.mean(0) - R @ p_est.mean(0)
    return R, t


def ate_yaw_aligned(p_est: np.ndarray, p_ref: np.ndarray) -> float:
    """RMS position error after the 4-DoF alignment (m)."""
    p_est, p_ref = np.asarray(p_est, np.float64), np.asarray(p_ref, np.float64)
    if p_est.shape != p_ref.shape or p_est.ndim != 2 or p_est.shape[1] != 3:
        raise ValueError(f"need matching (n, 3) arrays, got {p_est.shape} and {p_ref.shape}")
    if len(p_est) < 2:
        raise ValueError("need at least 2 matched poses")
    R, t = align_yaw_translation(p_est, p_ref)
    err = p_est @ R.T + t - p_ref
    return float(np.sqrt(np.mean(np.sum(err**2, axis=1))))
