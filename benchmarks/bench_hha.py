"""HHA encoding speed at 640×480 on simulated frames, with and without gravity (run by hand).

Renders ``--frames`` frames with ``configs/sim/default.yaml`` (640×480, sensor depth noise),
then times :func:`gaitnet.segmentation.hha.hha_encode` on one thread (best of ``--repeat``
passes over the frames; wall time and the process's CPU time, the machine is shared) with the
frame's gravity and with ``gravity_C=None``. Also printed, as a check of the encoding on
realistic depth: on the frames' background pixels that the floor fit calls floor (height within
2 cm), the median and 95th percentile of the angle channel [deg] and of |height| [mm], and how
often the no-IMU fallback finds the same floor (height codes within 2).

``--stride 2`` times the encoding at every second pixel (the committed segmenter's, whose
streams see the frame at half size; :func:`gaitnet.segmentation.hha.hha_stride`).

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/bench_hha.py [--frames 8] [--repeat 3]
        [--stride 1]
"""

from __future__ import annotations

import os
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from gaitnet.config import load_config  # noqa: E402
from gaitnet.segmentation.hha import hha_decode, hha_encode  # noqa: E402
from gaitnet.sim.config import SimConfig  # noqa: E402
from gaitnet.sim.dataset import simulate_frame  # noqa: E402
from gaitnet.training.scripts import ScriptParser  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = ScriptParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=8)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--seed", type=int, default=11)
    ap.add_argument("--stride", type=int, default=1, help="HHA stride (1: every pixel)")
    args = ap.parse_args()
    cv2.setNumThreads(1)
    cfg = load_config(SimConfig, ROOT / "configs" / "sim" / "default.yaml")
    frames = [simulate_frame(cfg, args.seed, i) for i in range(args.frames)]
    h, w = frames[0].depth_m.shape
    print(
        f"{len(frames)} simulated frames {w}×{h} (configs/sim/default.yaml, seed {args.seed}), "
        f"HHA stride {args.stride}"
    )
    for name, use_gravity in (("with gravity", True), ("gravity=None", False)):
        best_wall = best_cpu = np.inf
        for _ in range(args.repeat):
            t0, c0 = time.perf_counter(), time.process_time()
            for f in frames:
                gravity = f.gravity_C() if use_gravity else None
                hha_encode(f.depth_m, f.K, gravity, stride=args.stride)
            best_wall = min(best_wall, time.perf_counter() - t0)
            best_cpu = min(best_cpu, time.process_time() - c0)
        n = len(frames)
        print(
            f"  {name:13s}: {n / best_wall:6.1f} frames/s wall ({1e3 * best_wall / n:.1f} ms), "
            f"{n / best_cpu:6.1f} frames/s CPU ({1e3 * best_cpu / n:.1f} ms)"
        )
    angles, heights, same = [], [], 0
    for f in frames:
        hha = hha_encode(f.depth_m, f.K, f.gravity_C(), stride=args.stride)
        _, height, angle = hha_decode(hha)
        floor = (f.render.label == 0) & (np.abs(height) < 0.02) & np.isfinite(angle)
        angles.append(angle[floor])
        heights.append(np.abs(height[floor]) * 1e3)
        no_imu = hha_encode(f.depth_m, f.K, None, stride=args.stride)
        valid = f.depth_m > 0
        diff = np.abs(no_imu[..., 1].astype(int) - hha[..., 1].astype(int))[valid]
        same += int(np.percentile(diff, 99) <= 2)
    a, hh = np.concatenate(angles), np.concatenate(heights)
    print(
        f"  floor pixels: angle median {np.median(a):.2f}°, p95 {np.percentile(a, 95):.2f}°; "
        f"|height| median {np.median(hh):.1f} mm, p95 {np.percentile(hh, 95):.1f} mm"
    )
    print(f"  no-IMU fallback finds the IMU's floor in {same}/{len(frames)} frames")


if __name__ == "__main__":
    from gaitnet.cli.scripts import run_script

    raise SystemExit(run_script(main))
