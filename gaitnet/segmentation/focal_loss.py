"""Multi-class softmax focal loss with per-class alpha and an ignore index (thesis sec. 4.1).

Focal loss (Lin, Goyal, Girshick, He, Dollár, "Focal Loss for Dense Object Detection", ICCV
2017), the softmax form over C classes, per pixel with true class t and predicted probability
``p_t = softmax(logits)_t``::

    FL = -alpha_t (1 - p_t)^gamma log(p_t)

``alpha`` (one weight per class, or None for 1) balances the classes, ``gamma`` down-weights
pixels that are already well classified; gamma = 0 without alpha is the cross-entropy. Pixels
whose target is ``ignore_index`` (255: labelme's ``__ignore__``) contribute nothing.
``reduction="mean"`` divides the sum by the number of non-ignored pixels (not by the sum of
their alphas, unlike ``F.cross_entropy(weight=...)``); a batch with every pixel ignored gives
0 (with a gradient of 0), never NaN.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import torch
from torch import nn

from gaitnet.errors import ConfigError, InputError

__all__ = ["FocalLoss"]


class FocalLoss(nn.Module):
    """``FocalLoss(alpha, gamma, ignore_index, reduction)(logits (B, C, H, W), target (B, H, W)
    int64)`` → scalar."""

    def __init__(
        self,
        alpha: Sequence[float] | None = None,
        gamma: float = 2.0,
        ignore_index: int = 255,
        reduction: str = "mean",
    ) -> None:
        super().__init__()
        if alpha is not None:
            values = list(alpha)
            if not values or not all(
                isinstance(a, (int, float)) and not isinstance(a, bool) and math.isfinite(a)
                for a in values
            ):
                raise ConfigError(
                    f"focal loss alpha must be a list of finite numbers, got {alpha!r}"
                )
            if any(a < 0 for a in values):
                raise ConfigError(f"focal loss alpha must not be negative, got {values}")
            self.register_buffer("alpha", torch.tensor(values, dtype=torch.float32))
        else:
            self.alpha = None
        if isinstance(gamma, bool) or not isinstance(gamma, (int, float)) or not gamma >= 0:
            raise ConfigError(f"focal loss gamma must be a number ≥ 0, got {gamma!r}")
        if not math.isfinite(gamma):
            raise ConfigError(f"focal loss gamma must be finite, got {gamma!r}")
        if reduction not in ("mean", "sum"):
            raise ConfigError(f"focal loss reduction must be 'mean' or 'sum', got {reduction!r}")
        self.gamma = float(gamma)
        self.ignore_index = int(ignore_index)
        self.reduction = reduction

    def forward(self, logits: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
        if logits.ndim != 4 or target.shape != (logits.shape[0], *logits.shape[2:]):
            raise InputError(
                f"focal loss: logits (B, C, H, W) and target (B, H, W) expected, got "
                f"{tuple(logits.shape)} and {tuple(target.shape)}"
            )
        if target.dtype != torch.int64:
            raise InputError(f"focal loss: target must be int64 class labels, got {target.dtype}")
        n_classes = logits.shape[1]
        if self.alpha is not None and self.alpha.numel() != n_classes:
            raise ConfigError(
                f"focal loss alpha has {self.alpha.numel()} values for {n_classes} classes"
            )
        valid = target != self.ignore_index
        labels = torch.where(valid, target, torch.zeros_like(target))
        if bool(((labels < 0) | (labels >= n_classes)).any()):
            bad = int(labels[(labels < 0) | (labels >= n_classes)][0])
            raise InputError(
                f"focal loss: target holds label {bad}, outside [0, {n_classes}) and not the "
                f"ignore index {self.ignore_index}"
            )
        logp = torch.log_softmax(logits, dim=1)
        logp_t = logp.gather(1, labels.unsqueeze(1)).squeeze(1)  # log p_t, (B, H, W)
        loss = -logp_t
        if self.gamma != 0.0:
            # 1 - p_t without cancellation; clamped so (1 - p_t)^gamma has a finite gradient
            one_minus = (-torch.expm1(logp_t)).clamp(min=torch.finfo(logp_t.dtype).tiny)
            loss = loss * one_minus.pow(self.gamma)
        if self.alpha is not None:
            loss = loss * self.alpha.to(loss.dtype)[labels]
        loss = torch.where(valid, loss, torch.zeros_like(loss))
        total = loss.sum()
        if self.reduction == "sum":
            return total
        return total / valid.sum().clamp(min=1)
