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
from gaitnet.evaluation.metrics import ate_yaw_aligned, match_times, mpjpe
from gaitnet.io.trajectory import read_tum, write_tum


def test_mpjpe_known_answer() -> None:
    ref = np.random.default_rng(0).normal(size=(5, 7, 3))
    offset = np.array([0.03, 0.04, 0.0])
    assert mpjpe(ref + offset, ref) == pytest.approx(0.05)


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
    positions[:, :7] += [0.0, 0.0, 0.02]
    np.savez(result / "joints.npz", t_ns=t_ns, positions=positions)
    t, T = read_tum(gt / "camera_frames.tum")
    T[:, :3, 3] += [0.5, 0.0, 0.0]
    write_tum(result / "camera_frames.tum", t, T)
    report = evaluate_result(result, tiny_sim_session)
    assert report.metrics["mpjpe_m"] == pytest.approx(0.02, abs=1e-9)
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
    assert json.loads(out.read_text())["mpjpe_m"] == pytest.approx(0.02, abs=1e-9)


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
