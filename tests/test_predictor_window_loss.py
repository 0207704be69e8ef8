"""loss.window_normalisation: each window's loss divided by its padding guess's error + ε
(gaitnet.motion.losses.baseline_window_weights, gaitnet.training.predictor.window_weights),
checked against a hand computation on two tiny windows."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from gaitnet.config import parse_config
from gaitnet.errors import ConfigError
from gaitnet.motion.gcn import DCTGCN, PredictorConfig
from gaitnet.motion.losses import motion_loss
from gaitnet.motion.skeleton import builtin_skeleton
from gaitnet.training.predictor import LossConfig, window_weights

N_PAST, N_FUTURE = 10, 10
L_KNEE_X = 9  # node 3j + c of joint j = 3 (L_knee), component x
SKEL = builtin_skeleton(1.75)
# a left-knee rotation by θ moves only the left ankle (local joint 5) among the 7 joints
SHANK = float(np.linalg.norm(SKEL.rest_joints[5] - SKEL.rest_joints[3]))


def _windows(theta_truth: float, theta_pred: float) -> tuple[torch.Tensor, torch.Tensor]:
    """Two windows, all zero pose; window 1's truth flexes the left knee by ``theta_truth`` in
    the future frames, window 0's prediction by ``theta_pred`` (window 0's truth stays still,
    window 1's prediction stays still)."""
    truth = torch.zeros(2, N_PAST + N_FUTURE, 21, dtype=torch.float64)
    truth[1, N_PAST:, L_KNEE_X] = theta_truth
    pred = torch.zeros_like(truth)
    pred[0, N_PAST:, L_KNEE_X] = theta_pred
    return pred, truth


def _ankle_mpjpe(theta: float) -> float:
    """MPJPE over the 7 joints of a pose whose left knee is off by ``theta``: one joint moves
    by the chord 2 · shank · sin(θ/2)."""
    return 2 * SHANK * math.sin(theta / 2) / 7


def test_baseline_normalisation_matches_the_hand_computation() -> None:
    t_truth, t_pred, eps, w_mae = 0.3, 0.1, 0.01, 0.1
    pred, truth = _windows(t_truth, t_pred)
    skel = torch.tensor(np.array(SKEL.rest_joints), dtype=torch.float64).expand(2, 9, 3)
    model = DCTGCN(PredictorConfig(hidden=8, n_blocks=1, residual="last_pose",
                                   pad_velocity_decay=0.8)).double()  # fmt: skip
    cfg = LossConfig(window_normalisation="baseline", normalisation_eps_m=eps)
    w = window_weights(cfg, model, truth, skel)
    # both windows' past is still: the padding guess is the zero pose; window 0's truth is
    # still (error 0, weight 1), window 1's is off by the knee angle in the 10 future frames
    e1 = _ankle_mpjpe(t_truth)
    np.testing.assert_allclose(w.numpy(), [1.0, eps / (e1 + eps)], rtol=1e-12)

    # per window over all 20 frames: half the frames carry the error; MAE: one of 7 rotations
    m = [0.5 * _ankle_mpjpe(t_pred), 0.5 * e1]
    a = [0.5 * t_pred / 7, 0.5 * t_truth / 7]
    loss = motion_loss(pred, truth, skel, w_mpjpe=1.0, w_mae=w_mae, window_weights=w)
    want = (1.0 * (m[0] + w_mae * a[0]) + eps / (e1 + eps) * (m[1] + w_mae * a[1])) / 2
    assert float(loss.total) == pytest.approx(want, rel=1e-10)
    # the reported terms stay the plain means
    assert float(loss.mpjpe) == pytest.approx(sum(m) / 2, rel=1e-10)
    assert float(loss.mae) == pytest.approx(sum(a) / 2, rel=1e-10)

    # "none": no weights, the plain mean (which the weighted total undercuts here)
    assert window_weights(LossConfig(), model, truth, skel) is None
    plain = motion_loss(pred, truth, skel, w_mpjpe=1.0, w_mae=w_mae)
    assert float(plain.total) == pytest.approx((m[0] + m[1] + w_mae * (a[0] + a[1])) / 2)
    assert float(loss.total) < float(plain.total)


def test_weights_follow_the_damped_padding_and_carry_no_gradient() -> None:
    """A window moving at constant velocity: with γ = 0 the guess is zero velocity, with γ > 0
    it continues the step, so its error (and the weight's shortfall from 1) is smaller."""
    truth = torch.zeros(1, N_PAST + N_FUTURE, 21, dtype=torch.float64)
    truth[0, :, L_KNEE_X] = 0.02 * torch.arange(N_PAST + N_FUTURE, dtype=torch.float64)
    skel = torch.tensor(np.array(SKEL.rest_joints), dtype=torch.float64).expand(1, 9, 3)
    cfg = LossConfig(window_normalisation="baseline", normalisation_eps_m=0.01)
    weights = {}
    for g in (0.0, 0.8):
        model = DCTGCN(PredictorConfig(hidden=8, n_blocks=1, pad_velocity_decay=g)).double()
        weights[g] = float(window_weights(cfg, model, truth.requires_grad_(True), skel)[0])
    last = 0.02 * (N_PAST - 1)
    e0 = np.mean([_ankle_mpjpe(0.02 * (N_PAST + k) - last) for k in range(N_FUTURE)])
    assert weights[0.0] == pytest.approx(0.01 / (e0 + 0.01), rel=1e-9)
    assert weights[0.0] < weights[0.8] < 1.0
    w = window_weights(cfg, model, truth, skel)
    assert not w.requires_grad


@pytest.mark.parametrize(
    "raw, match",
    [({"window_normalisation": "zero"}, "window_normalisation"),
     ({"normalisation_eps_m": 0.0}, "normalisation_eps_m")],
)  # fmt: skip
def test_bad_window_normalisation_keys(raw: dict, match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        parse_config(LossConfig, raw, "loss")
