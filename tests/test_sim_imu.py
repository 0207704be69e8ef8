"""Synthetic IMU: exact signals (integrated back to the trajectory) and the noise model."""

from __future__ import annotations

import numpy as np

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
