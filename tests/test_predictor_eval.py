"""Predictor evaluation: baselines with known answers, per-horizon metrics, torch vs ONNX."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation

from gaitnet.errors import InputError
from gaitnet.motion.evaluation import (
    constant_velocity,
    evaluate_predictors,
    horizon_errors,
    onnx_predictor,
    torch_predictor,
    zero_velocity,
)
from gaitnet.motion.gcn import DCTGCN, PredictorConfig
from gaitnet.motion.skeleton import builtin_skeleton

SKEL = builtin_skeleton(1.75)
N_PAST, N_FUTURE = 10, 10
FPS = 30.0


def _rotating_windows(n: int, seed: int = 0) -> np.ndarray:
    """Windows where every node rotates at a constant angular rate (body frame)."""
    rng = np.random.default_rng(seed)
    W = N_PAST + N_FUTURE
    out = np.empty((n, W, 21))
    for i in range(n):
        for j in range(7):
            R0 = Rotation.from_rotvec(rng.normal(scale=0.4, size=3))
            omega = rng.normal(scale=0.05, size=3)  # rad per frame
            frames = [R0 * Rotation.from_rotvec(k * omega) for k in range(W)]
            out[i, :, 3 * j : 3 * j + 3] = np.stack([f.as_rotvec() for f in frames])
    return out


def test_zero_velocity_is_exact_on_a_static_pose() -> None:
    pose = np.random.default_rng(1).normal(scale=0.3, size=(4, 1, 21))
    windows = np.repeat(pose, N_PAST + N_FUTURE, axis=1)
    report = evaluate_predictors(windows, {}, SKEL, n_past=N_PAST, fps=FPS)
    zv, cv = report.methods["zero_velocity"], report.methods["constant_velocity"]
    assert zv.mpjpe_m.shape == (10,) and zv.mae_rad.shape == (10,)
    np.testing.assert_allclose(zv.mpjpe_m, 0.0, atol=1e-12)
    np.testing.assert_allclose(zv.mae_rad, 0.0, atol=1e-12)
    np.testing.assert_allclose(cv.mpjpe_m, 0.0, atol=1e-7)  # no motion to extrapolate either


def test_constant_velocity_is_exact_on_constant_angular_rate() -> None:
    windows = _rotating_windows(6)
    pred = constant_velocity(windows[:, :N_PAST], N_FUTURE)
    np.testing.assert_allclose(pred, windows[:, N_PAST:], atol=1e-9)
    report = evaluate_predictors(windows, {}, SKEL, n_past=N_PAST, fps=FPS)
    assert report.methods["constant_velocity"].mpjpe_m.max() < 1e-9
    zv = report.methods["zero_velocity"].mpjpe_m
    assert zv.shape == (10,) and np.all(np.diff(zv) > 0)  # grows with the horizon on motion
    assert (
        report.horizons_ms[0] == pytest.approx(1000 / 30)
        and report.horizons_ms[-1] == 333.3333333333333
    )


def test_constant_velocity_is_not_linear_in_axis_angle() -> None:
    # A large rotation about a tilted axis composed with a step about another axis: the SO(3)
    # extrapolation differs from adding the axis-angle difference.
    windows = _rotating_windows(1, seed=3)
    past = windows[:, :N_PAST]
    linear = past[:, -1:] + np.arange(1, N_FUTURE + 1)[None, :, None] * (
        past[:, -1:] - past[:, -2:-1]
    )
    exact = constant_velocity(past, N_FUTURE)
    assert np.abs(linear - exact).max() > 1e-3
    np.testing.assert_allclose(exact, windows[:, N_PAST:], atol=1e-9)


def test_zero_velocity_repeats_last_pose_and_horizon_errors_shapes() -> None:
    windows = _rotating_windows(3, seed=5)
    pred = zero_velocity(windows[:, :N_PAST], N_FUTURE)
    assert pred.shape == (3, N_FUTURE, 21)
    np.testing.assert_array_equal(pred[:, 4], windows[:, N_PAST - 1])
    s_pos, s_ang = horizon_errors(pred, windows[:, N_PAST:], SKEL)
    assert s_pos.shape == s_ang.shape == (N_FUTURE,)


def test_report_json_has_gcn_and_both_baselines_and_reductions() -> None:
    windows = _rotating_windows(5, seed=7)
    model = DCTGCN(PredictorConfig(hidden=16, n_blocks=1, dropout=0.0))
    report = evaluate_predictors(
        windows, {"gcn": torch_predictor(model)}, SKEL, n_past=N_PAST, fps=FPS
    )
    data = report.to_dict()
    assert set(data["methods"]) == {"gcn", "zero_velocity", "constant_velocity"}
    assert len(data["methods"]["gcn"]["mpjpe_m"]) == 10 and len(data["horizons_ms"]) == 10
    red = data["mpjpe_reduction_vs_baselines"]["gcn"]
    assert set(red) == {"zero_velocity", "constant_velocity"} and len(red["zero_velocity"]) == 10


def test_nan_predictions_are_refused() -> None:
    windows = _rotating_windows(2)
    with pytest.raises(InputError, match="'bad' returned NaN"):
        evaluate_predictors(
            windows, {"bad": lambda p: np.full((p.shape[0], 10, 21), np.nan)}, SKEL,
            n_past=N_PAST, fps=FPS, baselines=False,
        )  # fmt: skip


def test_torch_and_onnx_give_the_same_numbers(tmp_path: Path) -> None:
    from gaitnet.motion.onnx_runtime import OnnxPredictor, export_predictor_onnx

    torch.manual_seed(0)
    model = DCTGCN(PredictorConfig(hidden=16, n_blocks=1, dropout=0.0)).eval()
    path = tmp_path / "m.onnx"
    export_predictor_onnx(model, path)
    windows = _rotating_windows(4, seed=11)
    a = evaluate_predictors(windows, {"gcn": torch_predictor(model)}, SKEL, n_past=10, fps=FPS)
    b = evaluate_predictors(
        windows, {"gcn": onnx_predictor(OnnxPredictor(path))}, SKEL, n_past=10, fps=FPS
    )
    np.testing.assert_allclose(a.methods["gcn"].mpjpe_m, b.methods["gcn"].mpjpe_m, atol=1e-5)


def test_motion_type_benchmark_script(tmp_path: Path) -> None:
    """benchmarks/bench_predictor_motion.py on a folder of AMASS-format clips and an ONNX model."""
    import json
    import subprocess
    import sys

    from amassfactory import walking_like_clip, write_smplh_poses

    from gaitnet.motion.gcn import DCTGCN, PredictorConfig
    from gaitnet.motion.onnx_runtime import export_predictor_onnx

    rng = np.random.default_rng(0)
    poses, trans = walking_like_clip(120, 60.0, rng)
    write_smplh_poses(tmp_path / "clips" / "D" / "s" / "a_walk_poses.npz", poses, trans, 60.0)
    still = np.repeat(poses[:1], 120, axis=0)
    write_smplh_poses(tmp_path / "clips" / "D" / "s" / "b_walk_poses.npz", still,
                      np.repeat(trans[:1], 120, axis=0), 60.0)  # fmt: skip
    model = DCTGCN(PredictorConfig(hidden=8, n_blocks=1, residual="last_pose")).eval()
    export_predictor_onnx(model, tmp_path / "m.onnx")
    script = Path(__file__).parents[1] / "benchmarks" / "bench_predictor_motion.py"
    done = subprocess.run(
        [sys.executable, str(script), "--amass-root", str(tmp_path / "clips"), "--model",
         f"tiny={tmp_path / 'm.onnx'}", "--stride", "3", "--json", str(tmp_path / "r.json")],
        capture_output=True, text=True,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    report = json.loads((tmp_path / "r.json").read_text())
    standing = report["types"]["standing"]  # the still clip: every method is exact
    assert standing["n_windows"] == 14 and standing["methods"]["tiny"]["mean_mm"] == 0.0
    assert (
        sum(t["n_windows"] for k, t in report["types"].items() if k != "all") == report["n_windows"]
    )
    bad = subprocess.run(
        [sys.executable, str(script), "--prepared", str(tmp_path / "none.npz")],
        capture_output=True, text=True,
    )  # fmt: skip
    assert bad.returncode == 1 and bad.stderr.startswith("error: ")
