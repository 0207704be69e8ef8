"""A segmenter's PyTorch weights read back from its own ONNX export (``model.init_checkpoint:
models/segmenter/fcn8s_fusion_small.onnx``): fine-tuning the committed model needs no separate
checkpoint.

``export/to_onnx.py`` stores every weight of the net as a graph initializer and every layer's
module path in its nodes' ``pkg.torch.onnx.name_scopes`` metadata (a convolution whose bias is
all zeros is exported without one: its bias is zeros again); the architecture is in the
model's ``gaitnet.*`` metadata (:mod:`gaitnet.segmentation.onnx_runtime`). Each ``Conv`` and
``ConvTranspose`` node therefore names its module, and its weight and bias inputs are that
module's tensors (the exporter shares one initializer between modules whose tensors are
equal, e.g. two fixed bilinear upsampling kernels, so the node's input is followed, not the
initializer's name). The net is rebuilt, filled, and checked against onnxruntime on the same
input before it is returned: a graph this reading misunderstands is refused, never trained on.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import torch

from gaitnet.errors import InputError
from gaitnet.io.onnx_session import open_session
from gaitnet.segmentation.segmenter_net import SegmenterNet, segmenter_from_checkpoint

__all__ = ["PARITY_ATOL", "segmenter_from_onnx"]

PARITY_ATOL = 1e-3
"""Largest logit difference between the rebuilt net and onnxruntime that is accepted."""

_LAYER_OPS = ("Conv", "ConvTranspose")
_SCOPES_KEY = "pkg.torch.onnx.name_scopes"


def _architecture(meta: dict[str, str], source: str) -> dict:
    """``config.model`` of a checkpoint, from the ONNX file's ``gaitnet.*`` metadata."""
    if meta.get("gaitnet.model") != "segmenter":
        raise InputError(f"{source}: not a gaitnet segmenter export (no gaitnet.model metadata)")
    try:
        return {
            "arch": meta["gaitnet.arch"],
            "width": float(meta["gaitnet.width"]),
            "num_classes": len(json.loads(meta["gaitnet.classes"])),
            "input_scale": float(meta["gaitnet.input_scale"]),
            "padding": meta.get("gaitnet.padding", "published"),
            "output_stride": int(meta.get("gaitnet.output_stride", 8)),
            "logit_bias": json.loads(meta.get("gaitnet.logit_bias", "null")),
        }
    except (KeyError, ValueError, TypeError) as exc:
        raise InputError(f"{source}: its gaitnet.* metadata is incomplete ({exc})") from None


def _layer_tensors(graph, source: str) -> dict[str, np.ndarray]:
    """Module tensor name → array, from each layer node's scope and inputs."""
    from onnx import numpy_helper

    initializers = {init.name: init for init in graph.initializer}
    state: dict[str, np.ndarray] = {}
    for node in graph.node:
        if node.op_type not in _LAYER_OPS:
            continue
        meta = {p.key: p.value for p in node.metadata_props}
        try:
            module = json.loads(meta[_SCOPES_KEY].replace("'", '"'))[-2]
        except (KeyError, ValueError, IndexError):
            raise InputError(
                f"{source}: node {node.name} has no module scope (not exported by "
                "export/to_onnx.py with this PyTorch?)"
            ) from None
        for role, name in zip(("weight", "bias"), node.input[1:3], strict=False):
            if name not in initializers:
                raise InputError(f"{source}: {module}.{role} is not a constant of the graph")
            state[f"{module}.{role}"] = numpy_helper.to_array(initializers[name])
        if node.op_type == "Conv" and len(node.input) < 3:  # the exporter drops a zero bias
            state[f"{module}.bias"] = np.zeros(state[f"{module}.weight"].shape[0], np.float32)
    return state


def segmenter_from_onnx(path: str | Path) -> SegmenterNet:
    """The :class:`SegmenterNet` of a segmenter ONNX export, in eval mode on the CPU (module
    docstring). :class:`InputError` naming the file when it is not such an export, a tensor is
    missing, or the rebuilt net's logits differ from onnxruntime's by more than
    :data:`PARITY_ATOL`."""
    import onnx

    path = Path(path)
    source = str(path)
    session = open_session(path)  # exists, is ONNX, matches its sidecar's sha256
    model = onnx.load(str(path))
    meta = {p.key: p.value for p in model.metadata_props}
    state = {k: torch.from_numpy(v.copy()) for k, v in _layer_tensors(model.graph, source).items()}
    ckpt = {"config": {"model": _architecture(meta, source)}, "model": state}
    net = segmenter_from_checkpoint(ckpt, source)
    (input_meta,) = session.get_inputs()
    height, width = (d if isinstance(d, int) else 64 for d in input_meta.shape[2:])
    x = torch.rand(
        (1, input_meta.shape[1], height, width), generator=torch.Generator().manual_seed(0)
    )
    with torch.no_grad():
        expected = net(x).numpy()
    (got,) = session.run(None, {input_meta.name: x.numpy()})
    diff = float(np.max(np.abs(got - expected)))
    if not diff <= PARITY_ATOL:
        raise InputError(
            f"{source}: the net rebuilt from its weights differs from onnxruntime by {diff:.3g} "
            f"(more than {PARITY_ATOL:g}): the graph is not one this reader understands"
        )
    return net
