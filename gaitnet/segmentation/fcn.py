"""FCN-8s on torchvision's VGG16, one stream of the segmenter (thesis sec. 4.1;
:mod:`gaitnet.segmentation.segmenter_net` combines the streams).

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
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import torch
from torch import nn
from torchvision.models import vgg as tv_vgg

from gaitnet.errors import ConfigError

__all__ = [
    "OUTPUT_STRIDES",
    "PADDINGS",
    "FCN8s",
    "bilinear_kernel",
    "check_output_stride",
    "check_padding",
    "fcn8s_parameter_count",
    "scaled_channels",
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
        self.padding = check_padding(padding)
        self.output_stride = check_output_stride(output_stride)
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


def check_output_stride(stride: Any, name: str = "segmenter output_stride") -> int:
    """``stride`` as an int of :data:`OUTPUT_STRIDES`, or a ConfigError naming ``name``."""
    if isinstance(stride, bool) or stride not in OUTPUT_STRIDES:
        raise ConfigError(f"{name} must be one of {list(OUTPUT_STRIDES)}, got {stride!r}")
    return int(stride)


def check_padding(padding: Any) -> str:
    """``padding`` if it is one of :data:`PADDINGS`, else a ConfigError."""
    if padding not in PADDINGS:
        raise ConfigError(f"segmenter padding must be one of {list(PADDINGS)}, got {padding!r}")
    return padding
