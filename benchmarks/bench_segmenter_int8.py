"""The segmenter quantised to int8 with onnxruntime.quantization, against the committed float
model: time per 640×480 frame on 1 and 2 threads, and the label scores of a labelled set.

Two quantisations of the committed model (``models/segmenter/``):

- ``dynamic``: ``quantize_dynamic``, int8 weights, activations quantised per call (ConvInteger);
- ``static``: ``quant_pre_process`` then ``quantize_static`` in the QDQ format, int8 weights
  per output channel, uint8 activations calibrated (min–max) on the frames of ``--calibration``,
  a set other than the one scored.

Each quantised model gets the committed model's sidecar with its own sha256, so that
:class:`gaitnet.segmentation.onnx_runtime.OnnxSegmenter` loads it as ``gaitnet infer`` would.
Times are the median of ``--runs`` calls on one frame of the scored set after three warm-up
calls; scores are ``bench_segmenter_labels.py``'s (network, edge-refined, post-processed).

    python benchmarks/bench_segmenter_int8.py SET --calibration CAL_SET [--runs 20]
        [--work DIR] [--json OUT.json]
"""

from __future__ import annotations

import hashlib
import json
import statistics
import tempfile
import time
from pathlib import Path

import onnxruntime as ort
from bench_segmenter_labels import score_set

from gaitnet.segmentation.dataset import SegmentationFolder
from gaitnet.segmentation.edge_refine import EdgeRefineParams
from gaitnet.segmentation.hha import hha_stride
from gaitnet.segmentation.onnx_runtime import OnnxSegmenter, network_input
from gaitnet.segmentation.postprocess import FootKeypointParams
from gaitnet.segmentation.segment_session import default_segmenter_path
from gaitnet.training.scripts import ScriptParser
from gaitnet.training.segmenter_data import resolve_set


def _frames(root: Path, input_scale: float) -> SegmentationFolder:
    folder, ids = resolve_set(root)
    return SegmentationFolder(folder, ids, hha_stride=hha_stride(input_scale))


def _with_sidecar(model: Path, sidecar: dict) -> Path:
    data = model.read_bytes()
    own = {**sidecar, "onnx": model.name, "sha256": hashlib.sha256(data).hexdigest(),
           "size_bytes": len(data)}  # fmt: skip
    model.with_suffix(".json").write_text(json.dumps(own, indent=1) + "\n")
    return model


def quantised_models(source: Path, calibration: SegmentationFolder, work: Path) -> dict[str, Path]:
    """``dynamic`` and ``static`` int8 copies of ``source`` in ``work`` (module docstring)."""
    from onnxruntime.quantization import (
        CalibrationDataReader,
        QuantFormat,
        QuantType,
        quantize_dynamic,
        quantize_static,
    )
    from onnxruntime.quantization.shape_inference import quant_pre_process

    sidecar = json.loads(source.with_suffix(".json").read_text())
    arch = sidecar["arch"]

    class Frames(CalibrationDataReader):
        def __init__(self) -> None:
            self.ids = iter(calibration.ids)

        def get_next(self) -> dict | None:
            frame_id = next(self.ids, None)
            if frame_id is None:
                return None
            rgb, hha = calibration.read_rgb(frame_id), calibration.read_hha(frame_id)
            return {"image": network_input(arch, rgb, hha)}

    dynamic, static, prepared = (work / f"{n}.onnx" for n in ("dynamic", "static", "prepared"))
    quantize_dynamic(source, dynamic, weight_type=QuantType.QInt8)
    quant_pre_process(str(source), str(prepared))
    quantize_static(
        prepared, static, Frames(), quant_format=QuantFormat.QDQ,
        activation_type=QuantType.QUInt8, weight_type=QuantType.QInt8, per_channel=True,
    )  # fmt: skip
    return {"dynamic": _with_sidecar(dynamic, sidecar), "static": _with_sidecar(static, sidecar)}


def milliseconds(model: Path, feed: dict, threads: int, runs: int) -> float:
    """Median ms of one network call of ``model`` on ``threads`` onnxruntime threads."""
    options = ort.SessionOptions()
    options.intra_op_num_threads, options.inter_op_num_threads = threads, 1
    session = ort.InferenceSession(str(model), options, providers=["CPUExecutionProvider"])
    for _ in range(3):
        session.run(None, feed)
    times = []
    for _ in range(runs):
        start = time.perf_counter()
        session.run(None, feed)
        times.append(1000.0 * (time.perf_counter() - start))
    return statistics.median(times)


def main() -> None:
    ap = ScriptParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("set", type=Path, help="labelled set scored (folder or split file)")
    ap.add_argument("--calibration", type=Path, required=True, help="labelled set calibrated on")
    ap.add_argument("--runs", type=int, default=20, help="timed calls per model and threads")
    ap.add_argument("--work", type=Path, default=None, help="folder for the quantised models")
    ap.add_argument("--json", type=Path, default=None, help="also write the rows here")
    args = ap.parse_args()
    for path in (args.set, args.calibration):
        if not path.exists():
            ap.error(f"{path}: not found")
    source = default_segmenter_path()
    sidecar = json.loads(source.with_suffix(".json").read_text())
    scored = _frames(args.set, sidecar["input_scale"])
    first = scored.ids[0]
    feed = {"image": network_input(sidecar["arch"], scored.read_rgb(first), scored.read_hha(first))}
    with tempfile.TemporaryDirectory() as tmp:
        work = args.work or Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        calibration = _frames(args.calibration, sidecar["input_scale"])
        models = {"float": source, **quantised_models(source, calibration, work)}
        print(f"{'model':8s} {'MB':>5s} {'ms 1 thr':>8s} {'ms 2 thr':>8s} "
              f"{'mIoU net':>8s} {'mIoU post':>9s} {'foot post':>9s}")  # fmt: skip
        rows = {}
        for name, path in models.items():
            scores = score_set(
                args.set, OnnxSegmenter(path, threads=1), FootKeypointParams(), EdgeRefineParams()
            )
            row = {
                "size_mb": path.stat().st_size / 1e6,
                "ms_1_thread": milliseconds(path, feed, 1, args.runs),
                "ms_2_threads": milliseconds(path, feed, 2, args.runs),
                "miou_network": scores["network"]["miou"],
                "miou_post": scores["post-processed"]["miou"],
                "foot_iou_post": scores["post-processed"]["iou"]["foot"],
            }
            rows[name] = row
            print(f"{name:8s} {row['size_mb']:5.2f} {row['ms_1_thread']:8.1f} "
                  f"{row['ms_2_threads']:8.1f} {row['miou_network']:8.4f} "
                  f"{row['miou_post']:9.4f} {row['foot_iou_post']:9.4f}")  # fmt: skip
    if args.json is not None:
        args.json.write_text(json.dumps(rows, indent=1) + "\n")


if __name__ == "__main__":
    from gaitnet.cli.scripts import run_script

    raise SystemExit(run_script(main))
