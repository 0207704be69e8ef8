"""Foot-trajectory error ``foot_nmate_m`` {left, right} (thesis sec. 5.2.3, Table 5.3).

A result's ``feet.csv`` has the layout of a simulated session's ``groundtruth/feet.csv`` for the
shoe markers — ``t_ns``, ``marker_{left,right}_{x,y,z}`` (world frame, metres) — and one column
``measured_{left,right}`` (1 where the segmenter saw that foot in the frame, 0 where the pose
correction filled the frame from the motion predictor: the swing gaps of thesis Fig. 5.10).

NMATE, the thesis's "norm of the mean of the absolute trajectory error", after aligning the
estimate to the ground truth as in Zhang & Scaramuzza (IROS 2018, the thesis's [66]): per foot,
the rotation about z and translation that best map the estimated trajectory onto the true one
over all matched frames (:func:`gaitnet.evaluation.metrics.align_yaw_translation`, the 4-DoF
alignment of visual-inertial trajectories, whose yaw and position are unobservable), then
``‖mean_k |e_k|‖`` with ``e_k`` the aligned error vector of frame ``k`` and ``|·|`` taken per
axis. ``foot_nmate_filled_m`` is the same over the frames filled in only (with the
alignment of all frames), ``foot_rmse_m`` the RMS of ``‖e_k‖`` for comparison with other
tools.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from gaitnet.errors import InputError, SessionError
from gaitnet.evaluation.metrics import align_yaw_translation, match_times

__all__ = ["FEET_FILE", "foot_metrics", "read_feet"]

FEET_FILE = "feet.csv"
SIDES = ("left", "right")


def read_feet(
    path: Path, error: type[InputError] | type[SessionError], measured: bool
) -> tuple[np.ndarray, dict[str, np.ndarray], dict[str, np.ndarray]]:
    """``t_ns`` (n,), marker positions per side (n, 3) and, with ``measured``, the measured
    flags per side (n,) bool of a ``feet.csv``; every value checked (one-line errors)."""
    try:
        with open(path, newline="", encoding="utf-8") as f:
            rows = list(csv.DictReader(f))
    except UnicodeDecodeError:
        raise error(f"{path}: not a UTF-8 CSV file") from None
    need = ["t_ns"] + [f"marker_{s}_{a}" for s in SIDES for a in "xyz"]
    need += [f"measured_{s}" for s in SIDES] if measured else []
    if not rows:
        raise error(f"{path}: no rows")
    missing = [c for c in need if c not in rows[0]]
    if missing:
        raise error(f"{path}: missing column(s) {', '.join(missing)}")
    try:
        t = np.array([int(r["t_ns"]) for r in rows], dtype=np.int64)
        p = {
            s: np.array([[float(r[f"marker_{s}_{a}"]) for a in "xyz"] for r in rows]) for s in SIDES
        }
        m = {s: np.array([int(r[f"measured_{s}"]) for r in rows]) for s in SIDES if measured}
    except (TypeError, ValueError, OverflowError) as exc:
        raise error(f"{path}: a value is not a number ({exc})") from None
    if np.any(np.diff(t) <= 0):
        raise error(f"{path}: t_ns must increase strictly")
    for s in SIDES:
        if not np.all(np.isfinite(p[s])):
            raise error(f"{path}: non-finite {s} marker positions")
        if measured and not np.all(np.isin(m[s], (0, 1))):
            raise error(f"{path}: measured_{s} must be 0 or 1")
    return t, p, {s: v.astype(bool) for s, v in m.items()}


def _nmate(err: np.ndarray) -> float:
    return float(np.linalg.norm(np.mean(np.abs(err), axis=0)))


def foot_metrics(
    result_feet: Path, reference_feet: Path
) -> tuple[dict[str, dict[str, float]], dict[str, int]]:
    """``foot_nmate_m``, ``foot_nmate_filled_m`` and ``foot_rmse_m`` per side (module docstring)
    and the matched / filled frame counts."""
    t_est, p_est, measured = read_feet(result_feet, InputError, measured=True)
    t_ref, p_ref, _ = read_feet(reference_feet, SessionError, measured=False)
    i, j = match_times(t_est, t_ref)
    if len(i) < 2:
        raise InputError(f"{result_feet}: fewer than 2 frames match the ground truth's times")
    nmate: dict[str, float] = {}
    filled: dict[str, float] = {}
    rmse: dict[str, float] = {}
    counts = {"foot_frames": int(len(i))}
    for s in SIDES:
        R, t = align_yaw_translation(p_est[s][i], p_ref[s][j])
        err = p_est[s][i] @ R.T + t - p_ref[s][j]
        nmate[s] = _nmate(err)
        rmse[s] = float(np.sqrt(np.mean(np.sum(err**2, axis=1))))
        gap = ~measured[s][i]
        counts[f"foot_frames_filled_{s}"] = int(gap.sum())
        if gap.any():
            filled[s] = _nmate(err[gap])
    metrics = {"foot_nmate_m": nmate, "foot_rmse_m": rmse}
    if filled:
        metrics["foot_nmate_filled_m"] = filled
    return metrics, counts
