"""FCN-8s on torchvision's VGG16 and the RGB / HHA / RGB+HHA late-fusion segmenter (thesis
sec. 4.1).

FCN-8s as published (Long, Shelhamer, Darrell, "Fully Convolutional Networks for Semantic
Segmentation", CVPR 2015; reference nets at github.com/shelhamer/fcn.berkeleyvision.org):
torchvision's VGG16 feature layers (``torchvision.models.vgg.make_layers(cfgs["D"])``, the
layers of ``torchvision.models.vgg16``) with ``conv1_1`` padded by 100 and ceil-mode pooling;
``fc6`` as a 7×7 convolution and ``fc7`` as a 1×1 convolution (4096 channels, ReLU, dropout
0.5); class score layers on ``fc7`` (``score_fr``), ``pool4`` and ``pool3``; transposed
convolutions ``upscore2`` (×2), ``upscore_pool4`` (×2) and ``upscore8`` (×8) initialised to
bilinear interpolation (the last one stays fixed, the other two learn, as in the reference
nets); the published crops 5 (pool4), 9 (pool3) and 31 (output), which make the output exactly
the input's size for any input size. Score layers start at zero, as in the reference nets.

``width`` scales every channel count (``max(1, round(c * width))``): 1.0 is the published net
(for GPUs), 1/8 or 1/16 make CPU-sized variants.

``padding`` "published" is the reference net's geometry above: ``conv1_1`` padded by 100 and an
unpadded 7×7 ``fc6``, so every layer works on the input plus a 100-pixel border (a 320×240
input is 520×440 at ``conv1_1``: 3× its pixels). "same" pads ``conv1_1`` by 1 (as in VGG16)
and ``fc6`` by 3, so the layers see only the input; the score maps are then aligned by the
offsets 1 (into ``upscore2``), 1 (into ``upscore_pool4``) and 4 (output), found like the
published ones by following each layer's map from its index to input pixels (a 3×3 conv with
padding 1 keeps the centre, a 2×2 pool of stride 2 maps ``i`` to ``2i + ½``, a transposed conv
of stride ``s`` and size ``2s`` maps ``j`` to ``(j − s + ½) / s``): the same algebra gives 5,
9, 31 for the published padding. Same parameters, about a third of the computation.

``output_stride`` 8 is FCN-8s. 4 and 2 (beyond the paper) take its pattern one and two steps
further: a ×2 upsampling of the fused 1/8 map summed with a score layer on ``pool2``, then
(for 2) on ``pool1``, before a final ×4 or ×2 bilinear upsampling, so a boundary is blurred
over 4 or 2 input pixels instead of 8. The same algebra gives the offsets: ``same`` 1 into
each upsampled map and output crops 2 (stride 4) and 1 (stride 2); ``published`` 17 (pool2)
and 33 (pool1) into the score maps and output crops 33 and 34.

:class:`SegmenterNet` wraps one stream (``arch`` "rgb" or "hha") or two (``"fusion"``: the
RGB and HHA streams' class score maps are summed, the thesis's late fusion, trained jointly).
It takes channels in [0, 1] (RGB/255, HHA/255, or both concatenated), normalises them itself
(ImageNet mean/std for RGB, :data:`HHA_MEAN` / :data:`HHA_STD` for HHA), resizes the input by
``input_scale`` before the streams (bilinear, no antialiasing, so the ONNX graph matches) and
returns logits at the input size.

:func:`build_segmenter` can start both streams from torchvision's ImageNet VGG16 weights given
as a LOCAL state-dict file (:mod:`gaitnet.segmentation.vgg16_weights`; nothing is downloaded).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import torch
from torch import nn
from torch.nn import functional as nnf
from torchvision.models import vgg as tv_vgg

from gaitnet.errors import ConfigError, InputError, one_line
from gaitnet.segmentation.channels import (
    ARCHS,
    HHA_MEAN,
    HHA_STD,
    RGB_MEAN,
    RGB_STD,
    check_arch,
    input_channels,
)
from gaitnet.segmentation.vgg16_weights import load_vgg16_weights, read_vgg16_weights

__all__ = [
    "ARCHS",
    "HHA_MEAN",
    "HHA_STD",
    "RGB_MEAN",
    "RGB_STD",
    "OUTPUT_STRIDES",
    "PADDINGS",
    "FCN8s",
    "SegmenterNet",
    "bilinear_kernel",
    "build_segmenter",
    "fcn8s_parameter_count",
    "input_channels",
    "model_input",
    "scaled_channels",
    "segmenter_from_checkpoint",
]

#: torchvision's VGG16 layer list ("D": channels, "M" = 2×2 max pooling).
VGG16_CFG: tuple[int | str, ...] = tuple(tv_vgg.cfgs["D"])
FC_CHANNELS = 4096
#: The published crops (offsets into the larger map) of FCN-8s.
CROP_POOL4, CROP_POOL3, CROP_OUT = 5, 9, 31
#: ``padding`` choices (module docstring).
PADDINGS = ("published", "same")
#: ``output_stride`` choices: 8 is the published FCN-8s; 4 and 2 add skips from pool2 and pool1.
OUTPUT_STRIDES = (8, 4, 2)
#: The pools whose score maps are fused, coarsest first, down to each output stride.
_SKIPS: dict[int, tuple[str, ...]] = {
    8: ("pool4", "pool3"),
    4: ("pool4", "pool3", "pool2"),
    2: ("pool4", "pool3", "pool2", "pool1"),
}
#: The final upsampling layer's name per output stride (``upscore8`` in the reference net).
_OUT_LAYER = {8: "upscore8", 4: "upscore4", 2: "upscore_out"}


@dataclass(frozen=True)
class _Geometry:
    """Offsets of one padding (module docstring): ``fuse[pool]`` = (offset into the upsampled
    map, offset into ``score_<pool>``); ``crop[stride]`` = the output crop."""

    conv1_pad: int
    fc6_pad: int
    fuse: dict[str, tuple[int, int]]
    crop: dict[int, int]


_GEOMETRY: dict[str, _Geometry] = {
    "published": _Geometry(
        100,
        0,
        {"pool4": (0, CROP_POOL4), "pool3": (0, CROP_POOL3), "pool2": (0, 17), "pool1": (0, 33)},
        {8: CROP_OUT, 4: 33, 2: 34},
    ),
    "same": _Geometry(
        1,
        3,
        {"pool4": (1, 0), "pool3": (1, 0), "pool2": (1, 0), "pool1": (1, 0)},
        {8: 4, 4: 2, 2: 1},
    ),
}


def scaled_channels(channels: int, width: float) -> int:
    """``max(1, round(channels * width))``: a channel count of the width-scaled net."""
    return max(1, int(round(channels * width)))


def bilinear_kernel(size: int) -> torch.Tensor:
    """The (size, size) bilinear interpolation kernel of an upsampling by ``(size + 1) // 2``
    (the FCN reference ``surgery.upsample_filt``)."""
    factor = (size + 1) // 2
    center = factor - 1 if size % 2 == 1 else factor - 0.5
    r = torch.arange(size, dtype=torch.float64)
    f = 1 - torch.abs(r - center) / factor
    return torch.outer(f, f).to(torch.float32)


def _bilinear_init(layer: nn.ConvTranspose2d) -> None:
    """Each class channel upsampled on its own by bilinear interpolation."""
    c_in, c_out, kh, kw = layer.weight.shape
    assert c_in == c_out and kh == kw
    with torch.no_grad():
        layer.weight.zero_()
        kernel = bilinear_kernel(kh)
        for c in range(c_in):
            layer.weight[c, c] = kernel


#: VGG16 output channels at each pool (before width scaling).
_POOL_CHANNELS = {"pool1": 64, "pool2": 128, "pool3": 256, "pool4": 512}


def fcn8s_parameter_count(
    num_classes: int, width: float = 1.0, in_channels: int = 3, output_stride: int = 8
) -> int:
    """Parameters of one FCN stream, counted from the layer list (weights + biases)."""
    total, c_prev = 0, in_channels
    for v in VGG16_CFG:
        if v == "M":
            continue
        c = scaled_channels(int(v), width)
        total += c_prev * c * 9 + c
        c_prev = c
    fc = scaled_channels(FC_CHANNELS, width)
    n = num_classes
    total += c_prev * fc * 49 + fc  # fc6
    total += fc * fc + fc  # fc7
    total += (fc + 1) * n  # score_fr
    for pool in _SKIPS[output_stride]:  # score_pool4, score_pool3, ...
        total += (scaled_channels(_POOL_CHANNELS[pool], width) + 1) * n
    # upscore2, upscore_pool4, ... (×2 each, no bias), then the final ×output_stride
    total += n * n * (4 * 4 * len(_SKIPS[output_stride]) + (2 * output_stride) ** 2)
    return total


class FCN8s(nn.Module):
    """One FCN-8s stream (3 input channels, already normalised) → class scores at input size.

    ``features`` is torchvision's VGG16 feature stack (``conv1_1`` … ``pool5``, channel counts
    scaled by ``width``); spatial scales below are relative to the padded input.
    ``output_stride`` 8 is the published FCN-8s; 4 and 2 continue its pattern one and two
    steps further, as the FCN authors went from FCN-32s to 16s to 8s: the fused 1/8 map is
    upsampled ×2 (``upscore_pool3``, learned, bilinear start) and summed with a zero-started
    score layer on ``pool2`` (``score_pool2``), and for 2 once more with ``pool1``; the final
    fixed bilinear upsampling is then ×4 (``upscore4``) or ×2 (``upscore_out``).
    """

    def __init__(
        self,
        num_classes: int = 3,
        width: float = 1.0,
        in_channels: int = 3,
        dropout: float = 0.5,
        padding: str = "published",
        output_stride: int = 8,
    ) -> None:
        super().__init__()
        self.padding = _check_padding(padding)
        self.output_stride = _check_output_stride(output_stride)
        geometry = _GEOMETRY[padding]
        cfg = [v if v == "M" else scaled_channels(int(v), width) for v in VGG16_CFG]
        self.features = tv_vgg.make_layers(cfg)
        first = self.features[0]
        assert isinstance(first, nn.Conv2d)
        if in_channels != 3:
            self.features[0] = first = nn.Conv2d(in_channels, first.out_channels, 3)
        first.padding = (geometry.conv1_pad, geometry.conv1_pad)  # 100 in the published net
        pools = [i for i, m in enumerate(self.features) if isinstance(m, nn.MaxPool2d)]
        for i in pools:
            self.features[i].ceil_mode = True
        self._skips = _SKIPS[output_stride]
        self._pool_at = {pools[int(name[-1]) - 1]: name for name in self._skips}
        self._fuse_offsets = [geometry.fuse[name] for name in self._skips]
        self._crop = geometry.crop[output_stride]
        c5 = scaled_channels(512, width)
        fc = scaled_channels(FC_CHANNELS, width)
        self.fc6 = nn.Conv2d(c5, fc, 7, padding=geometry.fc6_pad)  # 1/32
        self.relu6 = nn.ReLU(inplace=True)
        self.drop6 = nn.Dropout(dropout)
        self.fc7 = nn.Conv2d(fc, fc, 1)
        self.relu7 = nn.ReLU(inplace=True)
        self.drop7 = nn.Dropout(dropout)
        self.score_fr = nn.Conv2d(fc, num_classes, 1)
        n = num_classes
        # score_pool4, score_pool3 [, score_pool2 [, score_pool1]]
        for name in self._skips:
            c = scaled_channels(_POOL_CHANNELS[name], width)
            setattr(self, f"score_{name}", nn.Conv2d(c, n, 1))
        # upscore2 (after score_fr), upscore_pool4 [, upscore_pool3 [, upscore_pool2]]: ×2 each
        self._up_names = ["upscore2", *(f"upscore_{name}" for name in self._skips[:-1])]
        for name in self._up_names:
            setattr(self, name, nn.ConvTranspose2d(n, n, 4, stride=2, bias=False))
        self._out_name = _OUT_LAYER[output_stride]
        s = output_stride
        setattr(self, self._out_name, nn.ConvTranspose2d(n, n, 2 * s, stride=s, bias=False))
        self.num_classes = num_classes
        self.width = width
        self.reset_parameters()

    def reset_parameters(self) -> None:
        """VGG convs and fc6/fc7 as torchvision initialises VGG convs (He, fan-out); score
        layers zero; transposed convs bilinear, the final one (``upscore8``) fixed."""
        for m in [*self.features, self.fc6, self.fc7]:
            if isinstance(m, nn.Conv2d):
                nn.init.kaiming_normal_(m.weight, mode="fan_out", nonlinearity="relu")
                nn.init.zeros_(m.bias)
        for name in ("score_fr", *(f"score_{p}" for p in self._skips)):
            layer = getattr(self, name)
            nn.init.zeros_(layer.weight)
            nn.init.zeros_(layer.bias)
        for name in (*self._up_names, self._out_name):
            _bilinear_init(getattr(self, name))
        getattr(self, self._out_name).weight.requires_grad_(False)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """(B, 3, H, W) normalised → (B, num_classes, H, W) class scores."""
        h = x
        pooled: dict[str, torch.Tensor] = {}
        for i, layer in enumerate(self.features):
            h = layer(h)
            if i in self._pool_at:
                pooled[self._pool_at[i]] = h  # pool4 1/16, pool3 1/8, pool2 1/4, pool1 1/2
        h = self.drop6(self.relu6(self.fc6(h)))  # 1/32
        h = self.drop7(self.relu7(self.fc7(h)))
        score = self.score_fr(h)
        for up, name, offsets in zip(self._up_names, self._skips, self._fuse_offsets, strict=True):
            skip = getattr(self, f"score_{name}")(pooled[name])
            score = _fuse(getattr(self, up)(score), skip, offsets)  # 1/16, 1/8, ...
        out = getattr(self, self._out_name)(score)  # 1/1
        c = self._crop
        return out[:, :, c : c + x.shape[2], c : c + x.shape[3]]


def _fuse(up: torch.Tensor, skip: torch.Tensor, offsets: tuple[int, int]) -> torch.Tensor:
    """``up + skip`` on their overlap once ``up`` is shifted by ``offsets[0]`` and ``skip`` by
    ``offsets[1]`` (the aligned crops of the module docstring)."""
    a, b = offsets
    h = min(up.shape[2] - a, skip.shape[2] - b)
    w = min(up.shape[3] - a, skip.shape[3] - b)
    return up[:, :, a : a + h, a : a + w] + skip[:, :, b : b + h, b : b + w]


def _check_output_stride(stride: Any) -> int:
    if isinstance(stride, bool) or stride not in OUTPUT_STRIDES:
        raise ConfigError(
            f"segmenter output_stride must be one of {list(OUTPUT_STRIDES)}, got {stride!r}"
        )
    return int(stride)


def _check_padding(padding: Any) -> str:
    if padding not in PADDINGS:
        raise ConfigError(f"segmenter padding must be one of {list(PADDINGS)}, got {padding!r}")
    return padding


class SegmenterNet(nn.Module):
    """RGB, HHA or late-fusion RGB+HHA FCN-8s (thesis sec. 4.1).

    ``forward(x)``: ``x`` (B, C, H, W) float32 in [0, 1], ``C = input_channels(arch)`` (RGB/255,
    HHA/255, or RGB/255 then HHA/255) → logits (B, num_classes, H, W). Fusion sums the streams'
    score maps. With ``input_scale < 1`` the streams see the input resized by that factor and
    the logits are upsampled (bilinear) back to H × W.
    """

    def __init__(
        self,
        arch: str,
        width: float = 1.0,
        num_classes: int = 3,
        input_scale: float = 1.0,
        padding: str = "published",
        output_stride: int = 8,
    ) -> None:
        super().__init__()
        self.arch = check_arch(arch)
        self.padding = _check_padding(padding)
        self.output_stride = _check_output_stride(output_stride)
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
        return score


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
    )
    if state is not None:
        load_vgg16_weights(net, state)
    return net


def segmenter_from_checkpoint(ckpt: Mapping[str, Any], source: str = "checkpoint") -> SegmenterNet:
    """The trained :class:`SegmenterNet` of a checkpoint dict written by
    ``train/segmenter.py``: ``ckpt["config"]["model"]`` gives ``arch``, ``width``,
    ``num_classes``, ``input_scale``, ``padding`` ("published" when absent: checkpoints from
    before the option) and ``output_stride`` (8 when absent); ``ckpt["model"]`` the state dict. ``source`` (the file)
    names the checkpoint in errors. Returned in eval mode on the CPU."""
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
