"""Training losses of the motion predictor (thesis sec. 4.2.3, eq. 4.5 and 4.6).

Both losses average over every frame of the output sequence (the ``T + K`` frames: the
reconstructed past and the prediction, as the thesis and LTD do), every joint and the batch.

* MPJPE (4.5): mean Euclidean distance between predicted and true joint positions. Positions
  come from forward kinematics (:func:`gaitnet.motion.skeleton.forward_kinematics_torch`) of
  the 21-node pose vector of :mod:`gaitnet.motion.gcn` on a :class:`LowerBodySkeleton`, for the
  7 lower-body joints (pelvis, hips, knees, ankles). The root translation is not predicted, so
  both poses are placed with the same translation (zero by default), which cancels.
* MAE (4.6): mean over joints and frames of ``|x̂ − x|`` for the 3-component axis-angle vectors;
  ``|·|`` is read as the L1 norm of the 3-vector (LTD sums absolute differences over
  components), i.e. 3 × the element-wise mean absolute error.
"""

from __future__ import annotations

from typing import NamedTuple

import torch

from gaitnet.motion.gcn import split_pose_features
from gaitnet.motion.skeleton import N_ROTATED, LowerBodySkeleton, forward_kinematics_torch

__all__ = [
    "N_LOSS_JOINTS",
    "MotionLoss",
    "joint_positions",
    "mean_angle_error",
    "motion_loss",
    "mpjpe",
]

#: The MPJPE uses the first 7 skeleton joints (SMPL 0, 1, 2, 4, 5, 7, 8), as the thesis.
N_LOSS_JOINTS = 7


class MotionLoss(NamedTuple):
    """``total = w_mpjpe · mpjpe + w_mae · mae`` and its two terms (scalar tensors)."""

    total: torch.Tensor
    mpjpe: torch.Tensor
    mae: torch.Tensor


def mpjpe(p_hat: torch.Tensor, p: torch.Tensor) -> torch.Tensor:
    """Eq. (4.5): mean over all leading axes and joints of ``‖p̂ − p‖₂``; inputs (..., V, 3)."""
    if p_hat.shape != p.shape or p.shape[-1] != 3:
        raise ValueError(f"mpjpe needs equal shapes (..., V, 3), got {p_hat.shape}, {p.shape}")
    return torch.linalg.vector_norm(p_hat - p, dim=-1).mean()


def mean_angle_error(x_hat: torch.Tensor, x: torch.Tensor) -> torch.Tensor:
    """Eq. (4.6): mean over joints and frames of the L1 norm of ``x̂ − x``.

    Accepts 21-node pose vectors (..., 21) or per-joint axis-angles (..., V, 3).
    """
    if x_hat.shape != x.shape or x.shape[-1] % 3 != 0:
        raise ValueError(f"mean_angle_error needs equal shapes, got {x_hat.shape}, {x.shape}")
    d = (x_hat - x).reshape(*x.shape[:-1], -1, 3)
    return d.abs().sum(dim=-1).mean()


def joint_positions(
    features: torch.Tensor,
    skeleton: LowerBodySkeleton | torch.Tensor,
    trans: torch.Tensor | None = None,
    *,
    n_joints: int = N_LOSS_JOINTS,
) -> torch.Tensor:
    """Forward kinematics of 21-node pose vectors (..., 21) → joints (..., n_joints, 3).

    The foot joints' own rotations are set to zero (they move none of the 9 skeleton joints).
    ``trans`` (..., 3) defaults to zero.
    """
    root, body = split_pose_features(features)
    feet = body.new_zeros(*body.shape[:-2], N_ROTATED - body.shape[-2], 3)
    joint_aa = torch.cat([body, feet], dim=-2)
    if trans is None:
        trans = features.new_zeros(*features.shape[:-1], 3)
    return forward_kinematics_torch(skeleton, root, trans, joint_aa)[..., :n_joints, :]


def motion_loss(
    pred: torch.Tensor,
    target: torch.Tensor,
    skeleton: LowerBodySkeleton | torch.Tensor,
    *,
    w_mpjpe: float = 1.0,
    w_mae: float = 1.0,
) -> MotionLoss:
    """Weighted sum of (4.5) through forward kinematics and (4.6) on (..., 21) pose vectors."""
    if pred.shape != target.shape:
        raise ValueError(f"motion_loss needs equal shapes, got {pred.shape}, {target.shape}")
    l_pos = mpjpe(joint_positions(pred, skeleton), joint_positions(target, skeleton))
    l_ang = mean_angle_error(pred, target)
    return MotionLoss(total=w_mpjpe * l_pos + w_mae * l_ang, mpjpe=l_pos, mae=l_ang)
