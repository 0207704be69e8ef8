"""``gaitnet evaluate``: compare a result folder with a session's ground truth.

Reads whatever the result folder holds and reports the contract keys (DESIGN.md) that the
inputs allow, in SI units:

- ``mpjpe_m`` from ``RESULT_DIR/joints.npz`` (same layout as ``groundtruth/joints.npz``:
  ``t_ns`` and ``positions`` (n, 9, 3) of SMPL joints [0, 1, 2, 4, 5, 7, 8, 10, 11]); the mean
  over matched frames of the 7 lower-body joints (pelvis, hips, knees, ankles), eq. (4.5);
- ``body_ate_m`` from ``RESULT_DIR/camera_frames.tum``: RMS camera-position error after a
  yaw + translation alignment to ``groundtruth/camera_frames.tum``.

More keys (strides, foot trajectories, segmentation) join as the stages producing them land.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from gaitnet.errors import SessionError
from gaitnet.evaluation.metrics import ate_yaw_aligned, match_times, mpjpe
from gaitnet.io.atomic import atomic_write_text
from gaitnet.io.trajectory import read_tum

LOWER_BODY = slice(0, 7)  # rows of the 9-joint arrays that are the 7-joint lower body


@dataclass(frozen=True)
class EvaluationReport:
    metrics: dict[str, float] = field(default_factory=dict)
    counts: dict[str, int] = field(default_factory=dict)

    def to_json(self) -> str:
        return json.dumps({**self.metrics, "counts": self.counts}, indent=2, sort_keys=True)


def _load_joints(path: Path) -> tuple[np.ndarray, np.ndarray]:
    try:
        with np.load(path, allow_pickle=False) as data:
            t_ns, positions = data["t_ns"], data["positions"]
    except KeyError as exc:
        raise SessionError(f"{path}: missing key {exc}") from exc
    except (OSError, ValueError) as exc:
        raise SessionError(f"{path}: not a readable joints file ({exc})") from exc
    if positions.ndim != 3 or positions.shape[1:] != (9, 3) or len(t_ns) != len(positions):
        raise SessionError(f"{path}: 'positions' must be (n, 9, 3) with one t_ns per frame")
    if not np.all(np.isfinite(positions)):
        raise SessionError(f"{path}: non-finite joint positions")
    return t_ns.astype(np.int64), positions


def evaluate_result(result_dir: str | Path, session_dir: str | Path) -> EvaluationReport:
    """Metrics of ``result_dir`` against ``session_dir/groundtruth`` (module docstring)."""
    result_dir, gt = Path(result_dir), Path(session_dir) / "groundtruth"
    if not result_dir.is_dir():
        raise SessionError(f"{result_dir}: result folder not found")
    if not gt.is_dir():
        raise SessionError(f"{gt}: no ground truth (only simulated sessions have it)")
    metrics: dict[str, float] = {}
    counts: dict[str, int] = {}
    if (result_dir / "joints.npz").is_file():
        t_est, p_est = _load_joints(result_dir / "joints.npz")
        t_ref, p_ref = _load_joints(gt / "joints.npz")
        i, j = match_times(t_est, t_ref)
        if len(i) == 0:
            raise SessionError(f"{result_dir / 'joints.npz'}: no frame matches the ground truth")
        metrics["mpjpe_m"] = mpjpe(p_est[i, LOWER_BODY], p_ref[j, LOWER_BODY])
        counts["mpjpe_frames"] = int(len(i))
    if (result_dir / "camera_frames.tum").is_file():
        t_est, T_est = read_tum(result_dir / "camera_frames.tum")
        t_ref, T_ref = read_tum(gt / "camera_frames.tum")
        i, j = match_times(np.round(t_est * 1e9), np.round(t_ref * 1e9))
        if len(i) < 2:
            raise SessionError(f"{result_dir / 'camera_frames.tum'}: < 2 poses match")
        metrics["body_ate_m"] = ate_yaw_aligned(T_est[i, :3, 3], T_ref[j, :3, 3])
        counts["ate_poses"] = int(len(i))
    if not metrics:
        raise SessionError(
            f"{result_dir}: nothing to evaluate (expected joints.npz and/or camera_frames.tum)"
        )
    return EvaluationReport(metrics, counts)


def write_report(report: EvaluationReport, path: str | Path) -> None:
    atomic_write_text(path, report.to_json() + "\n")
