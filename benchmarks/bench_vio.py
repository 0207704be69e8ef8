"""The filter on simulated sessions: stride-length errors, body trajectory error, time per frame.

For every session folder given (simulated, with ``groundtruth/``): runs ``run_vio`` with the
default config, matches its strides to the true ones (``gaitnet evaluate``'s matching) and
prints one row per session — floor family, matched strides per side, stride RMSE and maximum
error per side, body ATE of the filter and of the IMU-only dead reckoning, measurements used
and skipped, CPU milliseconds per frame by stage — then the overall stride RMSE.

    python benchmarks/bench_vio.py SESSION [SESSION ...]

Make held-out sessions with ``gaitnet simulate --seed N --out DIR`` (seeds the config was not
tuned on: the detectors and odometry were tuned on 200–210).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402
import yaml  # noqa: E402

from gaitnet.errors import InputError, SessionError  # noqa: E402
from gaitnet.evaluation.metrics import ate_yaw_aligned  # noqa: E402
from gaitnet.evaluation.strides import match_strides, read_strides  # noqa: E402
from gaitnet.io import open_session  # noqa: E402
from gaitnet.vio.config import VioConfig  # noqa: E402
from gaitnet.vio.report import write_result  # noqa: E402
from gaitnet.vio.run import run_vio  # noqa: E402


def _family(session: Path) -> str:
    cfg = yaml.safe_load((session / "sim_config.yaml").read_text())
    family = cfg.get("scene", {}).get("floor_family", "?")
    extra = yaml.safe_load((session / "session.yaml").read_text()).get("extra", {})
    return str(extra.get("floor_family", family))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("sessions", nargs="+", type=Path)
    args = parser.parse_args()
    cv2.setNumThreads(1)
    errors: list[float] = []
    print(
        "session | floor | strides L/R | RMSE L/R [cm] | max L/R [cm] | ATE filter / IMU-only [cm]"
        " | VO used/skipped | ms/frame (CPU) | stages [ms/frame]"
    )
    for session in args.sessions:
        source = open_session(session)
        t0 = time.process_time()
        result = run_vio(source, VioConfig())
        cpu_ms = 1e3 * (time.process_time() - t0) / len(source)
        with tempfile.TemporaryDirectory() as tmp:
            out = write_result(result, Path(tmp) / "r", "")
            est = read_strides(out / "strides.csv", InputError)
        ref = read_strides(session / "groundtruth" / "strides.csv", SessionError)
        match = match_strides(est, ref)
        cells = []
        for side in ("left", "right"):
            e = np.array([est.length_m[i] - ref.length_m[j] for i, j in match.pairs[side]])
            errors += list(e)
            cells.append(
                (
                    len(e),
                    np.sqrt(np.mean(e**2)) * 100 if len(e) else np.nan,
                    np.abs(e).max() * 100 if len(e) else np.nan,
                )
            )
        truth = np.loadtxt(session / "groundtruth" / "camera_frames.tum")[:, 1:4]
        ate_f = ate_yaw_aligned(result.T_WfromC_filter[:, :3, 3], truth) * 100
        ate_i = ate_yaw_aligned(result.T_WfromC_imu_only[:, :3, 3], truth) * 100
        n = len(source)
        stages = ", ".join(f"{k} {1e3 * v / n:.1f}" for k, v in result.timings_s.items())
        vo_skip = sum(result.skipped.get("vo", {}).values())
        print(
            f"{session.name} | {_family(session)} | {cells[0][0]}/{cells[1][0]} | "
            f"{cells[0][1]:.2f}/{cells[1][1]:.2f} | {cells[0][2]:.2f}/{cells[1][2]:.2f} | "
            f"{ate_f:.1f} / {ate_i:.1f} | {result.used['vo']}/{vo_skip} | {cpu_ms:.0f} | {stages}"
        )
    if errors:
        e = np.array(errors)
        print(f"overall: {len(e)} strides, RMSE {100 * np.sqrt(np.mean(e**2)):.2f} cm")


if __name__ == "__main__":
    main()
