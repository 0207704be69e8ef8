"""Evaluation metrics (known answers) and the ``gaitnet evaluate`` job on a simulated session."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from gaitnet.errors import InputError, SessionError
from gaitnet.evaluation.evaluate import evaluate_result
from gaitnet.evaluation.metrics import ate_yaw_aligned, match_times, mpjpe, mpjpe_yaw_aligned
from gaitnet.io.trajectory import read_tum, write_tum


def test_mpjpe_known_answer() -> None:
    ref = np.random.default_rng(0).normal(size=(5, 7, 3))
    offset = np.array([0.03, 0.04, 0.0])
    assert mpjpe(ref + offset, ref) == pytest.approx(0.05)


def _yaw(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def test_mpjpe_yaw_aligned_removes_one_world_motion_only() -> None:
    rng = np.random.default_rng(3)
    ref = rng.normal(size=(40, 7, 3)) + np.linspace(0, 5, 40)[:, None, None] * [1.0, 0.2, 0.0]
    moved = ref @ _yaw(0.7).T + [2.0, -1.0, 0.05]
    assert mpjpe_yaw_aligned(moved, ref) < 1e-12
    assert mpjpe(moved, ref) > 1.0
    # a tilt is not a world-frame ambiguity (gravity fixes it), nor is a per-frame error
    roll = np.array([[1, 0, 0], [0, np.cos(0.2), -np.sin(0.2)], [0, np.sin(0.2), np.cos(0.2)]])
    assert mpjpe_yaw_aligned(ref @ roll.T, ref) > 0.05
    wobble = ref.copy()
    wobble[::2] += [0.03, 0.0, 0.0]
    wobble[1::2] -= [0.03, 0.0, 0.0]
    assert mpjpe_yaw_aligned(wobble, ref) == pytest.approx(0.03, rel=1e-3)


def test_mpjpe_yaw_aligned_matches_a_numerical_fit() -> None:
    """The closed form against a generic least-squares fit of yaw and translation."""
    from scipy.optimize import least_squares

    rng = np.random.default_rng(4)
    ref = rng.normal(size=(30, 7, 3)) * [1.0, 1.0, 0.3]
    est = (ref + rng.normal(scale=0.05, size=ref.shape)) @ _yaw(-0.4).T + [0.5, 0.2, -0.1]

    def residuals(x: np.ndarray) -> np.ndarray:
        return (est @ _yaw(x[0]).T + x[1:] - ref).ravel()

    fit = least_squares(residuals, np.zeros(4), xtol=1e-14, ftol=1e-14, gtol=1e-14).x
    expected = mpjpe(est @ _yaw(fit[0]).T + fit[1:], ref)
    assert mpjpe_yaw_aligned(est, ref) == pytest.approx(expected, rel=1e-8)
    assert mpjpe_yaw_aligned(est, ref) < mpjpe(est, ref)
    with pytest.raises(ValueError, match="matching"):
        mpjpe_yaw_aligned(est[:, :3], ref)


def test_ate_ignores_yaw_and_translation_but_not_shape() -> None:
    rng = np.random.default_rng(1)
    ref = np.cumsum(rng.normal(size=(50, 3)), axis=0)
    yaw = 0.7
    R = np.array([[np.cos(yaw), -np.sin(yaw), 0], [np.sin(yaw), np.cos(yaw), 0], [0, 0, 1]])
    moved = ref @ R.T + [1.0, -2.0, 0.3]
    assert ate_yaw_aligned(moved, ref) < 1e-12
    noisy = ref + rng.normal(scale=0.01, size=ref.shape)
    assert 0.005 < ate_yaw_aligned(noisy, ref) < 0.02
    # a roll is not removed by a 4-DoF alignment
    roll = np.array([[1, 0, 0], [0, np.cos(0.3), -np.sin(0.3)], [0, np.sin(0.3), np.cos(0.3)]])
    assert ate_yaw_aligned(ref @ roll.T, ref) > 0.1


def test_match_times_tolerance() -> None:
    i, j = match_times(np.array([100, 2_000_500, 9_000_000]), np.array([0, 2_000_000, 4_000_000]))
    assert i.tolist() == [0, 1] and j.tolist() == [0, 1]


def test_evaluate_job_on_simulated_truth(tmp_path: Path, tiny_sim_session: Path) -> None:
    result = tmp_path / "result"
    result.mkdir()
    gt = tiny_sim_session / "groundtruth"
    with np.load(gt / "joints.npz") as data:
        t_ns, positions = data["t_ns"], data["positions"].copy()
    positions[:, :7] += [0.0, 0.0, 0.02]  # the 7 joints 2 cm up: the same in any world
    positions[::2, :7] += [0.01, 0.0, 0.0]  # and every other frame 1 cm ahead
    positions[1::2, :7] -= [0.01, 0.0, 0.0]
    positions[:, :7] = positions[:, :7] @ _yaw(0.5).T + [3.0, -1.0, 0.0]  # another world
    np.savez(result / "joints.npz", t_ns=t_ns, positions=positions)
    t, T = read_tum(gt / "camera_frames.tum")
    T[:, :3, 3] += [0.5, 0.0, 0.0]
    write_tum(result / "camera_frames.tum", t, T)
    report = evaluate_result(result, tiny_sim_session)
    # the 2 cm lift is a translation of the whole sequence (aligned away); the 1 cm back and
    # forth is not; the world-frame value sees the other origin and heading
    assert report.metrics["mpjpe_aligned_m"] == pytest.approx(0.01, abs=1e-6)
    assert report.metrics["mpjpe_m"] > 1.0
    assert report.metrics["body_ate_m"] < 1e-6
    out = tmp_path / "eval.json"
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "gaitnet.cli",
            "evaluate",
            str(result),
            "--session",
            str(tiny_sim_session),
            "--json",
            str(out),
        ],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 0, proc.stderr
    assert json.loads(out.read_text())["mpjpe_aligned_m"] == pytest.approx(0.01, abs=1e-6)


def test_evaluate_errors(tmp_path: Path, tiny_sim_session: Path) -> None:
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match="nothing to evaluate"):
        evaluate_result(tmp_path / "empty", tiny_sim_session)
    bad = tmp_path / "bad"
    bad.mkdir()
    np.savez(bad / "joints.npz", t_ns=np.arange(3), positions=np.full((3, 9, 3), np.nan))
    with pytest.raises(InputError, match="non-finite joint positions"):
        evaluate_result(bad, tiny_sim_session)
    no_gt = tmp_path / "no_gt"
    shutil.copytree(tiny_sim_session, no_gt, ignore=shutil.ignore_patterns("groundtruth"))
    with pytest.raises(SessionError, match="no ground truth"):
        evaluate_result(bad, no_gt)
