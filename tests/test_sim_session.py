"""Whole simulated sessions: reader acceptance, determinism, ground truth consistency."""

from __future__ import annotations

import hashlib
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from gaitnet.config import load_config
from gaitnet.errors import GaitnetError, InputError
from gaitnet.io import SessionFolder
from gaitnet.io.trajectory import read_tum
from gaitnet.sim.config import SimConfig
from gaitnet.sim.gait import generate_walk
from gaitnet.sim.imu import ImuConfig, simulate_imu
from gaitnet.sim.scene_setup import build_scene, rng_streams
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
    # Frame timestamps: the 1/6 s grid with sub-millisecond jitter, now and then a frame left
    # out (timing.frame_drop_rate): every interval is a whole number of periods within 2 ms.
    periods = np.diff(times) * 6
    assert np.all(np.abs(periods - np.round(periods)) * (1 / 6) < 0.002)
    assert np.all(np.round(periods) >= 1) and np.all(np.round(periods) <= 2)
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


def test_output_compress_frames_deflates_colour_and_depth(tiny_sim: Path, tmp_path: Path) -> None:
    """The default stores the frames uncompressed; compress_frames=true gives the same pixels
    in smaller files and leaves the ground truth's bytes alone."""
    cfg = load_config(SimConfig, CONFIG, [*FAST, "output.compress_frames=true"])
    packed = simulate_session(cfg, 3, tmp_path / "packed").path
    stored, deflated = SessionFolder(tiny_sim), SessionFolder(packed)
    for k in (0, len(stored) // 2):
        a, b = stored.frame(k), deflated.frame(k)
        np.testing.assert_array_equal(a.rgb, b.rgb)
        np.testing.assert_array_equal(a.depth_m, b.depth_m)
    for sub in ("color", "depth"):
        small = sum(p.stat().st_size for p in (packed / sub).iterdir())
        large = sum(p.stat().st_size for p in (tiny_sim / sub).iterdir())
        assert small < 0.8 * large, sub
    digest = tree_digest(tiny_sim / "groundtruth")
    assert tree_digest(packed / "groundtruth") == digest


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


def test_pitch_range_draws_one_pitch_per_session_and_records_it(tmp_path: Path) -> None:
    cfg = load_config(SimConfig, CONFIG, [*FAST, "mount.pitch_deg=[40, 60]", "camera.fps=2"])
    pitches = []
    for seed in (1, 2):
        out = simulate_session(cfg, seed, tmp_path / f"s{seed}").path
        pitch = SessionFolder(out).calibration.extra["mount_pitch_deg"]
        assert 40.0 <= pitch <= 60.0
        # Standing upright at the first frame: gravity in the camera is (0, cos p, sin p).
        _, T_WC = read_tum(out / "groundtruth" / "camera_frames.tum")
        g_C = T_WC[0, :3, :3].T @ np.array([0.0, 0.0, -1.0])
        p = np.radians(pitch)
        np.testing.assert_allclose(g_C, [0.0, np.cos(p), np.sin(p)], atol=0.02)
        pitches.append(pitch)
    assert pitches[0] != pitches[1]
    # The pitch has its own random stream: the rest of the world does not depend on it.
    fixed = load_config(SimConfig, CONFIG, [*FAST, "camera.fps=2"])
    drawn, level = build_scene(cfg, rng_streams(1)), build_scene(fixed, rng_streams(1))
    assert drawn.pitch_deg == pytest.approx(pitches[0], abs=1e-6) and level.pitch_deg == 70.0
    assert drawn.subject == level.subject and drawn.light == level.light
    assert drawn.floor_family == level.floor_family
    assert drawn.exposure_gain == level.exposure_gain
    np.testing.assert_array_equal(drawn.floor.levels[0], level.floor.levels[0])


@pytest.mark.parametrize("seed", [-1, 2**32, True, 1.5])
def test_bad_seed_is_an_input_error_before_anything_is_written(tmp_path: Path, seed) -> None:
    with pytest.raises(InputError, match="seed"):
        simulate_session(load_config(SimConfig, CONFIG, FAST), seed, tmp_path / "out")
    assert list(tmp_path.iterdir()) == []


def test_output_that_is_a_file_is_refused_before_any_work(tmp_path: Path, monkeypatch) -> None:
    import gaitnet.sim.session as session_module

    def no_work(*args, **kwargs):
        raise AssertionError("the scene was built before the output path was checked")

    monkeypatch.setattr(session_module, "build_scene", no_work)
    target = tmp_path / "file"
    target.write_text("keep")
    with pytest.raises(GaitnetError, match="not a folder"):
        simulate_session(load_config(SimConfig, CONFIG, FAST), 0, target)
    assert target.read_text() == "keep" and [p.name for p in tmp_path.iterdir()] == ["file"]


def test_exception_mid_run_leaves_nothing_and_leftovers_of_killed_runs_go(
    tmp_path: Path, monkeypatch
) -> None:
    import gaitnet.sim.session_frames as session_module  # frames are sensed there

    cfg = load_config(SimConfig, CONFIG, [*FAST, "camera.fps=2"])
    real, calls = session_module.apply_sensor, []

    def failing(*args, **kwargs):
        calls.append(1)
        if len(calls) == 3:
            raise RuntimeError("boom")
        return real(*args, **kwargs)

    monkeypatch.setattr(session_module, "apply_sensor", failing)
    with pytest.raises(RuntimeError, match="boom"):
        simulate_session(cfg, 0, tmp_path / "out", workers=1)  # the patch is in this process
    assert list(tmp_path.iterdir()) == []
    monkeypatch.setattr(session_module, "apply_sensor", real)
    # A staging folder of a killed run (a process id that no longer runs) is removed.
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True).stdout.strip()  # fmt: skip
    leftover = tmp_path / f".out.partial-{dead}"
    (leftover / "color").mkdir(parents=True)
    simulate_session(cfg, 0, tmp_path / "out")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_camera_looking_away_from_the_feet_is_logged_not_hung(tmp_path: Path, caplog) -> None:
    cfg = load_config(
        SimConfig, CONFIG, [*FAST, "camera.fps=2", "mount.pitch_deg=10", "mount.yaw_deg=60"]
    )
    with caplog.at_level("WARNING", logger="gaitnet.sim.session"):
        result = simulate_session(cfg, 0, tmp_path / "away")
    assert result.marker_checks["visible_marker_fraction"] < 0.5
    assert any("foot markers are in the image" in r.message for r in caplog.records)


def test_rig_motion_imu_errors_and_frame_timing_truths_are_written(tiny_sim: Path) -> None:
    import csv

    import yaml

    gt = tiny_sim / "groundtruth"
    session = SessionFolder(tiny_sim)
    # Camera in the pelvis frame: camera_frames = pelvis_frames · mount_frames, and it moves.
    t_c, T_WC = read_tum(gt / "camera_frames.tum")
    t_p, T_WP = read_tum(gt / "pelvis_frames.tum")
    t_m, T_PC = read_tum(gt / "mount_frames.tum")
    np.testing.assert_allclose(t_m, t_c)
    np.testing.assert_allclose(T_WP @ T_PC, T_WC, atol=1e-5)
    assert np.ptp(T_PC[:, :3, 3], axis=0).max() > 2e-4
    # IMU timestamps = true sampling instants + the offset in imu_calibration.yaml.
    cal = yaml.safe_load((gt / "imu_calibration.yaml").read_text())
    truth = np.load(gt / "imu_truth.npz")
    np.testing.assert_array_equal(truth["t_ns"], session.imu.t_ns)
    np.testing.assert_allclose(
        truth["t_ns"] * 1e-9 - truth["t_true_s"], cal["imu_time_offset_s"], atol=2e-9
    )
    assert 0 < abs(cal["imu_time_offset_s"]) <= 0.005
    assert abs(np.diag(cal["accel_matrix"]) - 1).max() > 0 and cal["accel_lsb_mps2"] > 0
    motion = np.load(gt / "mount_motion.npz")
    assert np.abs(motion["impact_m"]).max() > 0 and np.abs(motion["wobble_m"]).max() > 0
    # Frame timing: kept frames are the session's frames, dropped ones are listed.
    rows = list(csv.DictReader((gt / "frame_times.csv").read_text().splitlines()))
    kept = [r for r in rows if r["dropped"] == "0"]
    np.testing.assert_array_equal([int(r["t_ns"]) for r in kept], session.frame_times_ns)
    assert [int(r["frame"]) for r in rows if r["dropped"] == "1"] == cal["dropped_frames"]
    jitter = session.frame_times_ns * 1e-9 - np.array(
        [float(r["true_exposure_mid_s"]) for r in kept]
    )
    assert 0 < np.abs(jitter).max() < 0.001
