"""Whole simulated sessions: reader acceptance, determinism, ground truth consistency."""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pytest

from gaitnet.config import load_config
from gaitnet.io import SessionFolder
from gaitnet.io.trajectory import read_tum
from gaitnet.sim.config import SimConfig
from gaitnet.sim.gait import generate_walk
from gaitnet.sim.imu import ImuConfig, simulate_imu
from gaitnet.sim.scene_setup import rng_streams
from gaitnet.sim.session import simulate_session
from gaitnet.sim.strapdown import integrate_imu
from gaitnet.sim.subject import sample_subject

CONFIG = Path(__file__).parents[1] / "configs" / "sim" / "tiny.yaml"
FAST = ["camera.fps=6", "output.preview_frames=2"]


def tree_digest(root: Path) -> dict[str, str]:
    return {
        str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(root.rglob("*"))
        if p.is_file()
    }


@pytest.fixture(scope="module")
def tiny_sim(tiny_sim_session: Path) -> Path:
    """The shared tiny session (conftest): tiny.yaml + FAST overrides, seed 3."""
    return tiny_sim_session


def test_reader_accepts_simulated_session(tiny_sim: Path) -> None:
    session = SessionFolder(tiny_sim)
    assert len(session) > 10
    frame = session.frame(len(session) // 2)
    assert frame.rgb.shape == (120, 160, 3) and frame.depth_m.shape == (120, 160)
    valid = frame.depth_m[frame.depth_m > 0]
    assert 0.3 < np.median(valid) < 3.0
    assert session.calibration.imu_noise is not None
    assert len(session.calibration.apriltag_boards) == 2
    times = session.frame_times_ns * 1e-9
    assert session.imu.t_ns[0] <= session.frame_times_ns[0]
    assert np.allclose(np.diff(times), 1 / 6, atol=1e-6)
    for name in [
        "camera_frames.tum",
        "imu_imurate.tum",
        "joints.npz",
        "events.csv",
        "strides.csv",
        "feet.csv",
        "marker_pixels.csv",
        "subject.yaml",
    ]:
        assert (tiny_sim / "groundtruth" / name).is_file(), name
    labels = sorted((tiny_sim / "groundtruth" / "labels").iterdir())
    assert len(labels) == len(session)
    assert (tiny_sim / "preview.png").is_file() and (tiny_sim / "sim_config.yaml").is_file()


def test_same_seed_same_bytes_other_seed_differs(tiny_sim: Path, tmp_path: Path) -> None:
    cfg = load_config(SimConfig, CONFIG, FAST)
    again = simulate_session(cfg, 3, tmp_path / "again").path
    assert tree_digest(again) == tree_digest(tiny_sim)
    other = simulate_session(cfg, 4, tmp_path / "other").path
    a = (tiny_sim / "groundtruth" / "subject.yaml").read_text()
    b = (other / "groundtruth" / "subject.yaml").read_text()
    assert a != b
    assert (
        SessionFolder(other).calibration.extra != SessionFolder(tiny_sim).calibration.extra
        or (SessionFolder(other).frame(0).rgb != SessionFolder(tiny_sim).frame(0).rgb).any()
    )


def test_resolved_config_reproduces(tiny_sim: Path) -> None:
    cfg = load_config(SimConfig, tiny_sim / "sim_config.yaml")
    assert cfg == load_config(SimConfig, CONFIG, FAST)


def test_camera_trajectory_matches_imu_trajectory_and_extrinsic(tiny_sim: Path) -> None:
    session = SessionFolder(tiny_sim)
    t_c, T_WC = read_tum(tiny_sim / "groundtruth" / "camera_frames.tum")
    t_i, T_WI = read_tum(tiny_sim / "groundtruth" / "imu_frames.tum")
    np.testing.assert_allclose(t_c, t_i)
    T_CI = np.linalg.inv(T_WC) @ T_WI
    np.testing.assert_allclose(
        T_CI, np.broadcast_to(session.calibration.T_CfromI, T_CI.shape), atol=1e-6
    )


def test_stance_soles_do_not_slip(tiny_sim: Path) -> None:
    import csv

    rows = list(csv.DictReader((tiny_sim / "groundtruth" / "events.csv").read_text().splitlines()))
    assert {r["side"] for r in rows} == {"left", "right"}
    feet = np.loadtxt(tiny_sim / "groundtruth" / "feet.csv", delimiter=",", skiprows=1)
    t = feet[:, 0] * 1e-9
    soles = {"left": feet[:, 7:10], "right": feet[:, 10:13]}
    checked = 0
    for r in rows:
        inside = (t >= float(r["flat_start_s"])) & (t <= float(r["flat_end_s"]))
        if inside.sum() >= 2:
            p = soles[r["side"]][inside]
            assert np.linalg.norm(p - p[0], axis=1).max() < 0.002
            checked += 1
    assert checked >= 3


def test_noise_free_imu_reproduces_walk_trajectory() -> None:
    """Issue criterion: integrate the noise-free IMU from the true initial state: < 1 cm / 10 s."""
    cfg = load_config(SimConfig, None, ["gait.walk_length_m=7"])
    rngs = rng_streams(5)
    subject = sample_subject(rngs["subject"])
    walk = generate_walk(subject, cfg.gait, rngs["gait"])
    T_PfromI = cfg.mount.T_PfromC() @ cfg.mount.T_CfromI()
    imu_cfg = ImuConfig(noise_free=True)
    samples, truth = simulate_imu(
        walk.pelvis_kinematics, T_PfromI, 0.0, 10.0, imu_cfg, np.random.default_rng(0)
    )
    p_est, _ = integrate_imu(
        samples.t_ns * 1e-9,
        samples.accel,
        samples.gyro,
        truth.R_WfromI[0],
        truth.p_IinW[0],
        truth.v_IinW[0],
        imu_cfg.gravity_mps2,
    )
    err = np.linalg.norm(p_est - truth.p_IinW, axis=1)
    assert err.max() < 0.01
    assert np.linalg.norm(truth.p_IinW[-1] - truth.p_IinW[0]) > 3.0  # it really walked


def test_foot_markers_land_on_foot_labels(tiny_sim: Path) -> None:
    data = np.genfromtxt(
        tiny_sim / "groundtruth" / "marker_pixels.csv",
        delimiter=",",
        names=True,
        dtype=None,
        encoding="utf-8",
    )
    visible = data["visible"] == 1
    assert visible.sum() >= 5
    assert data["on_foot_label"][visible].mean() >= 0.99


def test_unknown_config_key_is_named(tmp_path: Path) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("gait:\n  sped_mps: 1.0\n")
    from gaitnet.errors import ConfigError

    with pytest.raises(ConfigError, match=r"bad.yaml: unknown key 'gait.sped_mps'"):
        load_config(SimConfig, bad)
