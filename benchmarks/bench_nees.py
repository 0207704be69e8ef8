"""Consistency of the filter's position covariance on simulated sessions (run by hand).

For each session: ``run_vio`` (smoother off: only the filter's covariance is judged), then per
processed frame the normalised estimation error squared of the IMU position

    NEES_k = eᵀ P⁻¹ e,   e = p_true − p_filter,   P = cov_p_IinW_filter[k]

against ``groundtruth/imu_frames.tum`` (same timestamps). A consistent filter has NEES ~ χ²(3):
mean 3, and 95 % of the frames inside the two-sided band [0.216, 9.35]. Printed per session:
frames, mean and median NEES, the fraction inside the band, above it and below it, the mean
position error and the mean standard deviation the filter claims (√(trace P / 3)), the
fraction inside the band while standing at the start, walking and standing at the end (the
true IMU position within 5 cm of its first / last one), and the filter's VO updates used /
skipped.

    OMP_NUM_THREADS=1 python benchmarks/bench_nees.py SESSION [SESSION ...] [--set vo.KEY=V ...]

``--set`` takes ``configs/vio`` overrides (``vo.cov_scale=4``, ``imu.scale=1.5``, ...).
Only sessions initialised from AprilTags are meaningful (the filter's world is then the
simulator's); the others are reported and left out of the totals.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import logging  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from gaitnet.config import load_config  # noqa: E402
from gaitnet.evaluation.metrics import match_times  # noqa: E402
from gaitnet.io import open_session  # noqa: E402
from gaitnet.io.trajectory import read_tum  # noqa: E402
from gaitnet.training.scripts import ScriptParser  # noqa: E402
from gaitnet.vio.config import VioConfig  # noqa: E402
from gaitnet.vio.run import run_vio  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
BAND_3DOF_95 = (0.2158, 9.3484)
"""Two-sided 95 % interval of χ²(3): the 2.5 % and 97.5 % quantiles."""


def position_nees(result, session: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per matched frame: NEES of the IMU position, the error norm [m], the filter's position
    covariance and the phase (0 standing at the start, 1 walking, 2 standing at the end)."""
    t_true, T_true = read_tum(session / "groundtruth" / "imu_frames.tum")
    i, j = match_times(np.round(result.t_s * 1e9), np.round(t_true * 1e9))
    e = T_true[j, :3, 3] - result.T_WfromI_filter[i, :3, 3]
    P = result.cov_p_IinW_filter[i]
    nees = np.einsum("na,na->n", e, np.linalg.solve(P, e[..., None])[..., 0])
    p = T_true[j, :3, 3]
    phase = np.ones(len(p), dtype=int)
    phase[np.linalg.norm(p - T_true[0, :3, 3], axis=1) < 0.05] = 0
    phase[np.linalg.norm(p - T_true[-1, :3, 3], axis=1) < 0.05] = 2
    return nees, np.linalg.norm(e, axis=1), P, phase


def main() -> None:
    parser = ScriptParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("sessions", nargs="+", type=Path)
    parser.add_argument("--set", nargs="*", default=[], metavar="KEY=VALUE")
    parser.add_argument("--smoother", action="store_true", help="also run the smoother")
    args = parser.parse_args()
    logging.basicConfig(level=logging.WARNING)
    cv2.setNumThreads(1)
    overrides = list(args.set)
    if not args.smoother:
        overrides.append("smoother.enabled=false")
    cfg = load_config(VioConfig, ROOT / "configs" / "vio" / "default.yaml", overrides)
    lo, hi = BAND_3DOF_95
    print(
        f"{'session':<22}{'frames':>7}{'mean':>8}{'median':>8}{'in%':>7}{'above%':>8}"
        f"{'below%':>8}{'|e| mm':>8}{'σ mm':>7}{'in% stand/walk/stand':>22}"
        f"{'VO used/skip':>14}{'CPU s':>7}"
    )
    totals: list[np.ndarray] = []
    for session in args.sessions:
        t0 = time.process_time()
        result = run_vio(open_session(session), cfg)
        cpu = time.process_time() - t0
        nees, err, P, phase = position_nees(result, session)
        inside = (nees >= lo) & (nees <= hi)
        by_phase = "/".join(
            f"{100 * inside[phase == k].mean():.0f}" if np.any(phase == k) else "-"
            for k in range(3)
        )
        sigma = np.sqrt(np.trace(P, axis1=1, axis2=2) / 3.0)
        vo_skip = sum(result.skipped.get("vo", {}).values())
        note = "" if result.initialisation == "apriltag" else "  (no tags: world differs)"
        if not note:
            totals.append(nees)
        print(
            f"{session.name:<22}{len(nees):>7}{nees.mean():>8.2f}{np.median(nees):>8.2f}"
            f"{100 * np.mean((nees >= lo) & (nees <= hi)):>7.1f}{100 * np.mean(nees > hi):>8.1f}"
            f"{100 * np.mean(nees < lo):>8.1f}{1e3 * err.mean():>8.1f}{1e3 * sigma.mean():>7.1f}"
            f"{by_phase:>22}{result.used['vo']:>8}/{vo_skip:<5}{cpu:>7.1f}{note}"
        )
    if totals:
        a = np.concatenate(totals)
        print(
            f"{'all':<22}{len(a):>7}{a.mean():>8.2f}{np.median(a):>8.2f}"
            f"{100 * np.mean((a >= lo) & (a <= hi)):>7.1f}{100 * np.mean(a > hi):>8.1f}"
            f"{100 * np.mean(a < lo):>8.1f}"
        )


if __name__ == "__main__":
    from gaitnet.cli.scripts import run_script

    raise SystemExit(run_script(main))
