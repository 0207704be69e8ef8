"""IMU time update of the filter (gaitnet.vio.imu_propagation)."""

from __future__ import annotations

import numpy as np
import pytest

from gaitnet.config import load_config
from gaitnet.geometry import quat_boxminus, quat_from_rotmat, quat_from_rotvec
from gaitnet.io.types import ImuNoise, ImuSamples
from gaitnet.sim.config import SimConfig
from gaitnet.sim.gait import generate_walk
from gaitnet.sim.imu import ImuConfig, rig_imu_truth, simulate_imu
from gaitnet.sim.scene_setup import rng_streams
from gaitnet.sim.subject import sample_subject
from gaitnet.vio.covariance import clone
from gaitnet.vio.imu_propagation import (
    integrate_readings,
    lift,
    propagate_to,
    step_noise,
)
from gaitnet.vio.state import FilterState, ImuState

G = 9.81


def imu_error(a: ImuState, b: ImuState) -> np.ndarray:
    """``a ⊟ b`` in the 15-D error state."""
    return np.concatenate(
        [
            quat_boxminus(a.q, b.q),
            a.p_IinW - b.p_IinW,
            a.v_IinW - b.v_IinW,
            a.b_g - b.b_g,
            a.b_a - b.b_a,
        ]
    )


def random_imu(rng: np.random.Generator, t_s: float = 0.0) -> ImuState:
    return ImuState(
        q=quat_from_rotvec(rng.normal(size=3)),
        p_IinW=rng.normal(size=3),
        v_IinW=rng.normal(size=3),
        b_g=0.05 * rng.normal(size=3),
        b_a=0.3 * rng.normal(size=3),
        t_s=t_s,
    )


def readings(rng: np.random.Generator, m: int) -> tuple[np.ndarray, np.ndarray]:
    """Vigorous but plausible readings: rates up to a few rad/s, forces around gravity."""
    y_g = 2.0 * rng.normal(size=(m, 3))
    y_a = np.array([0.0, 0.0, G]) + 4.0 * rng.normal(size=(m, 3))
    return y_g, y_a


@pytest.mark.parametrize("steps", [[0.005], [0.0013], [0.005, 0.002, 0.005, 0.0041]])
def test_transition_equals_finite_difference_of_the_mechanisation(steps: list[float]) -> None:
    rng = np.random.default_rng(len(steps) * 7 + int(steps[0] * 1e4))
    imu = random_imu(rng)
    t = np.concatenate([[0.0], np.cumsum(steps)])
    y_g, y_a = readings(rng, len(t))
    end, F = integrate_readings(imu, t, y_g, y_a, G)
    Phi, _ = lift(F, np.zeros_like(F))
    base = FilterState.new(imu, np.eye(15))
    eps = 1e-6
    fd = np.zeros((15, 15))
    for j in range(15):
        e = np.zeros(15)
        e[j] = eps
        plus, _ = integrate_readings(base.boxplus(e).imu, t, y_g, y_a, G)
        minus, _ = integrate_readings(base.boxplus(-e).imu, t, y_g, y_a, G)
        fd[:, j] = (imu_error(plus, end) - imu_error(minus, end)) / (2 * eps)
    err = np.abs(fd - Phi).max() / np.abs(Phi).max()
    assert err < 1e-7, err
    # The transition is not trivial: attitude and bias couplings are present.
    assert np.abs(Phi[6:9, 0:3]).max() > 1e-3 and np.abs(Phi[0:3, 9:12]).max() > 1e-3


def _walk_imu(noise_free: bool, seconds: float):
    cfg = load_config(SimConfig, None, ["gait.walk_length_m=7"])
    rngs = rng_streams(5)
    walk = generate_walk(sample_subject(rngs["subject"]), cfg.gait, rngs["gait"])
    T_PfromI = cfg.mount.T_PfromC() @ cfg.mount.T_CfromI()
    imu_cfg = ImuConfig(noise_free=noise_free)
    samples, truth = simulate_imu(
        walk.pelvis_kinematics, T_PfromI, 0.0, seconds, imu_cfg, np.random.default_rng(0)
    )
    return walk, T_PfromI, imu_cfg, samples, truth


def test_noise_free_simulated_imu_integrates_to_the_truth_at_frame_times() -> None:
    """Noise-free simulator IMU (200 Hz, jittered, period-averaged samples), propagated frame by
    frame at 30 Hz (a variable number of samples per frame, frame times between samples): the
    pose stays within a few mm / 0.01° of the simulator's truth over a 10 s, 7 m walk."""
    walk, T_PfromI, imu_cfg, samples, truth = _walk_imu(True, 10.0)
    frames = 0.0123 + np.arange(0.0, 9.95, 1.0 / 30.0)
    R_t, p_t, v_t, _, _ = rig_imu_truth(walk.pelvis_kinematics, T_PfromI, frames, G)
    imu0 = ImuState(
        quat_from_rotmat(truth.R_WfromI[0]),
        truth.p_IinW[0].copy(),
        truth.v_IinW[0].copy(),
        np.zeros(3),
        np.zeros(3),
        float(truth.t_s[0]),
    )
    state = FilterState.new(imu0, 1e-4 * np.eye(15))
    noise = ImuNoise(1e-3, 1e-2, 1e-5, 1e-4)
    counts = set()
    pos_err, att_err = [], []
    for k, tf in enumerate(frames):
        info = propagate_to(state, samples, tf, noise, gravity_mps2=imu_cfg.gravity_mps2)
        counts.add(info.n_steps)
        assert info.held_s == 0.0
        pos_err.append(np.linalg.norm(state.imu.p_IinW - p_t[k]))
        att_err.append(np.linalg.norm(quat_boxminus(state.imu.q, quat_from_rotmat(R_t[k]))))
    assert np.linalg.norm(p_t[-1] - p_t[0]) > 6.0  # it really walked
    assert max(pos_err) < 0.003, max(pos_err)
    assert max(att_err) < np.radians(0.01), max(att_err)
    assert np.linalg.norm(state.imu.v_IinW - v_t[-1]) < 0.002
    assert len(counts) >= 2  # 6 and 7 (or 8) steps per frame: not an integer ratio
    # Gravity must match the data: the standard 9.80665 instead of the simulator's 9.81
    # drifts by decimetres in 10 s (the filter takes gravity as a parameter).
    wrong = FilterState.new(imu0, 1e-4 * np.eye(15))
    propagate_to(wrong, samples, frames[-1], noise, gravity_mps2=9.80665)
    assert np.linalg.norm(wrong.imu.p_IinW - p_t[-1]) > 0.05


def test_splitting_an_interval_at_frame_times_changes_almost_nothing() -> None:
    rng = np.random.default_rng(11)
    t_ns = np.round((np.arange(40) * 0.005 + rng.normal(0, 2e-5, 40)) * 1e9).astype(np.int64)
    y_g, y_a = readings(rng, 40)
    imu = ImuSamples(t_ns=t_ns, accel=y_a, gyro=y_g)
    noise = ImuNoise(1e-3, 2e-2, 1e-4, 1e-3)
    start = random_imu(rng, t_s=0.0171)
    direct = FilterState.new(start.copy(), np.eye(15) * 1e-3)
    split = FilterState.new(start.copy(), np.eye(15) * 1e-3)
    propagate_to(direct, imu, 0.1607, noise)
    for t in (0.0502, 0.0833, 0.0834, 0.1607):  # frame times between samples
        propagate_to(split, imu, t, noise)
    # Equal up to the integration error of the extra sub-steps (a held or nearest reading at
    # the frame time instead of the interpolated one would differ by ~1e-3).
    assert np.abs(imu_error(split.imu, direct.imu)).max() < 1e-6
    assert np.abs(split.P - direct.P).max() < 1e-6 * np.abs(direct.P).max()


def test_lifted_covariance_equals_the_per_sample_recursion_with_a_clone() -> None:
    rng = np.random.default_rng(12)
    t_ns = np.round(np.arange(30) * 0.005 * 1e9).astype(np.int64)
    y_g, y_a = readings(rng, 30)
    imu = ImuSamples(t_ns=t_ns, accel=y_a, gyro=y_g)
    noise = ImuNoise(1e-3, 2e-2, 1e-4, 1e-3)
    A = rng.normal(size=(15, 15))
    state = FilterState.new(random_imu(rng, t_s=0.0123), A @ A.T / 15 + 1e-3 * np.eye(15))
    clone(state)
    P = state.P.copy()
    t_end = 0.0123 + 1.0 / 30.0
    nodes = np.concatenate([[0.0123], t_ns[(t_ns > 12.3e6) & (t_ns < t_end * 1e9)] * 1e-9, [t_end]])
    g = np.stack([np.interp(nodes, t_ns * 1e-9, y_g[:, k]) for k in range(3)], 1)
    a = np.stack([np.interp(nodes, t_ns * 1e-9, y_a[:, k]) for k in range(3)], 1)
    _, F = integrate_readings(state.imu, nodes, g, a)
    Qd = step_noise(F, np.diff(nodes), noise)
    for Fj, Qj in zip(F, Qd, strict=True):  # one sample at a time, clone static
        Fx = np.eye(21)
        Fx[:15, :15] = Fj
        Qx = np.zeros((21, 21))
        Qx[:15, :15] = Qj
        P = Fx @ P @ Fx.T + Qx
    info = propagate_to(state, imu, t_end, noise)
    assert info.n_steps == len(nodes) - 1 == 8
    np.testing.assert_allclose(state.P, P, rtol=1e-9, atol=1e-14)


def test_covariance_matches_monte_carlo_of_noisy_readings() -> None:
    """Start errors drawn from P0 and white reading noise of the stated densities on every
    sample: the spread of the true states around the nominal matches the propagated P."""
    rng = np.random.default_rng(13)
    m = 101  # 0.5 s at 200 Hz
    t = np.arange(m) * 0.005
    y_g = np.stack([0.5 * np.sin(3 * t), 0.8 * np.cos(2 * t), 0.3 + 0 * t], 1)
    y_a = np.stack([2 * np.sin(4 * t), 1.5 * np.cos(3 * t), G + np.sin(5 * t)], 1)
    imu = ImuSamples(t_ns=np.round(t * 1e9).astype(np.int64), accel=y_a, gyro=y_g)
    noise = ImuNoise(0.02, 0.3, 0.0, 0.0)  # large white noise, so Q_d dominates
    P0 = np.diag(
        np.r_[
            1e-4 * np.ones(3),
            1e-4 * np.ones(3),
            1e-4 * np.ones(3),
            1e-6 * np.ones(3),
            1e-4 * np.ones(3),
        ]
    )
    nominal = ImuState(
        quat_from_rotvec([0.1, 0.2, 0.3]),
        np.zeros(3),
        np.array([1.0, 0, 0]),
        np.zeros(3),
        np.zeros(3),
        0.0,
    )
    state = FilterState.new(nominal.copy(), P0)
    propagate_to(state, imu, t[-1], noise)
    n_runs = 1500
    sig_g = noise.gyro_noise_density * np.sqrt(200.0)
    sig_a = noise.accel_noise_density * np.sqrt(200.0)
    L = np.linalg.cholesky(P0)
    base = FilterState.new(nominal.copy(), P0)
    errs = np.empty((n_runs, 15))
    for r in range(n_runs):
        true0 = base.boxplus(L @ rng.standard_normal(15)).imu
        # The truth moves with readings that are the measured ones minus noise (same biases).
        g_true = y_g - sig_g * rng.standard_normal((m, 3))
        a_true = y_a - sig_a * rng.standard_normal((m, 3))
        end, _ = integrate_readings(true0, t, g_true, a_true)
        errs[r] = imu_error(end, state.imu)
    C = np.cov(errs[:, :9], rowvar=False)
    P = state.P[:9, :9]
    np.testing.assert_allclose(np.diag(C), np.diag(P), rtol=0.12)
    corr_mc = C / np.sqrt(np.outer(np.diag(C), np.diag(C)))
    corr_p = P / np.sqrt(np.outer(np.diag(P), np.diag(P)))
    assert np.abs(corr_mc - corr_p).max() < 0.1
    assert np.abs(corr_p[3:6, 6:9]).max() > 0.5  # position-velocity correlation is tested
