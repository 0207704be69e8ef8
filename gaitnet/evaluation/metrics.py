"""Error metrics against ground truth (pure math: no file io, no plotting, no argparse).

- MPJPE: mean per-joint position error, thesis eq. (4.5). The ONE implementation, used by the
  training loss and validation (:mod:`gaitnet.motion.losses`, ``train/predictor.py``), the
  predictor evaluation per horizon (:mod:`gaitnet.motion.evaluation`) and ``gaitnet
  evaluate`` (:mod:`gaitnet.evaluation.evaluate`). :func:`joint_distances`, :func:`mpjpe` and
  :func:`mpjpe_per_horizon` take numpy arrays (computed in float64, returning floats / arrays)
  or torch tensors (staying on their device and in the autograd graph, as the loss needs).
- Angle error, thesis eq. (4.6): the L1 norm of the axis-angle difference per rotation, mean
  over rotations (:func:`angle_errors`, :func:`mean_angle_error`), numpy or torch alike.
- ATE after a 4-DoF alignment (yaw about the gravity axis + translation), the usual alignment
  for visual-inertial estimates whose roll and pitch are observable (docs/thesis-notes.md,
  NMATE).
"""

from __future__ import annotations

import sys
from typing import Any, Literal

import numpy as np

__all__ = [
    "align_yaw_translation",
    "angle_errors",
    "ate_yaw_aligned",
    "joint_distances",
    "match_times",
    "mean_angle_error",
    "mpjpe",
    "mpjpe_per_horizon",
    "mpjpe_yaw_aligned",
    "per_horizon",
]

Reduction = Literal["mean", "sum"]


def _is_tensor(x: Any) -> bool:
    """Whether ``x`` is a torch tensor (without importing torch for numpy callers)."""
    torch = sys.modules.get("torch")
    return torch is not None and isinstance(x, torch.Tensor)


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


def joint_distances(est: Any, ref: Any) -> Any:
    """``‖est − ref‖₂`` per joint: (..., V, 3) positions → (..., V) distances [m].

    numpy inputs are computed in float64; torch tensors keep their dtype, device and graph
    (``vector_norm`` has a zero subgradient at zero distance, so a joint that is always exact,
    such as the pelvis without translation, gives no NaN gradient).
    """
    if _is_tensor(est) or _is_tensor(ref):
        import torch

        if est.shape != ref.shape or est.shape[-1] != 3:
            raise ValueError(f"need equal (..., V, 3) shapes, got {est.shape} and {ref.shape}")
        return torch.linalg.vector_norm(est - ref, dim=-1)
    est, ref = np.asarray(est, np.float64), np.asarray(ref, np.float64)
    if est.shape != ref.shape or est.shape[-1:] != (3,):
        raise ValueError(f"need equal (..., V, 3) shapes, got {est.shape} and {ref.shape}")
    return np.linalg.norm(est - ref, axis=-1)


def mpjpe(est: Any, ref: Any) -> Any:
    """Eq. (4.5): mean over every leading axis and joint of ``‖est − ref‖₂``; (..., V, 3).

    A float for numpy inputs, a scalar tensor (differentiable) for torch tensors.
    """
    d = joint_distances(est, ref).mean()
    return d if _is_tensor(d) else float(d)


def per_horizon(errors: Any, reduction: Reduction = "mean") -> Any:
    """(B, K, J) per-window, per-horizon, per-joint errors → (K,): mean over the J joints,
    then mean (or ``"sum"``, to accumulate batches) over the B windows."""
    if errors.ndim != 3:
        raise ValueError(f"need (windows, horizons, joints) errors, got shape {errors.shape}")
    by_window = errors.mean(-1)
    if reduction == "sum":
        return by_window.sum(0)
    if reduction == "mean":
        return by_window.mean(0)
    raise ValueError(f"reduction must be 'mean' or 'sum', got {reduction!r}")


def mpjpe_per_horizon(est: Any, ref: Any, reduction: Reduction = "mean") -> Any:
    """MPJPE (4.5) per prediction horizon: (B, K, V, 3) positions → (K,) [m].

    Mean over the V joints and (``reduction="mean"``) the B windows; ``"sum"`` sums over the
    windows instead so batches can be accumulated and divided by the window count at the end.
    """
    return per_horizon(joint_distances(est, ref), reduction)


def angle_errors(est: Any, ref: Any) -> Any:
    """Eq. (4.6) per rotation: L1 norm of the axis-angle difference, (..., 3·J) → (..., J).

    The last axis holds J stacked 3-component axis-angles (e.g. the 21-node vectors of
    :mod:`gaitnet.motion.gcn`); a (..., J, 3) array gives (..., J, 1), with the same mean.
    """
    if est.shape != ref.shape or est.shape[-1] % 3 != 0:
        raise ValueError(f"need equal (..., 3·J) shapes, got {est.shape} and {ref.shape}")
    if _is_tensor(est) or _is_tensor(ref):
        d = (est - ref).reshape(*est.shape[:-1], -1, 3)
        return d.abs().sum(dim=-1)
    d = (np.asarray(est, np.float64) - np.asarray(ref, np.float64)).reshape(*est.shape[:-1], -1, 3)
    return np.abs(d).sum(axis=-1)


def mean_angle_error(est: Any, ref: Any) -> Any:
    """Eq. (4.6): mean over every leading axis and rotation of :func:`angle_errors` [rad]."""
    d = angle_errors(est, ref).mean()
    return d if _is_tensor(d) else float(d)


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


def mpjpe_yaw_aligned(est: np.ndarray, ref: np.ndarray) -> float:
    """Eq. (4.5) after the 4-DoF alignment (:func:`align_yaw_translation`) of every joint of
    every frame at once: (n, V, 3) positions → the mean joint distance [m]. One rigid motion
    for the whole sequence, so it removes a different world origin and heading, not errors
    of the pose from frame to frame."""
    est, ref = np.asarray(est, np.float64), np.asarray(ref, np.float64)
    if est.shape != ref.shape or est.ndim != 3 or est.shape[2] != 3 or est.size == 0:
        raise ValueError(f"need matching non-empty (n, V, 3) arrays, got {est.shape}, {ref.shape}")
    R, t = align_yaw_translation(est.reshape(-1, 3), ref.reshape(-1, 3))
    return mpjpe(est @ R.T + t, ref)


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
