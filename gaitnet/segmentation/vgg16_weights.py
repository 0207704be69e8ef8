"""torchvision's ImageNet VGG16 weights from a LOCAL file as the start of the FCN-8s streams.

The FCN authors started both streams of their RGB-HHA net from ImageNet VGG16: the conv layers
copied, ``fc6``/``fc7`` from the classifier's first two linear layers reshaped into
convolutions. :func:`read_vgg16_weights` reads a torchvision VGG16 state-dict file (e.g.
``vgg16-397923af.pth``) with ``torch.load(..., weights_only=True)`` and checks it key by key
against ``torchvision.models.vgg16``; nothing is ever downloaded. :func:`load_vgg16_weights`
copies it into every stream of a width-1 :class:`~gaitnet.segmentation.segmenter_net.SegmenterNet`.
"""

from __future__ import annotations

import pickle
import re
import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

import torch
import torchvision

from gaitnet.errors import ConfigError, InputError, one_line

if TYPE_CHECKING:
    from gaitnet.segmentation.segmenter_net import SegmenterNet

__all__ = ["load_vgg16_weights", "read_vgg16_weights"]


def _vgg16_reference_shapes() -> dict[str, torch.Size]:
    """Parameter shapes of ``torchvision.models.vgg16`` (built on the meta device: no memory,
    no download)."""
    with torch.device("meta"):
        ref = torchvision.models.vgg16(weights=None)
    return {k: v.shape for k, v in ref.state_dict().items()}


def read_vgg16_weights(path: str | Path) -> dict[str, torch.Tensor]:
    """A local torchvision VGG16 ImageNet state dict (``torch.load(..., weights_only=True)``),
    checked key by key against ``torchvision.models.vgg16``'s shapes; a missing, unreadable,
    pickled or foreign file is a one-line :class:`~gaitnet.errors.InputError`."""
    path = Path(path)
    if path.is_dir():
        raise InputError(f"VGG16 weights {path} is a folder, expected a .pth file")
    if not path.is_file():
        raise InputError(f"VGG16 weights {path} does not exist (give a local file; gaitnet "
                         "never downloads weights)")  # fmt: skip
    try:
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message="Detected pickle protocol")
            state = torch.load(path, map_location="cpu", weights_only=True)
    except pickle.UnpicklingError as exc:
        if re.search(r"GLOBAL|global", str(exc)):
            raise InputError(
                f"VGG16 weights {path} refused: it holds pickled Python objects, not only "
                "tensors (loaded with weights_only=True)"
            ) from exc
        raise InputError(f"VGG16 weights {path} cannot be read (not a torch file)") from exc
    except Exception as exc:  # truncated or foreign files raise many kinds
        raise InputError(
            f"VGG16 weights {path} cannot be read ({one_line(exc, limit=200)})"
        ) from exc
    if isinstance(state, Mapping) and isinstance(state.get("state_dict"), Mapping):
        state = state["state_dict"]
    if not isinstance(state, Mapping):
        raise InputError(f"VGG16 weights {path} holds a {type(state).__name__}, not a state dict")
    expected = _vgg16_reference_shapes()
    for key, shape in expected.items():
        value = state.get(key)
        if not isinstance(value, torch.Tensor) or value.shape != shape:
            found = "missing" if value is None else getattr(value, "shape", type(value).__name__)
            raise InputError(
                f"VGG16 weights {path}: not a torchvision vgg16 state dict (key {key!r}: "
                f"expected {tuple(shape)}, found {found})"
            )
        if not value.is_floating_point() or not torch.isfinite(value).all():
            raise InputError(f"VGG16 weights {path}: key {key!r} is not finite floating point")
    return {k: state[k].to(torch.float32) for k in expected}


def load_vgg16_weights(net: SegmenterNet, state: Mapping[str, torch.Tensor]) -> None:
    """Initialise every stream of ``net`` (width 1.0) from a VGG16 state dict
    (:func:`read_vgg16_weights`): ``features.*`` into the VGG layers, ``classifier.0``
    (25088 → 4096) reshaped to ``fc6`` (4096, 512, 7, 7), ``classifier.3`` to ``fc7``
    (4096, 4096, 1, 1), as the FCN authors did. Score and upsampling layers keep their FCN
    initialisation."""
    if net.width != 1.0:
        raise ConfigError(
            f"VGG16 weights fit only the published width 1.0, the model has width {net.width:g}"
        )
    features = {k[len("features.") :]: v for k, v in state.items() if k.startswith("features.")}
    for stream in (net.rgb, net.hha):
        if stream is None:
            continue
        stream.features.load_state_dict(features)
        with torch.no_grad():
            stream.fc6.weight.copy_(state["classifier.0.weight"].view(stream.fc6.weight.shape))
            stream.fc6.bias.copy_(state["classifier.0.bias"])
            stream.fc7.weight.copy_(state["classifier.3.weight"].view(stream.fc7.weight.shape))
            stream.fc7.bias.copy_(state["classifier.3.bias"])
