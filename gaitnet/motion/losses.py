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

Window weights (optional, ``window_weights``): the total is then the mean over the windows of
``w_b · (w_mpjpe · MPJPE_b + w_mae · MAE_b)`` instead of the plain mean.
:func:`baseline_window_weights` gives ``w_b = ε / (e_b + ε)``, ``e_b`` the MPJPE of a baseline
guess (the model's damped-velocity padding) over the predicted frames: each window's loss is
divided by its baseline error plus ``ε`` (times the constant ``ε``, so that the loss keeps its
units and a window whose guess is exact keeps weight 1). A still window's error of about 1 mm
then counts as much as a walking window's error of several centimetres relative to what the
guess leaves. The reported ``mpjpe`` / ``mae`` terms stay the unweighted means.
"""

from __future__ import annotations

from typing import NamedTuple

import torch

from gaitnet.evaluation.metrics import angle_errors, joint_distances, mean_angle_error, mpjpe
from gaitnet.motion.gcn import joint_positions
from gaitnet.motion.skeleton import LowerBodySkeleton

__all__ = ["MotionLoss", "baseline_window_weights", "motion_loss", "per_window_skeleton"]


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
    window_weights: torch.Tensor | None = None,
) -> MotionLoss:
    """Weighted sum of (4.5) through forward kinematics and (4.6) on (..., 21) pose vectors.

    ``skeleton``: one skeleton for every window (a :class:`LowerBodySkeleton` or a (9, 3)
    rest-joint tensor), or one per window: (B, 9, 3) for (B, W, 21) poses (each clip's own
    skeleton, :func:`gaitnet.training.predictor.clip_skeletons`). ``window_weights`` (B,) for
    (B, W, 21) poses: ``total`` is the mean over the windows of each window's loss times its
    weight (module docstring); ``mpjpe`` and ``mae`` stay the unweighted means.
    """
    if pred.shape != target.shape:
        raise ValueError(f"motion_loss needs equal shapes, got {pred.shape}, {target.shape}")
    skeleton = per_window_skeleton(skeleton, pred)
    p_pred, p_true = joint_positions(pred, skeleton), joint_positions(target, skeleton)
    if window_weights is None:
        l_pos = mpjpe(p_pred, p_true)
        l_ang = mean_angle_error(pred, target)
        return MotionLoss(total=w_mpjpe * l_pos + w_mae * l_ang, mpjpe=l_pos, mae=l_ang)
    if pred.dim() != 3 or window_weights.shape != pred.shape[:1]:
        raise ValueError(
            f"window_weights {tuple(window_weights.shape)} need (B, W, 21) poses with B "
            f"windows, got poses {tuple(pred.shape)}"
        )
    pos_b = joint_distances(p_pred, p_true).flatten(1).mean(1)  # (B,) MPJPE per window
    ang_b = angle_errors(pred, target).flatten(1).mean(1)  # (B,) MAE per window
    total = (window_weights * (w_mpjpe * pos_b + w_mae * ang_b)).mean()
    return MotionLoss(total=total, mpjpe=pos_b.mean(), mae=ang_b.mean())


@torch.no_grad()
def baseline_window_weights(
    guess: torch.Tensor,
    target: torch.Tensor,
    skeleton: LowerBodySkeleton | torch.Tensor,
    eps_m: float,
) -> torch.Tensor:
    """``ε / (e_b + ε)`` per window (module docstring): ``e_b`` the MPJPE (4.5) of the baseline
    ``guess`` against ``target``, both (B, K, 21) predicted frames; ``eps_m`` = ε in metres.
    No gradient flows through the weights."""
    if eps_m <= 0:
        raise ValueError(f"eps_m must be > 0, got {eps_m}")
    skeleton = per_window_skeleton(skeleton, guess)
    err = joint_distances(joint_positions(guess, skeleton), joint_positions(target, skeleton))
    return eps_m / (err.flatten(1).mean(1) + eps_m)
