"""ONNX export of the segmenter with a parity check, and its onnxruntime wrapper.

The exported graph is :meth:`gaitnet.segmentation.segmenter_net.SegmenterNet.forward`,
normalisation, ``input_scale`` resizing and ``logit_bias`` included: input ``image`` (batch,
C, H, W) float32 in [0, 1] (C = 3 RGB/255 or HHA/255, or 6: RGB/255 then HHA/255) → output
``logits`` (batch, classes, H, W),
with a dynamic batch and a fixed frame size (640 × 480 by default). The export
(:func:`export_segmenter_onnx`, through :func:`gaitnet.io.onnx_export.export_onnx_checked`) is
refused, and nothing is written, unless onnxruntime reproduces PyTorch within ``atol`` (max
absolute logit difference, default 1e-4) on random inputs; the file is written atomically.
What a runtime must know is stored in the model's ``metadata_props`` (:data:`METADATA_KEYS`):
``gaitnet.model`` = ``segmenter``, the arch, width, input scale, padding, output stride, logit
bias, class names, the input's channels and the normalisation applied inside the graph.

:class:`OnnxSegmenter` runs such a file on explicit providers with a set thread count; frames
of another size than the model's are scaled and windowed
(:mod:`gaitnet.segmentation.frame_windows`); a file that is missing, unreadable or not a gaitnet
segmenter, and an input of the wrong rank, channels or dtype, an empty batch or NaN/inf, are
one-line :class:`~gaitnet.io.onnx_session.OnnxInputError` s (an
:class:`~gaitnet.errors.InputError`) naming the file. Running a model does not import PyTorch
(only the export does). :meth:`OnnxSegmenter.labels` is one frame's label map from its RGB
and HHA: the network's input (:func:`network_input`), its arg-max, and optionally the edge
refinement (:mod:`gaitnet.segmentation.edge_refine`).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import cv2
import numpy as np

from gaitnet.io.onnx_export import ExportReport, OnnxParityError, export_onnx_checked
from gaitnet.io.onnx_session import (
    OnnxInputError,
    check_input,
    model_metadata,
    open_session,
    run_session,
)
from gaitnet.segmentation.channels import (
    ARCHS,
    HHA_MEAN,
    HHA_STD,
    RGB_MEAN,
    RGB_STD,
    input_channels,
)
from gaitnet.segmentation.edge_refine import EdgeRefineParams, argmax_classes, refine_labels
from gaitnet.segmentation.frame_windows import windowed_logits

if TYPE_CHECKING:  # PyTorch is imported only to export (module docstring)
    import torch

    from gaitnet.segmentation.segmenter_net import SegmenterNet

__all__ = [
    "DEFAULT_CLASSES",
    "INPUT_NAME",
    "METADATA_KEYS",
    "OUTPUT_NAME",
    "ExportReport",
    "OnnxInputError",
    "OnnxParityError",
    "OnnxSegmenter",
    "default_classes",
    "export_segmenter_onnx",
    "network_input",
    "segmenter_metadata",
]

INPUT_NAME = "image"
OUTPUT_NAME = "logits"
#: Label values 0, 1, 2 (docs/design.md, *Conventions*).
DEFAULT_CLASSES = ("background", "foot", "leg")
METADATA_KEYS = (
    "gaitnet.model",
    "gaitnet.arch",
    "gaitnet.width",
    "gaitnet.input_scale",
    "gaitnet.padding",
    "gaitnet.output_stride",
    "gaitnet.logit_bias",
    "gaitnet.classes",
    "gaitnet.input",
    "gaitnet.normalisation",
)
_CHANNELS = {
    "rgb": "R, G, B (each /255)",
    "hha": "HHA disparity, height, angle (each /255)",
    "fusion": "R, G, B, then HHA disparity, height, angle (each /255)",
}


def default_classes(num_classes: int) -> tuple[str, ...]:
    """:data:`DEFAULT_CLASSES` for 3 classes, else ``"0"``, ``"1"``, ..."""
    return DEFAULT_CLASSES if num_classes == 3 else tuple(str(i) for i in range(num_classes))


def segmenter_metadata(model: SegmenterNet, classes: Sequence[str]) -> dict[str, str]:
    """The ``metadata_props`` of an exported segmenter (every value a string; JSON where
    structured)."""
    norm = {}
    if model.rgb is not None:
        norm["rgb"] = {"mean": list(RGB_MEAN), "std": list(RGB_STD)}
    if model.hha is not None:
        norm["hha"] = {"mean": list(HHA_MEAN), "std": list(HHA_STD)}
    return {
        "gaitnet.model": "segmenter",
        "gaitnet.arch": model.arch,
        "gaitnet.width": repr(model.width),
        "gaitnet.input_scale": repr(model.input_scale),
        "gaitnet.padding": model.padding,
        "gaitnet.output_stride": str(model.output_stride),
        "gaitnet.logit_bias": json.dumps(list(model.logit_bias)),
        "gaitnet.classes": json.dumps(list(classes)),
        "gaitnet.input": f"float32 (batch, {model.in_channels}, H, W) in [0, 1]: "
        + _CHANNELS[model.arch],
        "gaitnet.normalisation": json.dumps(
            {"applied": "inside the graph, (x - mean) / std per channel", **norm}
        ),
    }


def export_segmenter_onnx(
    model: SegmenterNet,
    path: str | Path,
    height: int = 480,
    width: int = 640,
    opset: int = 18,
    *,
    atol: float = 1e-4,
    batch_sizes: Sequence[int] = (1, 2),
    seed: int = 0,
    classes: Sequence[str] | None = None,
) -> ExportReport:
    """Export ``model`` for (batch, C, ``height``, ``width``) frames to ``path`` and check
    parity on uniform random inputs in [0, 1] (the input's domain); see the module docstring.
    ``classes`` defaults to :func:`default_classes`."""
    for name, value in (("height", height), ("width", width)):
        if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= 8192:
            raise OnnxInputError(f"ONNX export {path}: {name} must be in [1, 8192], got {value!r}")
    if classes is None:
        classes = default_classes(model.num_classes)
    if len(classes) != model.num_classes:
        raise OnnxInputError(
            f"ONNX export {path}: {len(classes)} class names for {model.num_classes} classes"
        )
    import torch

    channels = model.in_channels

    def make_input(batch: int, gen: torch.Generator) -> torch.Tensor:
        return torch.rand(batch, channels, height, width, generator=gen)

    return export_onnx_checked(
        model,
        path,
        make_input,
        input_name=INPUT_NAME,
        output_name=OUTPUT_NAME,
        opset=opset,
        atol=atol,
        batch_sizes=batch_sizes,
        seed=seed,
        metadata=segmenter_metadata(model, classes),
    )


class OnnxSegmenter:
    """Run an exported segmenter with onnxruntime.

    ``threads`` sets onnxruntime's intra-op threads (0: its default), ``providers`` the
    execution providers in order. :attr:`arch`, :attr:`channels`, :attr:`classes`,
    :attr:`input_scale` and the frame size (:attr:`height`, :attr:`width`) come from the file.

    ``flip_average``: the logits are the mean of the network's on the frame and, mirrored
    back, on the frame mirrored left to right (test-time augmentation; the classes have no
    side and training mirrors frames, so both are the network's view of the same scene). It
    doubles the network's work; docs/segmenter.md has what it gains.

    ``edge_refine``: :meth:`labels` moves the class boundaries of the arg-max to the frame's
    colour edges (:func:`~gaitnet.segmentation.edge_refine.refine_labels`); ``None``: the
    arg-max as it is.
    """

    def __init__(
        self,
        path: str | Path,
        threads: int = 1,
        providers: Sequence[str] = ("CPUExecutionProvider",),
        flip_average: bool = False,
        edge_refine: EdgeRefineParams | None = None,
    ) -> None:
        self.path = Path(path)
        self.flip_average = bool(flip_average)
        self.edge_refine = edge_refine
        self.session = open_session(self.path, threads, providers)
        self.metadata = model_metadata(self.session)
        if self.metadata.get("gaitnet.model") != "segmenter":
            raise OnnxInputError(
                f"ONNX model {self.path} is not a gaitnet segmenter (its metadata lack "
                "gaitnet.model = segmenter; export it with export/to_onnx.py segmenter)"
            )
        arch = self.metadata.get("gaitnet.arch")
        if arch not in ARCHS:
            raise OnnxInputError(f"ONNX model {self.path}: unknown segmenter arch {arch!r}")
        self.arch: str = arch
        try:
            classes = json.loads(self.metadata.get("gaitnet.classes", ""))
        except ValueError:
            classes = None
        if not isinstance(classes, list) or not all(isinstance(c, str) for c in classes):
            raise OnnxInputError(f"ONNX model {self.path}: metadata gaitnet.classes is not a list")
        self.classes: tuple[str, ...] = tuple(classes)
        try:
            scale = float(self.metadata.get("gaitnet.input_scale", "1.0"))
        except ValueError:
            scale = float("nan")
        if not 0 < scale <= 1:
            raise OnnxInputError(
                f"ONNX model {self.path}: metadata gaitnet.input_scale must be a number in "
                f"(0, 1], got {self.metadata.get('gaitnet.input_scale')!r}"
            )
        self.input_scale: float = scale
        """The factor by which the graph resizes its input before the streams (HHA stride)."""
        inputs, outputs = self.session.get_inputs(), self.session.get_outputs()
        if len(inputs) != 1 or len(outputs) != 1:
            raise OnnxInputError(
                f"ONNX model {self.path}: expected one input and one output, found "
                f"{[i.name for i in inputs]} and {[o.name for o in outputs]}"
            )
        self.input_name: str = inputs[0].name
        self.output_name: str = outputs[0].name
        self.input_shape: tuple[int | str | None, ...] = tuple(inputs[0].shape)
        shape = self.input_shape
        if (
            inputs[0].type != "tensor(float)"
            or len(shape) != 4
            or shape[1] != input_channels(self.arch)
        ):
            raise OnnxInputError(
                f"ONNX model {self.path}: input {self.input_name!r} is {inputs[0].type} "
                f"{shape}, expected float (batch, {input_channels(self.arch)}, H, W)"
            )

    @property
    def channels(self) -> int:
        """Input channels: 3 (rgb, hha) or 6 (fusion: RGB then HHA)."""
        return input_channels(self.arch)

    @property
    def height(self) -> int | None:
        d = self.input_shape[2]
        return d if isinstance(d, int) else None

    @property
    def width(self) -> int | None:
        d = self.input_shape[3]
        return d if isinstance(d, int) else None

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """Logits (batch, classes, H, W) float32 for ``x`` (batch, C, H, W) in [0, 1] (with
        :attr:`flip_average`, the mean over the frame and its mirror image, in one run).

        Frames of another size than a model exported for one size are scaled to the model's
        height and run in overlapping windows across their width
        (:mod:`gaitnet.segmentation.frame_windows`)."""
        any_size = (*self.input_shape[:2], None, None)
        feed = check_input(x, self.path, self.input_name, any_size, labels=("batch", "C", "H", "W"))
        height, width = self.height, self.width
        if height is not None and width is not None and feed.shape[2:] != (height, width):
            return windowed_logits(self._run, feed, height, width)
        if (height is not None and feed.shape[2] != height) or (
            width is not None and feed.shape[3] != width
        ):  # one fixed dimension: no rule to scale by
            check_input(
                feed, self.path, self.input_name, self.input_shape, ("batch", "C", "H", "W")
            )
        return self._run(feed)

    def _run(self, feed: np.ndarray) -> np.ndarray:
        """The network's logits for a checked batch of the model's size."""
        batch = feed.shape[0]
        if self.flip_average:
            feed = np.concatenate([feed, feed[..., ::-1]])
        (logits,) = run_session(
            self.session, self.path, {self.input_name: feed}, [self.output_name]
        )
        if self.flip_average:
            logits = logits[:batch] + logits[batch:, ..., ::-1]
            logits *= np.float32(0.5)
        return logits

    def predict(self, x: np.ndarray) -> np.ndarray:
        """Labels (batch, H, W) uint8: the arg-max class per pixel (:func:`argmax_classes`)."""
        return argmax_classes(self(x))

    def labels(self, rgb: np.ndarray, hha: np.ndarray) -> np.ndarray:
        """Label map (H, W) uint8 of one frame from its RGB and HHA (H, W, 3) uint8: the
        arg-max of the network's logits, refined by :attr:`edge_refine` when set (the guide is
        the frame's RGB, whatever the network sees)."""
        logits = self(network_input(self.arch, rgb, hha))
        labels = argmax_classes(logits)[0]
        if self.edge_refine is None:
            return labels
        return refine_labels(logits[0], rgb, labels, self.edge_refine)


def network_input(arch: str, rgb: np.ndarray, hha: np.ndarray) -> np.ndarray:
    """(1, C, H, W) float32 input of a segmenter ``arch`` from RGB and HHA (H, W, 3) uint8:
    RGB/255 (``rgb``), HHA/255 (``hha``) or both, RGB first (``fusion``)."""
    parts = {"rgb": (rgb,), "hha": (hha,), "fusion": (rgb, hha)}[arch]
    h, w = parts[0].shape[:2]
    x = np.empty((1, 3 * len(parts), h, w), np.float32)
    for i, image in enumerate(parts):  # channel planes copied by OpenCV: 15× numpy's transpose
        for c, plane in enumerate(cv2.split(np.ascontiguousarray(image))):
            x[0, 3 * i + c] = plane
    x *= np.float32(1.0 / 255.0)
    return x
