"""ONNX export of the DCT-GCN predictor with a parity check, and an onnxruntime wrapper.

The exported graph is :meth:`gaitnet.motion.gcn.DCTGCN.forward`: input ``past_poses`` (batch,
n_past, 21) float32 → output ``poses`` (batch, n_past + n_future, 21) float32, with a dynamic
batch dimension. The export is refused (and nothing is written) unless onnxruntime reproduces
PyTorch to within ``atol`` on random inputs of several batch sizes; the file is written
atomically (:func:`gaitnet.io.atomic.atomic_save`).

:class:`OnnxPredictor` checks what it is given: a missing, unreadable or foreign ``.onnx`` file,
and an input of the wrong rank, shape or dtype, an empty batch or a NaN/inf (also one that
appears when float64 values beyond float32's range are cast), are one-line
:class:`OnnxInputError` s (an :class:`~gaitnet.errors.InputError`) naming the file and the
input; a non-finite output is never returned.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from gaitnet.io.onnx_export import ExportReport, OnnxParityError, export_onnx_checked
from gaitnet.io.onnx_session import OnnxInputError, check_input, open_session, run_session

if TYPE_CHECKING:  # PyTorch is imported only to export: running a model does not need it
    import torch

    from gaitnet.motion.gcn import DCTGCN

__all__ = [
    "INPUT_NAME",
    "OUTPUT_NAME",
    "ExportReport",
    "OnnxInputError",
    "OnnxParityError",
    "OnnxPredictor",
    "export_predictor_onnx",
]

INPUT_NAME = "past_poses"
OUTPUT_NAME = "poses"


def export_predictor_onnx(
    model: DCTGCN,
    path: str | Path,
    opset: int = 18,
    *,
    atol: float = 1e-4,
    batch_sizes: Sequence[int] = (1, 2, 5),
    seed: int = 0,
) -> ExportReport:
    """Export ``model`` to ``path`` (one self-contained ``.onnx`` file) and check parity.

    :func:`gaitnet.io.onnx_export.export_onnx_checked` on a CPU copy of the model in eval mode
    (the caller's model is not touched): the dynamo exporter with a dynamic batch axis, input
    ``past_poses`` and output ``poses``; onnxruntime (CPU) is compared with PyTorch on seeded
    standard-normal inputs of each size in ``batch_sizes``; if the largest absolute difference
    exceeds ``atol`` :class:`OnnxParityError` is raised and ``path`` is left as it was. On
    success the file is renamed into place atomically.
    """
    import torch

    cfg = model.config

    def make_input(batch: int, gen: torch.Generator) -> torch.Tensor:
        return torch.randn(batch, cfg.n_past, cfg.n_nodes, generator=gen)

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
    )


class OnnxPredictor:
    """Run an exported predictor with onnxruntime on the CPU.

    Input and output names and the expected input shape are read from the session. Calls
    check the input (a clear :class:`OnnxInputError` naming the model file and the expected vs.
    given shape or dtype), and feed a C-contiguous float32 copy. ``threads`` sets
    ``intra_op_num_threads``.
    """

    def __init__(self, path: str | Path, threads: int = 1):
        self.path = Path(path)
        self.session = open_session(self.path, threads)
        inputs = self.session.get_inputs()
        if len(inputs) != 1:
            names = [i.name for i in inputs]
            raise OnnxInputError(f"ONNX model {self.path}: expected one input, found {names}")
        self.input_name: str = inputs[0].name
        self.input_shape: tuple[int | str | None, ...] = tuple(inputs[0].shape)
        self.input_type: str = inputs[0].type
        self.output_names: list[str] = [o.name for o in self.session.get_outputs()]
        if self.input_type != "tensor(float)":
            raise OnnxInputError(
                f"ONNX model {self.path}: input {self.input_name!r} has type {self.input_type}, "
                "expected tensor(float)"
            )
        if len(self.input_shape) != 3:
            raise OnnxInputError(
                f"ONNX model {self.path}: input {self.input_name!r} has shape "
                f"{self.input_shape}, expected (batch, n_past, nodes)"
            )

    @property
    def n_past(self) -> int | None:
        """Observed frames the model takes (None when the model leaves it dynamic)."""
        d = self.input_shape[1]
        return d if isinstance(d, int) else None

    def run(self, past: np.ndarray) -> dict[str, np.ndarray]:
        """All outputs by name for ``past`` (batch, n_past, nodes); every value finite
        (:func:`gaitnet.io.onnx_session.check_input`, :func:`~gaitnet.io.onnx_session.
        run_session`)."""
        feed = check_input(
            past, self.path, self.input_name, self.input_shape, ("batch", "n_past", "nodes")
        )
        outputs = run_session(self.session, self.path, {self.input_name: feed}, self.output_names)
        return dict(zip(self.output_names, outputs, strict=True))

    def __call__(self, past: np.ndarray) -> np.ndarray:
        """The full sequence (batch, n_past + n_future, nodes): the first output."""
        return self.run(past)[self.output_names[0]]

    def predict_future(self, past: np.ndarray) -> np.ndarray:
        """Only the predicted frames (batch, n_future, nodes)."""
        past = np.asarray(past)
        return self(past)[:, past.shape[1] :]
