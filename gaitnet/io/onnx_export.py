"""Export a PyTorch model to one ONNX file, checked against PyTorch before it is written.

:func:`export_onnx_checked` is the generic piece of the project's exporters (e.g.
:func:`gaitnet.segmentation.onnx_runtime.export_segmenter_onnx`): a CPU float32 eval-mode copy
of the model (the caller's is not touched) goes through ``torch.onnx.export`` (dynamo
exporter, one self-contained file, a dynamic batch axis), string metadata is stored in the
model's ``metadata_props``, and onnxruntime (CPU) runs the graph on seeded inputs of several
batch sizes. If the largest absolute difference from PyTorch exceeds ``atol``
:class:`OnnxParityError` is raised and the target path is left as it was; otherwise the file is
renamed into place atomically (:func:`gaitnet.io.atomic.atomic_save`). Needs the ``[train]``
extra (``onnx``, ``onnxscript``); torch is imported when called.
"""

from __future__ import annotations

import contextlib
import copy
import io
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from gaitnet.io.atomic import atomic_save
from gaitnet.io.onnx_session import open_session

if TYPE_CHECKING:
    import torch

__all__ = ["ExportReport", "OnnxParityError", "export_onnx_checked"]


class OnnxParityError(RuntimeError):
    """The exported graph does not reproduce the PyTorch model within tolerance."""


@dataclass(frozen=True)
class ExportReport:
    """What :func:`export_onnx_checked` wrote and the parity check it passed."""

    path: Path
    opset: int
    max_abs_diff: float
    batch_sizes: tuple[int, ...]


def export_onnx_checked(
    model: torch.nn.Module,
    path: str | Path,
    make_input: Callable[[int, torch.Generator], torch.Tensor],
    *,
    input_name: str,
    output_name: str,
    opset: int = 18,
    atol: float = 1e-4,
    batch_sizes: Sequence[int] = (1, 2),
    seed: int = 0,
    metadata: Mapping[str, str] | None = None,
) -> ExportReport:
    """Export ``model`` (one input, one output) to ``path`` and check it against PyTorch.

    ``make_input(batch, generator)`` draws an input of the model's domain; the export uses a
    batch of 2 with the batch axis dynamic, parity uses each size in ``batch_sizes``.
    """
    import torch

    path = Path(path)
    net = copy.deepcopy(model).to("cpu", torch.float32).eval()
    example = make_input(2, torch.Generator().manual_seed(seed))
    worst = 0.0

    def export_and_check(tmp_name: str) -> None:
        nonlocal worst
        # The exporter reports progress on stdout; library code stays quiet.
        with contextlib.redirect_stdout(io.StringIO()):
            program = torch.onnx.export(
                net,
                (example,),
                None,
                input_names=[input_name],
                output_names=[output_name],
                opset_version=int(opset),
                dynamo=True,
                dynamic_shapes=({0: torch.export.Dim("batch")},),
                verbose=False,
            )
            for key, value in (metadata or {}).items():
                program.model.metadata_props[str(key)] = str(value)
            program.save(tmp_name, external_data=False)
        session = open_session(tmp_name, threads=1)
        gen = torch.Generator().manual_seed(seed + 1)
        for b in batch_sizes:
            x = make_input(int(b), gen)
            with torch.no_grad():
                expected = net(x).numpy()
            (got,) = session.run([output_name], {input_name: x.numpy()})
            if got.shape != expected.shape:
                raise OnnxParityError(
                    f"ONNX export {path}: output shape {got.shape} for batch {b}, PyTorch gives "
                    f"{expected.shape}"
                )
            diff = float(np.max(np.abs(got - expected)))
            worst = max(worst, diff if np.isfinite(diff) else float("inf"))
        if not worst <= atol:
            raise OnnxParityError(
                f"ONNX export {path}: max |onnxruntime - torch| = {worst:.3g} exceeds {atol:g}"
            )

    atomic_save(path, export_and_check)
    return ExportReport(
        path=path, opset=int(opset), max_abs_diff=worst, batch_sizes=tuple(batch_sizes)
    )
