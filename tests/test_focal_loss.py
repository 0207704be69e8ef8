"""Focal loss (gaitnet.segmentation.focal_loss): a hand computation, the gamma = 0 →
cross-entropy identity, alpha weighting, the ignore index, an all-ignored batch."""

from __future__ import annotations

import math

import pytest
import torch
from torch.nn import functional as nnf

from gaitnet.errors import ConfigError, InputError
from gaitnet.segmentation.focal_loss import FocalLoss

# One image, 3 classes, 1 × 3 pixels; targets 0, 2, 255 (ignored).
LOGITS = torch.tensor([[1.0, 0.0, 3.0], [2.0, 0.0, 1.0], [0.0, 0.0, -1.0]]).view(1, 3, 1, 3)
TARGET = torch.tensor([[[0, 2, 255]]])


def softmax_by_hand(values: list[float]) -> list[float]:
    e = [math.exp(v) for v in values]
    return [v / sum(e) for v in e]


def test_hand_computation() -> None:
    alpha, gamma = [0.25, 0.5, 1.5], 2.0
    # pixel 0: logits (1, 2, 0), true class 0; pixel 1: logits (0, 0, 0), true class 2
    p0 = softmax_by_hand([1.0, 2.0, 0.0])[0]
    p1 = softmax_by_hand([0.0, 0.0, 0.0])[2]
    fl0 = -alpha[0] * (1 - p0) ** gamma * math.log(p0)
    fl1 = -alpha[2] * (1 - p1) ** gamma * math.log(p1)
    loss = FocalLoss(alpha=alpha, gamma=gamma)(LOGITS, TARGET)
    assert loss.item() == pytest.approx((fl0 + fl1) / 2, rel=1e-6)
    total = FocalLoss(alpha=alpha, gamma=gamma, reduction="sum")(LOGITS, TARGET)
    assert total.item() == pytest.approx(fl0 + fl1, rel=1e-6)


@pytest.mark.parametrize("ignore_index", [255, -100])
def test_gamma_zero_is_cross_entropy(ignore_index: int) -> None:
    gen = torch.Generator().manual_seed(0)
    logits = 3 * torch.randn(2, 3, 5, 7, generator=gen)
    target = torch.randint(0, 3, (2, 5, 7), generator=gen)
    target[0, 1:3, 2:6] = ignore_index
    ours = FocalLoss(gamma=0.0, ignore_index=ignore_index)(logits, target)
    ref = nnf.cross_entropy(logits, target, ignore_index=ignore_index)
    assert ours.item() == pytest.approx(ref.item(), rel=1e-6)
    ours_sum = FocalLoss(gamma=0.0, ignore_index=ignore_index, reduction="sum")(logits, target)
    ref_sum = nnf.cross_entropy(logits, target, ignore_index=ignore_index, reduction="sum")
    assert ours_sum.item() == pytest.approx(ref_sum.item(), rel=1e-6)


def test_alpha_weights_each_class() -> None:
    gen = torch.Generator().manual_seed(1)
    logits = torch.randn(1, 3, 4, 4, generator=gen)
    target = torch.randint(0, 3, (1, 4, 4), generator=gen)
    alpha = [0.2, 1.0, 3.0]
    per_pixel = nnf.cross_entropy(logits, target, reduction="none")  # gamma 0: CE per pixel
    expected = (torch.tensor(alpha)[target] * per_pixel).sum() / target.numel()
    got = FocalLoss(alpha=alpha, gamma=0.0)(logits, target)
    assert got.item() == pytest.approx(expected.item(), rel=1e-6)
    # scaling one class's alpha scales only that class's pixels' share
    only_two = FocalLoss(alpha=[0.0, 0.0, 1.0], gamma=0.0, reduction="sum")(logits, target)
    assert only_two.item() == pytest.approx(per_pixel[target == 2].sum().item(), rel=1e-6)


def test_gamma_down_weights_easy_pixels() -> None:
    # an easy pixel (p_t ≈ 0.99) loses far more of its loss than a hard one (p_t ≈ 0.1)
    easy = torch.tensor([5.0, 0.0, 0.0]).view(1, 3, 1, 1)
    hard = torch.tensor([-1.0, 1.2, 0.0]).view(1, 3, 1, 1)
    t = torch.zeros(1, 1, 1, dtype=torch.int64)
    ratio_easy = FocalLoss(gamma=2.0)(easy, t) / FocalLoss(gamma=0.0)(easy, t)
    ratio_hard = FocalLoss(gamma=2.0)(hard, t) / FocalLoss(gamma=0.0)(hard, t)
    p_easy = softmax_by_hand([5.0, 0.0, 0.0])[0]
    p_hard = softmax_by_hand([-1.0, 1.2, 0.0])[0]
    assert ratio_easy.item() == pytest.approx((1 - p_easy) ** 2, rel=1e-5)
    assert ratio_hard.item() == pytest.approx((1 - p_hard) ** 2, rel=1e-5)


def test_ignored_pixels_do_not_count() -> None:
    logits = LOGITS.clone().requires_grad_(True)
    loss = FocalLoss(alpha=[1.0, 2.0, 3.0], gamma=2.0)(logits, TARGET)
    loss.backward()
    assert torch.count_nonzero(logits.grad[..., 2]) == 0  # the ignored pixel
    # changing the ignored pixel's logits changes nothing
    other = LOGITS.clone()
    other[..., 2] = torch.tensor([9.0, -9.0, 4.0]).view(1, 3, 1)
    again = FocalLoss(alpha=[1.0, 2.0, 3.0], gamma=2.0)(other, TARGET)
    assert again.item() == loss.item()


@pytest.mark.parametrize("reduction", ["mean", "sum"])
def test_all_ignored_is_zero_without_nan(reduction: str) -> None:
    logits = torch.randn(2, 3, 4, 4, requires_grad=True)
    target = torch.full((2, 4, 4), 255, dtype=torch.int64)
    loss = FocalLoss(alpha=[1.0, 1.0, 1.0], gamma=2.0, reduction=reduction)(logits, target)
    assert loss.item() == 0.0
    loss.backward()
    assert torch.isfinite(logits.grad).all() and torch.count_nonzero(logits.grad) == 0


@pytest.mark.parametrize("gamma", [0.5, 2.0])
def test_certain_pixels_have_finite_gradients(gamma: float) -> None:
    # p_t rounds to 1 in float32: (1 - p_t)^gamma must not give an infinite or NaN gradient
    logits = torch.tensor([200.0, 0.0, 0.0]).view(1, 3, 1, 1).requires_grad_(True)
    loss = FocalLoss(gamma=gamma)(logits, torch.zeros(1, 1, 1, dtype=torch.int64))
    loss.backward()
    assert torch.isfinite(loss) and torch.isfinite(logits.grad).all()


def test_bad_arguments() -> None:
    with pytest.raises(ConfigError, match="gamma"):
        FocalLoss(gamma=-1.0)
    with pytest.raises(ConfigError, match="alpha"):
        FocalLoss(alpha=[1.0, float("nan"), 1.0])
    with pytest.raises(ConfigError, match="alpha"):
        FocalLoss(alpha=[1.0, -0.5, 1.0])
    with pytest.raises(ConfigError, match="reduction"):
        FocalLoss(reduction="none")
    with pytest.raises(ConfigError, match="2 values for 3 classes"):
        FocalLoss(alpha=[1.0, 1.0])(LOGITS, TARGET)
    with pytest.raises(InputError, match="label 7"):
        FocalLoss()(LOGITS, torch.tensor([[[0, 7, 255]]]))
    with pytest.raises(InputError, match="int64"):
        FocalLoss()(LOGITS, TARGET.to(torch.int32))
    with pytest.raises(InputError, match="target"):
        FocalLoss()(LOGITS, TARGET[0])
