"""onnxruntime sessions with checked files, providers, threads, inputs and outputs.

The generic pieces of the project's ONNX model wrappers (one per model kind, e.g.
:class:`gaitnet.segmentation.onnx_runtime.OnnxSegmenter`):

- :func:`open_session`: a session on an explicit provider list with a set intra-op thread
  count; a missing file, a folder, an unknown provider or a file onnxruntime cannot load is a
  one-line :class:`OnnxInputError` naming the file. So is a file whose SHA-256 differs from
  the ``sha256`` its JSON sidecar records (``NAME.json`` beside ``NAME.onnx``, written by
  ``export/to_onnx.py``; :func:`check_sidecar_sha256`): the file is hashed once per load.
- :func:`model_metadata`: the model's ``metadata_props`` (key → string), where exporters
  record what a runtime must know (:func:`gaitnet.io.onnx_export.export_onnx_checked`).
- :func:`check_input`: an array checked against the expected shape (ints fixed, other entries
  free) and converted to a C-contiguous float32 copy; a wrong rank, shape or dtype, an empty
  batch, NaN/inf (also from float64 values beyond float32's range) is a one-line error naming
  the file and the input.
- :func:`run_session`: runs and refuses to return a non-finite output.
"""

from __future__ import annotations

import hashlib
import json
import re
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import onnxruntime as ort

from gaitnet.errors import InputError, one_line

__all__ = [
    "OnnxInputError",
    "check_input",
    "check_sidecar_sha256",
    "is_ort_error",
    "model_metadata",
    "open_session",
    "run_session",
]


class OnnxInputError(InputError):
    """An ONNX model file is unusable or an input does not match what it expects; the one-line
    message names the model file and the input."""


def is_ort_error(exc: BaseException) -> bool:
    """onnxruntime's own exceptions (``onnxruntime.capi...Fail``, ``InvalidProtobuf``, ...)."""
    return type(exc).__module__.startswith("onnxruntime")


_SHA256_HEX = re.compile(r"^[0-9a-f]{64}$")


def check_sidecar_sha256(path: str | Path) -> None:
    """Refuse the model file ``path`` when its JSON sidecar (``path`` with the suffix
    ``.json``) records a ``sha256`` that is not the file's (a damaged, truncated or replaced
    model). No sidecar, or a sidecar without ``sha256``, is not checked; a sidecar that is not
    a JSON object, or whose ``sha256`` is not 64 hex digits, is refused."""
    path = Path(path)
    sidecar = path.with_suffix(".json")
    if not sidecar.is_file():
        return
    try:
        doc = json.loads(sidecar.read_text(encoding="utf-8"))
    except (ValueError, RecursionError) as exc:  # not JSON, not UTF-8, nested too deeply
        raise OnnxInputError(
            f"ONNX model {path}: its sidecar {sidecar} is not readable JSON "
            f"({one_line(exc, limit=120)})"
        ) from None
    if not isinstance(doc, dict):
        raise OnnxInputError(f"ONNX model {path}: its sidecar {sidecar} is not a JSON object")
    if "sha256" not in doc:
        return
    recorded = doc["sha256"]
    if not isinstance(recorded, str) or not _SHA256_HEX.match(recorded.lower()):
        raise OnnxInputError(
            f"ONNX model {path}: its sidecar {sidecar} has 'sha256' {recorded!r:.80}, not 64 "
            "hex digits"
        )
    with path.open("rb") as f:
        actual = hashlib.file_digest(f, "sha256").hexdigest()
    if actual != recorded.lower():
        raise OnnxInputError(
            f"ONNX model {path}: its SHA-256 is {actual}, but its sidecar {sidecar} records "
            f"{recorded} (a damaged or replaced file: restore or re-export the model with its "
            "sidecar)"
        )


def open_session(
    path: str | Path,
    threads: int = 1,
    providers: Sequence[str] = ("CPUExecutionProvider",),
) -> ort.InferenceSession:
    """An onnxruntime session on ``path`` with ``intra_op_num_threads = threads`` (0: the
    runtime's default), one inter-op thread and exactly ``providers`` (in order); the file is
    first checked against its sidecar's SHA-256 (:func:`check_sidecar_sha256`)."""
    path = Path(path)
    if not isinstance(threads, int) or isinstance(threads, bool) or not 0 <= threads <= 1024:
        raise OnnxInputError(f"ONNX threads must be an integer in [0, 1024], got {threads!r}")
    if isinstance(providers, str) or not providers:
        raise OnnxInputError(f"ONNX providers must be a non-empty list of names, got {providers!r}")
    available = ort.get_available_providers()
    unknown = [p for p in providers if p not in available]
    if unknown:
        raise OnnxInputError(
            f"ONNX providers {unknown} are not available in this onnxruntime (available: "
            f"{available})"
        )
    if path.is_dir():
        raise OnnxInputError(f"ONNX model {path} is a folder, expected an .onnx file")
    if not path.is_file():
        raise OnnxInputError(f"ONNX model {path} does not exist")
    check_sidecar_sha256(path)
    options = ort.SessionOptions()
    options.intra_op_num_threads = int(threads)
    options.inter_op_num_threads = 1
    try:
        return ort.InferenceSession(str(path), options, providers=list(providers))
    except Exception as exc:
        if not is_ort_error(exc):
            raise
        raise OnnxInputError(
            f"ONNX model {path} cannot be loaded ({one_line(exc, limit=300)})"
        ) from exc


def model_metadata(session: ort.InferenceSession) -> dict[str, str]:
    """The model's ``metadata_props`` as a dict."""
    return dict(session.get_modelmeta().custom_metadata_map)


def check_input(
    x: object,
    path: str | Path,
    name: str,
    expected: Sequence[int | str | None],
    labels: Sequence[str] | None = None,
) -> np.ndarray:
    """``x`` as a C-contiguous float32 array after checking it against ``expected`` (fixed
    ints; strings or None are free dimensions, the first one the batch). ``labels`` names the
    free dimensions in messages (default: the model's names)."""
    try:
        arr = np.asarray(x)
    except (ValueError, TypeError) as exc:  # ragged nested lists
        raise OnnxInputError(f"ONNX model {path}: input {name!r} is not an array ({exc})") from exc
    if not (np.issubdtype(arr.dtype, np.floating) or np.issubdtype(arr.dtype, np.integer)):
        raise OnnxInputError(
            f"ONNX model {path}: input {name!r} needs real numbers (fed as float32), got dtype "
            f"{arr.dtype}"
        )
    ok = arr.ndim == len(expected) and all(
        not isinstance(e, int) or e == g for e, g in zip(expected, arr.shape, strict=False)
    )
    if not ok:
        shown = tuple(
            e if isinstance(e, int) else (labels[i] if labels else (e or "?"))
            for i, e in enumerate(expected)
        )
        raise OnnxInputError(
            f"ONNX model {path}: input {name!r} expects shape {shown}, given {arr.shape}"
        )
    if arr.size == 0:
        what = "an empty batch, " if arr.ndim and arr.shape[0] == 0 else ""
        raise OnnxInputError(
            f"ONNX model {path}: input {name!r} is empty ({what}shape {arr.shape})"
        )
    with np.errstate(over="ignore", invalid="ignore"):
        feed = np.ascontiguousarray(arr, dtype=np.float32)
    bad = ~np.isfinite(feed)
    if bad.any():
        first = tuple(int(i) for i in np.argwhere(bad)[0])
        raise OnnxInputError(
            f"ONNX model {path}: input {name!r} holds NaN/inf or values beyond float32's range, "
            f"first at index {first}"
        )
    return feed


def run_session(
    session: ort.InferenceSession,
    path: str | Path,
    feed: Mapping[str, np.ndarray],
    output_names: Sequence[str],
) -> list[np.ndarray]:
    """``session.run`` with onnxruntime's failures as one line; every output finite."""
    try:
        outputs = session.run(list(output_names), dict(feed))
    except Exception as exc:
        if not is_ort_error(exc):
            raise
        raise OnnxInputError(f"ONNX model {path} failed ({one_line(exc, limit=300)})") from exc
    for name, value in zip(output_names, outputs, strict=True):
        if not np.all(np.isfinite(value)):
            raise OnnxInputError(
                f"ONNX model {path}: output {name!r} is not finite for a finite input (a broken "
                "model file?)"
            )
    return outputs
