"""Inference time of the segmenter per 640×480 frame: PyTorch eager vs onnxruntime, 1 and 2 threads.

For each variant (arch, width, input_scale, padding, output stride) a net with random weights
is built, exported with the parity check
(gaitnet.segmentation.onnx_runtime.export_segmenter_onnx) and timed at batch 1 (the pipeline's
per-frame case) on random frames in [0, 1]: ``torch.no_grad`` eager with
``torch.set_num_threads(t)`` and :class:`OnnxSegmenter` (its input checks included) with
``threads=t`` for t = 1, 2. The first call is a warm-up; a variant whose warm-up takes longer
than ``--slow`` seconds (the published width 1) is timed once. Prints median (min) wall ms per
frame, frames/s of onnxruntime on 2 threads, the process CPU ms of the one-thread runs (on a
busy machine the best estimate of the one-thread wall time on an idle one), the machine's load
average before and after, and the CPU. The target for the default CPU model is ≥ 15 frames/s
with onnxruntime on 2 threads.

    nice -n 10 python benchmarks/bench_segmenter.py                  # the default table
    python benchmarks/bench_segmenter.py --variants fusion:0.0625:0.5:same rgb:0.125:1 --runs 20
    python benchmarks/bench_segmenter.py --variants fusion:0.0625:0.5:same:4      # output stride 4
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

try:
    import torch
except ModuleNotFoundError as exc:  # the core install has no PyTorch
    raise SystemExit(f"error: {exc.name} is not installed: pip install -e '.[train]'") from None

from gaitnet.segmentation.channels import ARCHS, input_channels
from gaitnet.segmentation.fcn import OUTPUT_STRIDES, PADDINGS
from gaitnet.segmentation.onnx_runtime import OnnxSegmenter, export_segmenter_onnx
from gaitnet.segmentation.segmenter_net import SegmenterNet
from gaitnet.training.scripts import ScriptParser

#: arch:width:input_scale[:padding[:output_stride]] (padding "published", stride 8 when left
#: out) — fusion at every width (full frames and half-size inside the net), the published
#: width 1 once, the single streams at the CPU default, and the CPU default with "same" padding.
DEFAULT_VARIANTS = (
    "fusion:0.0625:0.5",
    "fusion:0.0625:0.5:same",
    "fusion:0.0625:0.75:same",
    "fusion:0.09:0.5:same",
    "fusion:0.0625:1",
    "fusion:0.125:0.5",
    "fusion:0.125:1",
    "fusion:0.25:0.5",
    "fusion:0.25:1",
    "rgb:0.0625:0.5",
    "hha:0.0625:0.5",
    "fusion:1:1",
)


def parse_variant(text: str) -> tuple[str, float, float, str, int]:
    parts = text.split(":")
    defaults = ["published", "8"]  # padding, output stride
    parts += defaults[len(parts) - 3 :] if 3 <= len(parts) < 5 else []
    if len(parts) != 5:
        raise argparse.ArgumentTypeError(
            f"expected arch:width:input_scale[:padding[:output_stride]], got {text}"
        )
    arch, width, scale, padding, stride = parts
    if arch not in ARCHS:
        raise argparse.ArgumentTypeError(f"arch must be one of {ARCHS}: {text}")
    if padding not in PADDINGS:
        raise argparse.ArgumentTypeError(f"padding must be one of {PADDINGS}: {text}")
    if stride not in {str(s) for s in OUTPUT_STRIDES}:
        raise argparse.ArgumentTypeError(f"output stride must be one of {OUTPUT_STRIDES}: {text}")
    try:
        return arch, float(width), float(scale), padding, int(stride)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"width and input_scale must be numbers: {text}") from exc


def time_calls(fn: Callable[[], object], runs: int, slow_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Wall and process-CPU seconds per call after one warm-up call (one timed call if the
    warm-up is slow). On a busy machine the CPU time of a one-thread call is close to its wall
    time on an idle one; the wall time is not."""
    t0 = time.perf_counter()
    fn()
    if time.perf_counter() - t0 > slow_s:
        runs = 1
    wall, cpu = np.empty(runs), np.empty(runs)
    for i in range(runs):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        wall[i], cpu[i] = time.perf_counter() - t0, time.process_time() - c0
    return wall, cpu


def cpu_name() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def bench_variant(
    variant: tuple[str, float, float, str, int], args: argparse.Namespace, folder: Path
) -> dict:
    arch, width, scale, padding, stride = variant
    torch.manual_seed(0)
    net = SegmenterNet(
        arch, width=width, input_scale=scale, padding=padding, output_stride=stride
    ).eval()
    with torch.no_grad():  # score layers start at zero: give them values
        for name, layer in net.named_modules():
            if name.split(".")[-1].startswith("score_"):
                layer.weight.normal_(0.0, 0.01)
    path = folder / f"{arch}_{width:g}_{scale:g}_{padding}_{stride}.onnx"
    t0 = time.perf_counter()
    report = export_segmenter_onnx(
        net, path, height=args.height, width=args.width, batch_sizes=(1,)
    )
    export_s = time.perf_counter() - t0
    x = np.random.default_rng(0).random((1, input_channels(arch), args.height, args.width))
    x = x.astype(np.float32)
    xt = torch.from_numpy(x)
    row = {
        "arch": arch,
        "output_stride": stride,
        "width": width,
        "input_scale": scale,
        "padding": padding,
        "params": sum(p.numel() for p in net.parameters()),
        "onnx_mb": path.stat().st_size / 1e6,
        "parity_max_abs_diff": report.max_abs_diff,
        "export_s": export_s,
    }
    for threads in (1, 2):
        torch.set_num_threads(threads)
        with torch.no_grad():
            t, c = time_calls(lambda: net(xt), args.runs, args.slow)
        row[f"torch_{threads}t_ms"] = [float(np.median(t) * 1e3), float(t.min() * 1e3), len(t)]
        row[f"torch_{threads}t_cpu_ms"] = float(np.median(c) * 1e3)
        seg = OnnxSegmenter(path, threads=threads)
        t, c = time_calls(lambda seg=seg: seg(x), args.runs, args.slow)
        row[f"ort_{threads}t_ms"] = [float(np.median(t) * 1e3), float(t.min() * 1e3), len(t)]
        row[f"ort_{threads}t_cpu_ms"] = float(np.median(c) * 1e3)
        del seg
    path.unlink()
    return row


def fmt(cell: list) -> str:
    median, low, n = cell
    return f"{median:8.1f} ({low:7.1f})" + ("*" if n == 1 else " ")


def main(argv: list[str] | None = None) -> int:
    parser = ScriptParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--variants",
        nargs="+",
        type=parse_variant,
        default=None,
        help="arch:width:input_scale[:padding[:output_stride]] ... (default: the table in the "
        "docstring)",
    )
    parser.add_argument("--runs", type=int, default=10, help="timed calls per measurement")
    parser.add_argument(
        "--slow",
        type=float,
        default=3.0,
        help="warm-up seconds above which a measurement is timed once",
    )
    parser.add_argument("--height", type=int, default=480)
    parser.add_argument("--width", type=int, default=640)
    parser.add_argument("--json", help="also write the rows to this JSON file")
    args = parser.parse_args(argv)  # fmt: skip
    variants = args.variants or [parse_variant(v) for v in DEFAULT_VARIANTS]
    load_before = os.getloadavg()
    print(
        f"{cpu_name()}, {os.cpu_count()} CPUs, nice {os.nice(0)}, torch {torch.__version__}, "
        f"frame {args.width}x{args.height}, batch 1, load average {load_before[0]:.2f}"
    )
    head = (f"{'arch':6} {'width':>6} {'scale':>5} {'pad':>4} {'os':>2} {'params':>9} {'MB':>6} | "
            f"{'torch 1 thread':>18} {'torch 2 threads':>18} | {'ort 1 thread':>18} "
            f"{'ort 2 threads':>18} | {'fps ort 2t':>10} | "
            f"{'cpu torch 1t':>12} {'cpu ort 1t':>10}")  # fmt: skip
    print("ms per frame: median (min) of wall time; * = one timed run; cpu: median process CPU ms")
    print(head)
    print("-" * len(head))
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench_segmenter_") as tmp:
        for variant in variants:
            arch, width, scale, padding, stride = variant
            row = bench_variant(variant, args, Path(tmp))
            rows.append(row)
            fps = 1e3 / row["ort_2t_ms"][0]
            torch_cells = f"{fmt(row['torch_1t_ms'])} {fmt(row['torch_2t_ms'])}"
            ort_cells = f"{fmt(row['ort_1t_ms'])} {fmt(row['ort_2t_ms'])}"
            print(
                f"{arch:6} {width:6.4g} {scale:5.2g} {padding[:4]:>4} {stride:2d} "
                f"{row['params'] / 1e6:8.2f}M "
                f"{row['onnx_mb']:6.2f} | {torch_cells} | {ort_cells} | {fps:10.1f} | "
                f"{row['torch_1t_cpu_ms']:12.1f} {row['ort_1t_cpu_ms']:10.1f}",
                flush=True,
            )
    load_after = os.getloadavg()
    print(f"load average before {load_before[0]:.2f}, after {load_after[0]:.2f} (1 min); parity "
          f"max |ort - torch| {max(r['parity_max_abs_diff'] for r in rows):.2g}")  # fmt: skip
    if args.json:
        info = {"cpu": cpu_name(), "load_before": load_before, "load_after": load_after}
        Path(args.json).write_text(json.dumps({"machine": info, "rows": rows}, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    from gaitnet.cli.scripts import run_script

    raise SystemExit(run_script(main))
