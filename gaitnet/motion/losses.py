"""Training losses of the motion predictor (thesis sec. 4.2.3, eq. 4.5 and 4.6).

Both losses average over every frame of the output sequence (the ``T + K`` frames: the
reconstructed past and the prediction, as the thesis and LTD do), every joint and the batch.

* MPJPE (4.5, :func:`gaitnet.evaluation.metrics.mpjpe`): mean Euclidean distance between
  predicted and true joint positions. Positions come from forward kinematics
  (:func:`gaitnet.motion.gcn.joint_positions`) of the 21-node pose vector of
  :mod:`gaitnet.motion.gcn` on a :class:`LowerBodySkeleton`, for the 7 lower-body joints
  (pelvis, hips, knees, ankles). The root translation is not predicted, so
  both poses are placed with the same translation (zero by default), which cancels.
* MAE (4.6, :func:`gaitnet.evaluation.metrics.mean_angle_error`): mean over joints and frames
  of ``|x̂ − x|`` for the 3-component axis-angle vectors; ``|·|`` is read as the L1 norm of the
  3-vector (LTD sums absolute differences over components), i.e. 3 × the element-wise mean
  absolute error.
"""

from __future__ import annotations

from typing import NamedTuple

import torch

from gaitnet.evaluation.metrics import mean_angle_error, mpjpe
from gaitnet.motion.gcn import joint_positions
from gaitnet.motion.skeleton import LowerBodySkeleton

__all__ = ["MotionLoss", "motion_loss", "per_window_skeleton"]


class MotionLoss(NamedTuple):
    """``total = w_mpjpe · mpjpe + w_mae · mae`` and its two terms (scalar tensors)."""

    total: torch.Tensor
    mpjpe: torch.Tensor
    mae: torch.Tensor


def per_window_skeleton(
    skeleton: LowerBodySkeleton | torch.Tensor, poses: torch.Tensor
) -> LowerBodySkeleton | torch.Tensor:
    """A (B, 9, 3) batch of skeletons shaped to broadcast with (B, W, 21) poses (B, 1, 9, 3)."""
    if isinstance(skeleton, torch.Tensor) and skeleton.dim() == 3 and poses.dim() == 3:
        if skeleton.shape[0] != poses.shape[0]:
            raise ValueError(
                f"{skeleton.shape[0]} skeletons for a batch of {poses.shape[0]} windows"
            )
        return skeleton[:, None]
    return skeleton


def motion_loss(
    pred: torch.Tensor,
    target: torch.Tensor,
    skeleton: LowerBodySkeleton | torch.Tensor,
    *,
    w_mpjpe: float = 1.0,
    w_mae: float = 1.0,
) -> MotionLoss:
    """Weighted sum of (4.5) through forward kinematics and (4.6) on (..., 21) pose vectors.

    ``skeleton``: one skeleton for every window (a :class:`LowerBodySkeleton` or a (9, 3)
    rest-joint tensor), or one per window: (B, 9, 3) for (B, W, 21) poses (each clip's own
    skeleton, :func:`gaitnet.training.predictor.clip_skeletons`).
    """
    if pred.shape != target.shape:
        raise ValueError(f"motion_loss needs equal shapes, got {pred.shape}, {target.shape}")
    skeleton = per_window_skeleton(skeleton, pred)
    l_pos = mpjpe(joint_positions(pred, skeleton), joint_positions(target, skeleton))
    l_ang = mean_angle_error(pred, target)
    return MotionLoss(total=w_mpjpe * l_pos + w_mae * l_ang, mpjpe=l_pos, mae=l_ang)
