"""``foot_nmate_m`` (gaitnet.evaluation.feet): invariance to the yaw + translation alignment,
known answers, the frames filled in reported apart, and one-line errors."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from gaitnet.errors import InputError, SessionError
from gaitnet.evaluation.evaluate import evaluate_result
from gaitnet.evaluation.feet import foot_metrics

SIDES = ("left", "right")


def _write(path: Path, t_ns, feet: dict, measured: dict | None = None) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    cols = ["t_ns"] + [f"marker_{s}_{a}" for s in SIDES for a in "xyz"]
    cols += [f"measured_{s}" for s in SIDES] if measured else []
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(cols)
        for k, t in enumerate(t_ns):
            row = [int(t)] + [f"{v:.9f}" for s in SIDES for v in feet[s][k]]
            row += [int(measured[s][k]) for s in SIDES] if measured else []
            w.writerow(row)


def _walk(n: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
    x = np.linspace(0.0, 3.0, n)
    return {
        s: np.stack([x, np.full(n, 0.1 * sign), 0.05 + 0.05 * rng.random(n)], axis=1)
        for s, sign in zip(SIDES, (1, -1), strict=True)
    }


def test_alignment_removes_yaw_and_offset_exactly(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    t = np.arange(50) * 33_333_333
    truth = _walk(50, rng)
    yaw = 0.4
    R = np.array([[np.cos(yaw), -np.sin(yaw), 0], [np.sin(yaw), np.cos(yaw), 0], [0, 0, 1]])
    est = {s: truth[s] @ R.T + [1.0, -2.0, 0.3] for s in SIDES}
    _write(tmp_path / "gt" / "feet.csv", t, truth)
    all_measured = {s: np.ones(50) for s in SIDES}
    _write(tmp_path / "res" / "feet.csv", t, est, all_measured)
    metrics, counts = foot_metrics(tmp_path / "res" / "feet.csv", tmp_path / "gt" / "feet.csv")
    assert metrics["foot_nmate_m"] == pytest.approx({"left": 0.0, "right": 0.0}, abs=1e-8)
    assert "foot_nmate_filled_m" not in metrics
    assert counts["foot_frames"] == 50


def test_known_error_and_filled_frames(tmp_path: Path) -> None:
    """A vertical error of +2 cm on half the frames and −2 cm on the other half survives the
    alignment (its mean is zero): |e| = 2 cm on every frame, the NMATE is 0.02."""
    rng = np.random.default_rng(1)
    n = 40
    t = 1_000 + np.arange(n) * 33_333_333
    truth = _walk(n, rng)
    sign = np.where(np.arange(n) % 2 == 0, 1.0, -1.0)
    est = {s: truth[s] + np.outer(sign * 0.02, [0, 0, 1]) for s in SIDES}
    est["right"] = truth["right"].copy()
    est["right"][10:20, 0] += 0.05  # a gap filled 5 cm ahead
    measured = {s: np.ones(n) for s in SIDES}
    measured["right"][10:20] = 0
    _write(tmp_path / "gt" / "feet.csv", t, truth)
    _write(tmp_path / "res" / "feet.csv", t, est, measured)
    (tmp_path / "gt" / "groundtruth").mkdir()
    (tmp_path / "gt" / "feet.csv").rename(tmp_path / "gt" / "groundtruth" / "feet.csv")
    report = evaluate_result(tmp_path / "res", tmp_path / "gt")
    assert report.metrics["foot_nmate_m"]["left"] == pytest.approx(0.02, abs=1e-6)
    # independent: the 4-DoF alignment of the right foot shifts x by the mean error 1.25 cm
    e = np.zeros((n, 3))
    e[10:20, 0] = 0.05
    e[:, 0] -= e[:, 0].mean()
    assert report.metrics["foot_nmate_m"]["right"] == pytest.approx(
        np.abs(e).mean(axis=0)[0], abs=1e-3
    )
    assert report.metrics["foot_nmate_filled_m"]["right"] == pytest.approx(0.0375, abs=1e-3)
    assert report.counts["foot_frames_filled_right"] == 10


def test_feet_errors_name_the_file(tmp_path: Path) -> None:
    rng = np.random.default_rng(2)
    t = np.arange(5) * 10
    truth = _walk(5, rng)
    _write(tmp_path / "gt" / "feet.csv", t, truth)
    bad = tmp_path / "res" / "feet.csv"
    _write(bad, t, truth)  # no measured columns
    with pytest.raises(InputError, match="feet.csv: missing column"):
        foot_metrics(bad, tmp_path / "gt" / "feet.csv")
    nan = {s: truth[s].copy() for s in SIDES}
    nan["left"][2, 1] = np.nan
    _write(bad, t, nan, {s: np.ones(5) for s in SIDES})
    with pytest.raises(InputError, match="non-finite left"):
        foot_metrics(bad, tmp_path / "gt" / "feet.csv")
    _write(bad, t[::-1], truth, {s: np.ones(5) for s in SIDES})
    with pytest.raises(InputError, match="increase"):
        foot_metrics(bad, tmp_path / "gt" / "feet.csv")
    _write(bad, t + 10**9, truth, {s: np.ones(5) for s in SIDES})
    with pytest.raises(InputError, match="fewer than 2 frames"):
        foot_metrics(bad, tmp_path / "gt" / "feet.csv")
    (tmp_path / "gt" / "feet.csv").write_text("t_ns\n")
    _write(bad, t, truth, {s: np.ones(5) for s in SIDES})
    with pytest.raises(SessionError, match="no rows|missing column"):
        foot_metrics(bad, tmp_path / "gt" / "feet.csv")
