"""``gaitnet evaluate``: compare a result folder with a session's ground truth.

Reads whatever the result folder holds and reports the contract keys (docs/design.md) that the
inputs allow, in SI units:

- ``mpjpe_m`` from ``RESULT_DIR/joints.npz`` (same layout as ``groundtruth/joints.npz``:
  ``t_ns`` (n,) integer nanoseconds and ``positions`` (n, 9, 3) of SMPL joints
  [0, 1, 2, 4, 5, 7, 8, 10, 11]); the mean over matched frames of the 7 lower-body joints
  (pelvis, hips, knees, ankles), eq. (4.5), :func:`gaitnet.evaluation.metrics.mpjpe`, in the
  session's world frame, which the result shares where the session's start sheet set its
  world (AprilTags); ``mpjpe_aligned_m`` the same after one yaw + translation alignment of all
  those joints over the session to the truth
  (:func:`gaitnet.evaluation.metrics.mpjpe_yaw_aligned`, as ``body_ate_m`` and
  ``foot_nmate_m`` are aligned): the value to read where the result's world has its own
  origin and heading (no AprilTag sheet decoded: the filter starts from gravity, the floor
  and yaw 0);
- ``body_ate_m`` from ``RESULT_DIR/camera_frames.tum``: RMS camera-position error after a
  yaw + translation alignment to ``groundtruth/camera_frames.tum``;
- ``stride_rmse_m`` {left, right, all}, ``stride_max_err_m`` {left, right} and ``n_strides``
  {left, right} from ``RESULT_DIR/strides.csv`` against ``groundtruth/strides.csv``: strides
  matched in time, the unmatched ones counted in ``counts``
  (:mod:`gaitnet.evaluation.strides`).

- ``pixel_acc``, ``miou``, ``fw_iou`` and ``iou`` {background, foot, leg} from
  ``RESULT_DIR/labels/*.png`` (``gaitnet segment``) against the session's
  ``groundtruth/labels/`` or a labelled set's ``labels/`` or labelme JSON
  (:mod:`gaitnet.evaluation.label_maps`); ``SESSION`` may then be a labelled set.

- ``foot_nmate_m`` {left, right}, ``foot_nmate_filled_m`` {left, right} (the frames filled by
  prediction) and ``foot_rmse_m`` from ``RESULT_DIR/feet.csv`` against ``groundtruth/feet.csv``
  after a per-foot yaw + translation alignment (:mod:`gaitnet.evaluation.feet`).

Every input is checked where it is read: a result folder that is missing or a file, a
``joints.npz`` that is not a readable archive of the right keys, dtypes and shapes, NaN or inf
anywhere, times that are not strictly increasing or match no ground-truth frame, or a session
without the ground truth that a result file needs, raise :class:`~gaitnet.errors.InputError`
(the result) or :class:`~gaitnet.errors.SessionError` (the session) with one line naming the
file. A metric that is not finite is never reported.
"""

from __future__ import annotations

import json
import logging
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from gaitnet.errors import GaitnetError, InputError, SessionError
from gaitnet.evaluation.feet import FEET_FILE, foot_metrics
from gaitnet.evaluation.label_maps import LABELS_DIR, evaluate_label_maps
from gaitnet.evaluation.metrics import ate_yaw_aligned, match_times, mpjpe, mpjpe_yaw_aligned
from gaitnet.evaluation.strides import read_strides, stride_metrics
from gaitnet.io.atomic import atomic_write_text
from gaitnet.io.npz import npz_array, open_npz
from gaitnet.io.trajectory import read_tum

log = logging.getLogger(__name__)

__all__ = [
    "JOINTS_FILE",
    "STRIDES_FILE",
    "TRAJECTORY_FILE",
    "ResultEvaluation",
    "evaluate_result",
    "write_report",
]

JOINTS_FILE = "joints.npz"
TRAJECTORY_FILE = "camera_frames.tum"
STRIDES_FILE = "strides.csv"
LOWER_BODY = slice(0, 7)  # rows of the 9-joint arrays that are the 7-joint lower body
_N_JOINTS = 9


@dataclass(frozen=True)
class ResultEvaluation:
    """Metrics of one result folder against a session's ground truth (finite SI values) and
    how many frames/poses each was computed from; :meth:`to_json` is the contract JSON."""

    metrics: dict[str, float | dict[str, float]] = field(default_factory=dict)
    counts: dict[str, int] = field(default_factory=dict)

    def to_json(self) -> str:
        """One JSON object: the metric keys plus ``counts``."""
        return json.dumps({**self.metrics, "counts": self.counts}, indent=2, sort_keys=True)


def _load_joints(path: Path, error: type[GaitnetError]) -> tuple[np.ndarray, np.ndarray]:
    """``t_ns`` (n,) int64 and ``positions`` (n, 9, 3) float64 of a joints file, checked."""
    with open_npz(path, "a joints file (t_ns, positions)", error) as data:
        missing = [k for k in ("t_ns", "positions") if k not in data.files]
        if missing:
            raise error(f"{path}: missing key(s) {missing}")
        t_ns = npz_array(data, path, "t_ns", error)
        positions = npz_array(data, path, "positions", error)
    if t_ns.dtype.kind not in "iu" or t_ns.ndim != 1:
        raise error(f"{path}: 't_ns' must be a 1-D integer array, got {t_ns.dtype} {t_ns.shape}")
    if t_ns.dtype.kind == "u" and t_ns.size and int(t_ns.max()) > np.iinfo(np.int64).max:
        raise error(f"{path}: 't_ns' holds values too large for nanosecond timestamps")
    if positions.dtype.kind not in "iuf":
        raise error(f"{path}: 'positions' must hold numbers, got {positions.dtype}")
    if positions.ndim != 3 or positions.shape[1:] != (_N_JOINTS, 3):
        raise error(f"{path}: 'positions' must be (n, {_N_JOINTS}, 3), got {positions.shape}")
    if len(t_ns) != len(positions):
        raise error(f"{path}: {len(t_ns)} 't_ns' for {len(positions)} frames of 'positions'")
    if len(t_ns) == 0:
        raise error(f"{path}: no frames")
    t_ns = t_ns.astype(np.int64)
    steps = np.flatnonzero(np.diff(t_ns) <= 0)
    if steps.size:
        k = int(steps[0]) + 1
        raise error(
            f"{path}: 't_ns' must be strictly increasing, but frame {k} has t_ns {t_ns[k]} "
            f"after {t_ns[k - 1]}"
        )
    positions = positions.astype(np.float64)
    if not np.all(np.isfinite(positions)):
        raise error(f"{path}: non-finite joint positions")
    return t_ns, positions


def _load_trajectory(path: Path, error: type[GaitnetError]) -> tuple[np.ndarray, np.ndarray]:
    """Times [s] and positions (n, 3) of a TUM file, every value finite."""
    if not path.is_file():
        raise error(f"{path}: trajectory file not found")
    t, T = read_tum(path, error)
    p = T[:, :3, 3]
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(p))):
        raise error(f"{path}: non-finite times or positions")
    if np.max(np.abs(t)) > 9e9:  # nanoseconds must fit int64
        raise error(f"{path}: timestamps beyond year 2255 (seconds expected)")
    return t, p


def _own_world(result_dir: Path) -> bool:
    """Whether the result's ``summary.json`` (``gaitnet infer``) says its world frame was not
    set by an AprilTag sheet; False where it says nothing readable about it."""
    try:
        summary = json.loads((result_dir / "summary.json").read_text(encoding="utf-8"))
        return summary["world_frame"]["initialisation"] != "apriltag"
    except (OSError, ValueError, KeyError, TypeError):
        return False


def _finite(path: Path, name: str, value: float) -> float:
    if not math.isfinite(value):
        raise InputError(f"{path}: {name} is not finite (values too large?)")
    return value


def evaluate_result(result_dir: str | Path, session_dir: str | Path) -> ResultEvaluation:
    """Metrics of ``result_dir`` against ``session_dir/groundtruth`` (module docstring)."""
    result_dir, session_dir = Path(result_dir), Path(session_dir)
    gt = session_dir / "groundtruth"
    if not result_dir.exists():
        raise InputError(f"{result_dir}: result folder not found")
    if not result_dir.is_dir():
        raise InputError(f"{result_dir}: is not a folder (give the result folder)")
    if not session_dir.is_dir():
        raise SessionError(f"{session_dir}: session folder not found")
    metrics: dict[str, float | dict[str, float]] = {}
    counts: dict[str, int] = {}
    labels = result_dir / LABELS_DIR
    if labels.is_dir():
        found, n = evaluate_label_maps(labels, session_dir)
        metrics.update(found)
        counts.update(n)
    needs_gt = not labels.is_dir() or any(
        (result_dir / f).exists() for f in (JOINTS_FILE, TRAJECTORY_FILE, STRIDES_FILE, FEET_FILE)
    )
    if needs_gt and not gt.is_dir():
        raise SessionError(f"{gt}: no ground truth (only simulated sessions have it)")
    joints = result_dir / JOINTS_FILE
    if joints.exists():
        t_est, p_est = _load_joints(joints, InputError)
        t_ref, p_ref = _load_joints(gt / JOINTS_FILE, SessionError)
        i, j = match_times(t_est, t_ref)
        if len(i) == 0:
            raise InputError(f"{joints}: no frame matches the ground truth's times")
        est, ref = p_est[i][:, LOWER_BODY], p_ref[j][:, LOWER_BODY]
        with np.errstate(over="ignore", invalid="ignore"):  # reported below, not warned
            world = mpjpe(est, ref)
            aligned = mpjpe_yaw_aligned(est, ref) if np.isfinite(world) else world
        metrics["mpjpe_m"] = _finite(joints, "MPJPE", world)
        metrics["mpjpe_aligned_m"] = _finite(joints, "MPJPE", aligned)
        if _own_world(result_dir):
            log.warning(
                "%s: the result's world was set by gravity and the floor (no AprilTag sheet), "
                "not by the session's sheet: mpjpe_m compares different frames, read "
                "mpjpe_aligned_m",
                result_dir,
            )
        counts["mpjpe_frames"] = int(len(i))
    trajectory = result_dir / TRAJECTORY_FILE
    if trajectory.exists():
        t_est, p_est = _load_trajectory(trajectory, InputError)
        t_ref, p_ref = _load_trajectory(gt / TRAJECTORY_FILE, SessionError)
        i, j = match_times(np.round(t_est * 1e9), np.round(t_ref * 1e9))
        if len(i) < 2:
            raise InputError(f"{trajectory}: fewer than 2 poses match the ground truth's times")
        with np.errstate(over="ignore", invalid="ignore"):
            value = ate_yaw_aligned(p_est[i], p_ref[j])
        metrics["body_ate_m"] = _finite(trajectory, "ATE", value)
        counts["ate_poses"] = int(len(i))
    strides = result_dir / STRIDES_FILE
    if strides.exists():
        found, unmatched = stride_metrics(
            read_strides(strides, InputError), read_strides(gt / STRIDES_FILE, SessionError)
        )
        metrics.update(found)  # type: ignore[arg-type]
        counts.update(unmatched)
    feet = result_dir / FEET_FILE
    if feet.exists():
        found_feet, n_feet = foot_metrics(feet, gt / FEET_FILE)
        metrics.update(found_feet)  # type: ignore[arg-type]
        counts.update(n_feet)
    if not metrics:
        raise InputError(
            f"{result_dir}: nothing to evaluate (expected {JOINTS_FILE}, {TRAJECTORY_FILE}, "
            f"{STRIDES_FILE}, {FEET_FILE} and/or {LABELS_DIR}/)"
        )
    return ResultEvaluation(metrics, counts)


def write_report(report: ResultEvaluation, path: str | Path) -> None:
    """Write :meth:`ResultEvaluation.to_json` atomically (a folder at ``path`` is an error)."""
    atomic_write_text(path, report.to_json() + "\n")
