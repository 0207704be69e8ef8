"""Synthetic IMU: exact signals (integrated back to the trajectory) and the noise model."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gaitnet.geometry import make_T, so3_exp
from gaitnet.sim.imu import ImuConfig, simulate_imu
from gaitnet.sim.rig import MountConfig
from gaitnet.sim.strapdown import integrate_imu

W = 2 * np.pi * 0.9  # a walking-like fundamental [rad/s]


def _rot(axis: int, angle: np.ndarray) -> np.ndarray:
    e = np.zeros((len(angle), 3))
    e[:, axis] = angle
    return so3_exp(e)


def _rot_rate(axis: int, angle: np.ndarray, rate: np.ndarray) -> np.ndarray:
    e = np.zeros(3)
    e[axis] = 1.0
    E = np.array([[0, -e[2], e[1]], [e[2], 0, -e[0]], [-e[1], e[0], 0]])
    return _rot(axis, angle) @ E * rate[:, None, None]


def analytic_pelvis(t: np.ndarray):
    """A smooth swaying, bobbing, turning motion with exact derivatives."""
    t = np.atleast_1d(np.asarray(t, dtype=np.float64))
    p = np.stack(
        [1.2 * t + 0.03 * np.sin(W * t), 0.02 * np.sin(W * t), 1.0 + 0.02 * np.cos(2 * W * t)], 1
    )
    v = np.stack(
        [1.2 + 0.03 * W * np.cos(W * t), 0.02 * W * np.cos(W * t), -0.04 * W * np.sin(2 * W * t)], 1
    )
    a = np.stack(
        [
            -0.03 * W**2 * np.sin(W * t),
            -0.02 * W**2 * np.sin(W * t),
            -0.08 * W**2 * np.cos(2 * W * t),
        ],
        1,
    )
    yaw, dyaw = 0.08 * np.sin(W * t) + 0.02 * t, 0.08 * W * np.cos(W * t) + 0.02
    pit, dpit = 0.05 * np.sin(2 * W * t), 0.1 * W * np.cos(2 * W * t)
    rol, drol = 0.07 * np.sin(W * t + 1), 0.07 * W * np.cos(W * t + 1)
    Rz, Ry, Rx = _rot(2, yaw), _rot(1, pit), _rot(0, rol)
    R = Rz @ Ry @ Rx
    dR = (
        _rot_rate(2, yaw, dyaw) @ Ry @ Rx
        + Rz @ _rot_rate(1, pit, dpit) @ Rx
        + Rz @ Ry @ _rot_rate(0, rol, drol)
    )
    S = np.transpose(R, (0, 2, 1)) @ dR
    w = np.stack([S[:, 2, 1], S[:, 0, 2], S[:, 1, 0]], 1)
    return R, p, v, a, w


def test_noise_free_imu_integrates_back_to_the_trajectory() -> None:
    T_PfromI = MountConfig().T_PfromC() @ MountConfig().T_CfromI()
    cfg = ImuConfig(noise_free=True, timestamp_jitter_s=2e-5)
    samples, truth = simulate_imu(
        analytic_pelvis, T_PfromI, 0.0, 10.0, cfg, np.random.default_rng(0)
    )
    t = samples.t_ns * 1e-9
    p_est, _ = integrate_imu(
        t,
        samples.accel,
        samples.gyro,
        truth.R_WfromI[0],
        truth.p_IinW[0],
        truth.v_IinW[0],
        cfg.gravity_mps2,
    )
    err = np.linalg.norm(p_est - truth.p_IinW, axis=1)
    assert err.max() < 0.01, err.max()
    # The lever arm matters: ignoring it (IMU at the pelvis origin) breaks the check.
    R, p, *_ = analytic_pelvis(t)
    assert np.abs(truth.p_IinW - p).max() > 0.1


def test_imu_at_rest_reads_gravity_up() -> None:
    def still(t):
        n = len(np.atleast_1d(t))
        R = np.repeat(so3_exp(np.array([0.3, -0.2, 1.0]))[None], n, 0)
        return R, np.zeros((n, 3)) + [0, 0, 1], np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3))

    T = make_T(so3_exp(np.array([0.1, 0.2, 0.3])), [0.1, 0.0, 0.0])
    samples, truth = simulate_imu(
        still, T, 0.0, 1.0, ImuConfig(noise_free=True), np.random.default_rng(0)
    )
    R_WI = truth.R_WfromI[0]
    np.testing.assert_allclose(
        samples.accel, np.tile(R_WI.T @ [0, 0, 9.81], (len(samples), 1)), atol=1e-12
    )
    np.testing.assert_allclose(samples.gyro, 0.0, atol=1e-12)


def still_identity(t):
    """A pelvis at rest at the origin with the identity attitude."""
    n = len(np.atleast_1d(t))
    zeros = np.zeros((n, 3))
    return np.repeat(np.eye(3)[None], n, 0), zeros, zeros, zeros, zeros


def test_noise_statistics_match_the_densities() -> None:
    cfg = ImuConfig(gyro_bias_random_walk=0.0, accel_bias_random_walk=0.0)
    samples, truth = simulate_imu(
        still_identity, np.eye(4), 0.0, 200.0, cfg, np.random.default_rng(3)
    )
    gyro_noise = samples.gyro - truth.gyro_bias
    accel_noise = samples.accel - truth.specific_force - truth.accel_bias
    expected_g = cfg.gyro_noise_density * np.sqrt(cfg.rate_hz)
    expected_a = cfg.accel_noise_density * np.sqrt(cfg.rate_hz)
    np.testing.assert_allclose(gyro_noise.std(0), expected_g, rtol=0.03)
    np.testing.assert_allclose(accel_noise.std(0), expected_a, rtol=0.03)
    dt = np.diff(samples.t_ns) * 1e-9
    assert abs(dt.mean() - 0.005) < 1e-6 and 1e-6 < dt.std() < 1e-4


def test_bias_random_walk_grows_with_sqrt_time() -> None:
    cfg = ImuConfig(gyro_initial_bias_std=0.0, accel_initial_bias_std=0.0)
    ends = []
    for seed in range(200):
        _, truth = simulate_imu(
            still_identity, np.eye(4), 0.0, 4.0, cfg, np.random.default_rng(seed)
        )
        ends.append(truth.gyro_bias[-1])
    std = np.std(ends)
    assert abs(std / (cfg.gyro_bias_random_walk * 2.0) - 1.0) < 0.15


# --- Realism of the rig's motion, the IMU errors and the frame timing (issue 8, item 4) -----

from scipy.signal import butter, sosfiltfilt  # noqa: E402

from gaitnet.config import load_config  # noqa: E402
from gaitnet.sim.config import SimConfig  # noqa: E402
from gaitnet.sim.frame_timing import FrameTimingConfig, make_frame_times  # noqa: E402
from gaitnet.sim.imu import draw_imu_calibration  # noqa: E402
from gaitnet.sim.scene_setup import build_scene, rng_streams  # noqa: E402

TINY = Path(__file__).parents[1] / "configs" / "sim" / "tiny.yaml"
QUIET = [
    "imu.gyro_noise_density=0",
    "imu.accel_noise_density=0",
    "imu.gyro_bias_random_walk=0",
    "imu.accel_bias_random_walk=0",
    "imu.gyro_initial_bias_std=0",
    "imu.accel_initial_bias_std=0",
]


def tiny_scene(*overrides: str, seed: int = 2):
    cfg = load_config(SimConfig, TINY, ["scene.clutter_count=0", *overrides])
    return cfg, build_scene(cfg, rng_streams(seed))


def heel_strikes(walk) -> np.ndarray:
    hs = np.concatenate([walk.events[s].hs_s for s in ("left", "right")])
    return np.sort(hs[np.isfinite(hs)])


def shock_power(*overrides: str) -> tuple[float, float, float]:
    """>10 Hz power of the noise-free IMU near heel strikes, elsewhere, and the peak [g]."""
    cfg, scene = tiny_scene(*overrides)
    _, truth = simulate_imu(
        scene.camera_kinematics, cfg.mount.T_CfromI(), 0.0, scene.walk.duration_s,
        ImuConfig(noise_free=True), np.random.default_rng(0),
    )  # fmt: skip
    hp = sosfiltfilt(butter(4, 10.0, "highpass", fs=200.0, output="sos"), truth.specific_force, 0)
    power = (hp**2).sum(1)
    hs, t = heel_strikes(scene.walk), truth.t_s
    near = np.zeros(len(t), bool)
    for h in hs:
        near |= (t >= h - 0.02) & (t <= h + 0.15)
    far = (t > hs.min() - 0.3) & (t < hs.max() + 0.5) & ~near
    return power[near].mean(), power[far].mean(), float(np.sqrt(power[near].max()) / 9.80665)


def test_heel_strikes_put_power_above_10_hz_into_the_imu() -> None:
    near, far, peak_g = shock_power()
    assert near > 50 * far
    assert 0.5 < peak_g < 2.5  # about 1 g at the rig (docs/references.md)
    near_off, _, peak_off = shock_power("mount.impact_peak_g=0", "mount.wobble_gain=0")
    assert near_off < 1e-3 * near and peak_off < 0.05


def test_shock_peak_grows_with_walking_speed() -> None:
    peaks = []
    for speed in (0.8, 1.6):
        _, scene = tiny_scene(f"gait.speed_mps={speed}", "mount.wobble_gain=0")
        hs = heel_strikes(scene.walk)
        t = np.arange(hs.min(), hs.max() + 0.3, 1e-3)
        impact_acc, _ = scene.mount_motion.parts(t, 2)
        peaks.append(np.linalg.norm(impact_acc, axis=1).max() / 9.80665)
    assert 1.5 < peaks[1] / peaks[0] < 3.0
    assert 0.5 < peaks[0] < 2.0 and 1.5 < peaks[1] < 4.0


def test_wobble_is_a_damped_spring_of_mm_and_tenths_of_a_degree() -> None:
    cfg, scene = tiny_scene()
    motion, walk = scene.mount_motion, scene.walk
    t = np.arange(0.0, walk.duration_s, 1 / 200.0)
    impact, wobble = motion.parts(t)
    _, tilt = motion.displacement(t)
    amp = np.linalg.norm(wobble, axis=1).max()
    assert 0.5e-3 < amp < 10e-3 and 0.05 < np.degrees(np.abs(tilt).max()) < 1.5
    # ẍ + 2ζωẋ + ω²x = −γu recovered by least squares from the truth (vertical axis).
    h = 1 / 200.0
    x = wobble[:, 2]
    dx, ddx = np.gradient(x, h), np.gradient(np.gradient(x, h), h)
    R_WP, _, _, a_P, _ = walk.pelvis_kinematics(t)
    u = np.einsum("nji,nj->ni", R_WP, a_P)[:, 2] + np.gradient(np.gradient(impact[:, 2], h), h)
    (a1, a0, b), *_ = np.linalg.lstsq(np.stack([dx, x, u], 1), -ddx, rcond=None)
    w = np.sqrt(a0)
    assert abs(w / (2 * np.pi) - cfg.mount.wobble_freq_hz) < 0.2
    assert abs(a1 / (2 * w) - cfg.mount.wobble_damping_ratio) < 0.03
    assert abs(b - cfg.mount.wobble_gain) < 0.03


def test_spring_response_is_scipys_bilinear_filter() -> None:
    # The hand-written Tustin filter against scipy.signal's bilinear + lfilter (independent).
    from scipy.signal import bilinear, lfilter

    from gaitnet.sim.mount_dynamics import spring_response

    u = np.random.default_rng(3).normal(0.0, 3.0, (4000, 3))
    w, zeta, gain = 2 * np.pi * 4.5, 0.25, 0.3
    b, a = bilinear([-gain], [1.0, 2 * zeta * w, w * w], fs=1000.0)
    expected = lfilter(b, a, u, axis=0)
    got = spring_response(u, gain, w, zeta, 1000.0)
    assert np.abs(expected).max() > 1e-4
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12 * np.abs(expected).max())
    # one axis at a time is the same as all at once (axis 0 is time)
    np.testing.assert_array_equal(spring_response(u[:, 1], gain, w, zeta, 1000.0), got[:, 1])


def test_camera_poses_and_imu_follow_the_same_rig_motion() -> None:
    """Images and IMU agree: the noise-free IMU of the moving rig integrates back (at 1 kHz:
    the shocks' 10–30 Hz content is resolved) to the IMU poses ``T_WfromC · T_CfromI``."""
    cfg, scene = tiny_scene()
    T_CfromI = cfg.mount.T_CfromI()
    samples, truth = simulate_imu(
        scene.camera_kinematics, T_CfromI, 0.0, 6.0, ImuConfig(noise_free=True, rate_hz=1000),
        np.random.default_rng(0),
    )  # fmt: skip
    T_WI = scene.T_WfromC(truth.t_s) @ T_CfromI
    np.testing.assert_allclose(T_WI[:, :3, 3], truth.p_IinW, atol=1e-12)
    np.testing.assert_allclose(T_WI[:, :3, :3], truth.R_WfromI, atol=1e-12)
    p_est, _ = integrate_imu(
        samples.t_ns * 1e-9, samples.accel, samples.gyro, truth.R_WfromI[0], truth.p_IinW[0],
        truth.v_IinW[0], cfg.imu.gravity_mps2,
    )  # fmt: skip
    assert np.linalg.norm(p_est - truth.p_IinW, axis=1).max() < 0.003
    # The rig really moves on the pelvis (the camera-in-pelvis pose is not constant).
    T_PC = scene.mount_motion.T_PfromC(truth.t_s[::10])
    assert np.ptp(T_PC[:, 2, 3]) > 5e-4


def test_scale_and_misalignment_are_recovered_by_least_squares() -> None:
    cfg, scene = tiny_scene(*QUIET, "imu.accel_lsb_mps2=0", "imu.gyro_lsb_rad_s=0")
    cal = draw_imu_calibration(cfg.imu, np.random.default_rng(5))
    samples, truth = simulate_imu(
        scene.camera_kinematics, cfg.mount.T_CfromI(), 0.0, 5.0, cfg.imu,
        np.random.default_rng(0), cal,
    )  # fmt: skip
    for meas, ideal, M, scale_tol, cross_tol in (
        (samples.accel, truth.specific_force, cal.accel_matrix, 0.02, 0.01),
        (samples.gyro, truth.omega_I, cal.gyro_matrix, 0.01, 0.01),
    ):
        fit = np.linalg.lstsq(ideal, meas, rcond=None)[0].T
        np.testing.assert_allclose(fit, M, atol=1e-9)
        assert np.abs(np.diag(M) - 1).max() <= scale_tol and np.abs(np.diag(M) - 1).max() > 0
        off = M - np.diag(np.diag(M))
        assert np.abs(off).max() <= cross_tol and np.abs(off).max() > 0


def test_quantisation_steps_are_the_d400_lsbs() -> None:
    cfg, scene = tiny_scene(*QUIET)
    cal = draw_imu_calibration(cfg.imu, np.random.default_rng(5))
    samples, truth = simulate_imu(
        scene.camera_kinematics, cfg.mount.T_CfromI(), 0.0, 3.0, cfg.imu,
        np.random.default_rng(0), cal,
    )  # fmt: skip
    for meas, ideal, M, lsb in (
        (samples.accel, truth.specific_force, cal.accel_matrix, 8 * 9.80665 / 4096),
        (samples.gyro, truth.omega_I, cal.gyro_matrix, np.radians(2000.0) / 65536),
    ):
        k = meas / lsb
        np.testing.assert_allclose(k, np.round(k), atol=1e-6)
        assert np.abs(meas - ideal @ M.T).max() <= lsb / 2 + 1e-12


def test_time_offset_is_recovered_by_cross_correlation() -> None:
    cfg, scene = tiny_scene(*QUIET)
    offset = FrameTimingConfig().draw_imu_time_offset(np.random.default_rng(1))
    assert 0 < abs(offset) <= 0.005
    cal = draw_imu_calibration(cfg.imu, np.random.default_rng(5), offset)
    T_CfromI = cfg.mount.T_CfromI()
    samples, truth = simulate_imu(
        scene.camera_kinematics, T_CfromI, 0.0, scene.walk.duration_s, cfg.imu,
        np.random.default_rng(0), cal,
    )  # fmt: skip
    np.testing.assert_allclose(samples.t_ns * 1e-9 - truth.t_s, offset, atol=1e-9)
    grid = np.arange(1.0, scene.walk.duration_s - 1.0, 2e-4)
    meas = np.interp(grid, samples.t_ns * 1e-9, np.linalg.norm(samples.gyro, axis=1))
    ref = np.linalg.norm(scene.camera_kinematics(grid)[4], axis=1)
    lags = np.arange(-0.01, 0.01 + 1e-9, 2e-4)
    corr = [np.corrcoef(meas, np.interp(grid, grid + lag, ref))[0, 1] for lag in lags]
    assert abs(lags[int(np.argmax(corr))] - offset) <= 4e-4


def test_frame_timing_jitter_and_dropped_frames() -> None:
    cfg = FrameTimingConfig()
    ft = make_frame_times(3600.0, 30.0, cfg, np.random.default_rng(0))
    n = len(ft.index) + len(ft.dropped)
    assert 0.002 < len(ft.dropped) / n < 0.004
    assert np.all(np.diff(ft.dropped) > 1) and 0 not in ft.dropped and n - 1 not in ft.dropped
    jitter = ft.stamp_ns * 1e-9 - ft.true_s
    assert abs(jitter.std() - cfg.frame_jitter_s) < 1e-5 and np.abs(jitter).max() <= 6.1e-4
    assert np.all(np.diff(ft.stamp_ns) > 0)
    np.testing.assert_allclose(np.diff(ft.true_s) * 30, np.diff(ft.index), atol=1e-9)


@pytest.mark.parametrize(
    "key",
    [
        "mount.impact_peak_g",
        "mount.wobble_gain",
        "mount.wobble_tilt_deg_per_mm",
        "imu.accel_scale_tol",
        "imu.gyro_scale_tol",
        "imu.accel_cross_axis_tol",
        "imu.gyro_cross_axis_tol",
        "imu.accel_lsb_mps2",
        "imu.gyro_lsb_rad_s",
        "timing.frame_jitter_s",
        "timing.frame_drop_rate",
        "timing.imu_time_offset_max_s",
    ],
)
def test_each_key_switches_its_effect_off(key: str) -> None:
    def effect(*overrides: str) -> float:
        cfg = load_config(SimConfig, TINY, list(overrides))
        section, name = key.split(".")
        if section == "mount":
            scene = build_scene(cfg, rng_streams(2))
            t = np.arange(0.0, scene.walk.duration_s, 0.01)
            impact, wobble = scene.mount_motion.parts(t)
            _, tilt = scene.mount_motion.displacement(t)
            part = {"impact_peak_g": impact, "wobble_gain": wobble}.get(name, tilt)
            return float(np.abs(part).max())
        if section == "timing":
            ft = make_frame_times(600.0, 30.0, cfg.timing, np.random.default_rng(0))
            offset = cfg.timing.draw_imu_time_offset(np.random.default_rng(0))
            return {
                "frame_jitter_s": float(np.abs(ft.stamp_ns * 1e-9 - ft.true_s).max()),
                "frame_drop_rate": float(len(ft.dropped)),
                "imu_time_offset_max_s": abs(offset),
            }[name]
        cal = draw_imu_calibration(cfg.imu, np.random.default_rng(0))
        if name.endswith("_lsb_mps2") or name.endswith("_lsb_rad_s"):
            return getattr(cal, name)
        M = cal.accel_matrix if name.startswith("accel") else cal.gyro_matrix
        d = np.diag(M) - 1
        return float(np.abs(d if "scale" in name else M - np.diag(np.diag(M))).max())

    assert effect() > 0
    assert effect(f"{key}=0") <= 1e-9  # (nanosecond timestamps round)
