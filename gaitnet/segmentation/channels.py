"""The segmenter's input channels per architecture and their normalisation constants.

Kept apart from :mod:`gaitnet.segmentation.fcn` (which needs PyTorch) so that running an
exported model (:mod:`gaitnet.segmentation.onnx_runtime`, ``gaitnet infer``) does not import
PyTorch: about 2 s of start-up.
"""

from __future__ import annotations

from typing import Any

from gaitnet.errors import ConfigError

__all__ = ["ARCHS", "HHA_MEAN", "HHA_STD", "RGB_MEAN", "RGB_STD", "check_arch", "input_channels"]

ARCHS = ("rgb", "hha", "fusion")

#: ImageNet statistics torchvision's VGG16 weights were trained with (channels in [0, 1]).
RGB_MEAN = (0.485, 0.456, 0.406)
RGB_STD = (0.229, 0.224, 0.225)
#: Fixed normalisation of HHA/255: maps [0, 1] to [-2, 2], the spread of normalised RGB.
HHA_MEAN = (0.5, 0.5, 0.5)
HHA_STD = (0.25, 0.25, 0.25)


def check_arch(arch: Any) -> str:
    """``arch`` if it is one of :data:`ARCHS`, else a :class:`~gaitnet.errors.ConfigError`."""
    if arch not in ARCHS:
        raise ConfigError(f"segmenter arch must be one of {list(ARCHS)}, got {arch!r}")
    return arch


def input_channels(arch: str) -> int:
    """Input channels of ``arch``: 3 (rgb), 3 (hha), 6 (fusion: RGB then HHA)."""
    check_arch(arch)
    return 6 if arch == "fusion" else 3
