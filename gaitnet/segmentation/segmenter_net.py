"""The RGB / HHA / RGB+HHA late-fusion segmenter (thesis sec. 4.1) on the FCN-8s streams of
:mod:`gaitnet.segmentation.fcn`.

:class:`SegmenterNet` wraps one stream (``arch`` "rgb" or "hha") or two (``"fusion"``: the
RGB and HHA streams' class score maps are summed, the thesis's late fusion, trained jointly).
It takes channels in [0, 1] (RGB/255, HHA/255, or both concatenated), normalises them itself
(ImageNet mean/std for RGB, :data:`HHA_MEAN` / :data:`HHA_STD` for HHA), resizes the input by
``input_scale`` before the streams (bilinear, no antialiasing, so the ONNX graph matches) and
returns logits at the input size.

``logit_bias`` (one number per class, zeros by default) is added to the logits last. A net
trained with class-weighted focal loss over-predicts the up-weighted classes (the foot's alpha
is 4× the background's); :mod:`gaitnet.training.calibration` picks the bias that maximises
the mean IoU on a validation set after training, and the checkpoint and the ONNX graph carry it.

:func:`build_segmenter` can start both streams from torchvision's ImageNet VGG16 weights given
as a LOCAL state-dict file (:mod:`gaitnet.segmentation.vgg16_weights`; nothing is downloaded).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import torch
from torch import nn
from torch.nn import functional as nnf

from gaitnet.errors import ConfigError, InputError, one_line
from gaitnet.segmentation.channels import (
    HHA_MEAN,
    HHA_STD,
    RGB_MEAN,
    RGB_STD,
    check_arch,
    input_channels,
)
from gaitnet.segmentation.fcn import FCN8s, check_output_stride, check_padding
from gaitnet.segmentation.vgg16_weights import load_vgg16_weights, read_vgg16_weights

__all__ = [
    "SegmenterNet",
    "build_segmenter",
    "check_logit_bias",
    "model_input",
    "segmenter_from_checkpoint",
]


class SegmenterNet(nn.Module):
    """RGB, HHA or late-fusion RGB+HHA FCN-8s (thesis sec. 4.1).

    ``forward(x)``: ``x`` (B, C, H, W) float32 in [0, 1], ``C = input_channels(arch)`` (RGB/255,
    HHA/255, or RGB/255 then HHA/255) → logits (B, num_classes, H, W). Fusion sums the streams'
    score maps. With ``input_scale < 1`` the streams see the input resized by that factor and
    the logits are upsampled (bilinear) back to H × W. ``logit_bias`` (num_classes numbers) is
    added to the logits last (module docstring).
    """

    def __init__(
        self,
        arch: str,
        width: float = 1.0,
        num_classes: int = 3,
        input_scale: float = 1.0,
        padding: str = "published",
        output_stride: int = 8,
        logit_bias: Sequence[float] | None = None,
    ) -> None:
        super().__init__()
        self.arch = check_arch(arch)
        self.padding = check_padding(padding)
        self.output_stride = check_output_stride(output_stride)
        self.width = _check_real("segmenter width", width, 0.0, 1.0, open_lo=True)
        self.input_scale = _check_real("segmenter input_scale", input_scale, 0.0, 1.0, True)
        if isinstance(num_classes, bool) or not isinstance(num_classes, int) or num_classes < 2:
            raise ConfigError(f"segmenter num_classes must be an integer ≥ 2, got {num_classes!r}")
        self.num_classes = num_classes
        streams = ("rgb", "fusion"), ("hha", "fusion")
        geometry = {"padding": padding, "output_stride": output_stride}
        self.rgb = FCN8s(num_classes, width, **geometry) if arch in streams[0] else None
        self.hha = FCN8s(num_classes, width, **geometry) if arch in streams[1] else None
        mean = (RGB_MEAN if self.rgb else ()) + (HHA_MEAN if self.hha else ())
        std = (RGB_STD if self.rgb else ()) + (HHA_STD if self.hha else ())
        # Constants of the architecture, not learned state: kept out of state dicts.
        self.register_buffer("mean", torch.tensor(mean).view(1, -1, 1, 1), persistent=False)
        self.register_buffer("std", torch.tensor(std).view(1, -1, 1, 1), persistent=False)
        bias = check_logit_bias(logit_bias, num_classes)
        self.register_buffer("bias", torch.tensor(bias).view(1, -1, 1, 1), persistent=False)
        self.logit_bias = bias

    @property
    def in_channels(self) -> int:
        return input_channels(self.arch)

    def config(self) -> dict[str, Any]:
        """The keys :func:`segmenter_from_checkpoint` reads (``config["model"]``)."""
        return {
            "arch": self.arch,
            "width": self.width,
            "num_classes": self.num_classes,
            "input_scale": self.input_scale,
            "padding": self.padding,
            "output_stride": self.output_stride,
            "logit_bias": list(self.logit_bias),
        }

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        height, width = x.shape[2], x.shape[3]
        h = x
        if self.input_scale != 1.0:
            size = (
                max(1, round(height * self.input_scale)),
                max(1, round(width * self.input_scale)),
            )
            h = nnf.interpolate(h, size=size, mode="bilinear", align_corners=False, antialias=False)
        # After the resize (bilinear weights sum to 1, so the order does not matter): fewer pixels.
        h = (h - self.mean) / self.std
        if self.rgb is not None and self.hha is not None:
            score = self.rgb(h[:, :3]) + self.hha(h[:, 3:])  # late fusion: summed score maps
        else:
            stream = self.rgb if self.rgb is not None else self.hha
            assert stream is not None
            score = stream(h)
        if self.input_scale != 1.0:
            score = nnf.interpolate(
                score, size=(height, width), mode="bilinear", align_corners=False, antialias=False
            )
        if any(self.logit_bias):
            score = score + self.bias
        return score


def check_logit_bias(
    bias: Any, num_classes: int, name: str = "segmenter logit_bias"
) -> tuple[float, ...]:
    """``bias`` as a tuple of ``num_classes`` finite floats (zeros for None), or a ConfigError
    naming ``name``."""
    if bias is None:
        return (0.0,) * num_classes
    ok = (
        isinstance(bias, (list, tuple))
        and len(bias) == num_classes
        and all(
            isinstance(b, (int, float)) and not isinstance(b, bool) and math.isfinite(b)
            for b in bias
        )
    )
    if not ok:
        raise ConfigError(
            f"{name} must be null or a list of {num_classes} finite numbers "
            f"(one per class), got {bias!r}"
        )
    return tuple(float(b) for b in bias)


def _check_real(name: str, value: Any, lo: float, hi: float, open_lo: bool) -> float:
    ok = (
        isinstance(value, (int, float))
        and not isinstance(value, bool)
        and math.isfinite(value)
        and (value > lo if open_lo else value >= lo)
        and value <= hi
    )
    if not ok:
        left = "(" if open_lo else "["
        raise ConfigError(f"{name} must be a number in {left}{lo:g}, {hi:g}], got {value!r}")
    return float(value)


def model_input(
    arch: str, rgb: torch.Tensor | None = None, hha: torch.Tensor | None = None
) -> torch.Tensor:
    """The network input of ``arch`` from (B, 3, H, W) RGB/255 and HHA/255 tensors: ``rgb``,
    ``hha`` or both concatenated along channels (RGB first)."""
    check_arch(arch)
    if arch in ("rgb", "fusion") and rgb is None:
        raise InputError(f"segmenter arch {arch!r} needs an RGB input")
    if arch in ("hha", "fusion") and hha is None:
        raise InputError(f"segmenter arch {arch!r} needs an HHA input")
    if arch == "rgb":
        return rgb  # type: ignore[return-value]
    if arch == "hha":
        return hha  # type: ignore[return-value]
    return torch.cat([rgb, hha], dim=1)  # type: ignore[list-item]


def build_segmenter(
    arch: str,
    width: float = 1.0,
    num_classes: int = 3,
    input_scale: float = 1.0,
    vgg16_weights: str | Path | None = None,
    padding: str = "published",
    output_stride: int = 8,
    logit_bias: Sequence[float] | None = None,
) -> SegmenterNet:
    """A :class:`SegmenterNet`, optionally started from local ImageNet VGG16 weights
    (:func:`gaitnet.segmentation.vgg16_weights.read_vgg16_weights`, read before the net is
    built; ``width`` must then be 1.0)."""
    if vgg16_weights is not None and width != 1.0:
        raise ConfigError(
            f"VGG16 weights {vgg16_weights}: ImageNet weights fit only the published width "
            f"1.0, not width {width!r}"
        )
    state = None if vgg16_weights is None else read_vgg16_weights(vgg16_weights)
    net = SegmenterNet(
        arch,
        width=width,
        num_classes=num_classes,
        input_scale=input_scale,
        padding=padding,
        output_stride=output_stride,
        logit_bias=logit_bias,
    )
    if state is not None:
        load_vgg16_weights(net, state)
    return net


def segmenter_from_checkpoint(ckpt: Mapping[str, Any], source: str = "checkpoint") -> SegmenterNet:
    """The trained :class:`SegmenterNet` of a checkpoint dict written by
    ``train/segmenter.py``: ``ckpt["config"]["model"]`` gives ``arch``, ``width``,
    ``num_classes``, ``input_scale``, ``padding`` ("published" when absent: checkpoints from
    before the option), ``output_stride`` (8 when absent) and ``logit_bias`` (zeros when absent
    or null); ``ckpt["model"]`` the state dict. ``source`` (the file) names the checkpoint in
    errors. Returned in eval mode on the CPU."""
    if not isinstance(ckpt, Mapping):
        raise InputError(f"{source}: not a checkpoint dict")
    config = ckpt.get("config")
    model_cfg = config.get("model") if isinstance(config, Mapping) else None
    if not isinstance(model_cfg, Mapping):
        raise InputError(f"{source}: lacks the mapping config.model (a segmenter checkpoint?)")
    missing = [k for k in ("arch", "width", "num_classes", "input_scale") if k not in model_cfg]
    if missing:
        raise InputError(f"{source}: config.model lacks key(s) {missing}")
    try:
        net = SegmenterNet(
            model_cfg["arch"],
            width=model_cfg["width"],
            num_classes=model_cfg["num_classes"],
            input_scale=model_cfg["input_scale"],
            padding=model_cfg.get("padding", "published"),
            output_stride=model_cfg.get("output_stride", 8),
            logit_bias=model_cfg.get("logit_bias"),
        )
    except ConfigError as exc:
        raise InputError(f"{source}: config.model: {exc}") from exc
    state = ckpt.get("model")
    if not isinstance(state, Mapping):
        raise InputError(f"{source}: key 'model' must be a state dict")
    try:
        net.load_state_dict(state)
    except (RuntimeError, ValueError, KeyError, TypeError) as exc:
        raise InputError(
            f"{source}: its model state does not fit config.model ({one_line(exc, limit=300)})"
        ) from exc
    return net.eval()
