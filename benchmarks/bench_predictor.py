"""Single-thread inference time of an exported motion predictor with onnxruntime (CPU).

Runs the ONNX model on one window at a time (batch 1, the pipeline's per-frame case) with
``intra_op_num_threads = 1`` and prints the median and 90th percentile in ms/window, plus the
per-window time at batch 32 (offline use).

    python benchmarks/bench_predictor.py models/predictor/dctgcn_walk_small.onnx
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import platform  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from gaitnet.motion.onnx_runtime import OnnxInputError, OnnxPredictor  # noqa: E402
from gaitnet.training.scripts import ScriptParser  # noqa: E402


def time_calls(predictor: OnnxPredictor, x: np.ndarray, n: int, warmup: int) -> np.ndarray:
    """Seconds per call of ``predictor(x)`` over ``n`` timed calls after ``warmup`` calls."""
    for _ in range(warmup):
        predictor(x)
    out = np.empty(n)
    for i in range(n):
        t0 = time.perf_counter()
        predictor(x)
        out[i] = time.perf_counter() - t0
    return out


def main(argv: list[str] | None = None) -> int:
    parser = ScriptParser(description=__doc__.splitlines()[0])
    parser.add_argument("model", help="exported predictor .onnx")
    parser.add_argument("--n", type=int, default=2000, help="timed calls at batch 1")
    parser.add_argument("--warmup", type=int, default=100)
    args = parser.parse_args(argv)
    try:
        predictor = OnnxPredictor(args.model, threads=1)
    except OnnxInputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    n_past = predictor.n_past or 10
    rng = np.random.default_rng(0)
    x1 = rng.normal(scale=0.3, size=(1, n_past, 21)).astype(np.float32)
    t1 = time_calls(predictor, x1, args.n, args.warmup) * 1000
    x32 = rng.normal(scale=0.3, size=(32, n_past, 21)).astype(np.float32)
    t32 = time_calls(predictor, x32, max(20, args.n // 20), 10) * 1000 / 32
    size = os.path.getsize(args.model) / 1e6
    print(f"{args.model} ({size:.2f} MB), onnxruntime CPU, 1 thread, {platform.processor() or ''}")
    print(f"batch 1 : {np.median(t1):.3f} ms/window (median), p90 {np.percentile(t1, 90):.3f}")
    print(f"batch 32: {np.median(t32):.4f} ms/window (median)")
    return 0


if __name__ == "__main__":
    from gaitnet.cli.scripts import run_script

    raise SystemExit(run_script(main))
