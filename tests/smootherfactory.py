"""Synthetic smoothing problems with known truth (for tests/test_vio_smoother.py and
benchmarks/bench_smoother.py).

An analytic walking-like IMU trajectory (forward speed, vertical and lateral sway, yaw, roll and
pitch oscillations) gives exact IMU readings, to which white noise and constant biases are added;
frames at ``fps``; noisy VO relative poses between consecutive frames; stance-foot landmarks on
the floor, each seen for ``stance_s`` seconds (alternating sides, one new stance every
``step_s``); an end-sheet tag position at the last frames. A small error-state filter built from
the core (propagate_to, clone, VO/foot/tag updates, augmentation, marginalisation) runs over it
and fills a :class:`~gaitnet.vio.records.FilterRecorder` exactly as ``run.py`` does.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gaitnet.geometry import (
    invert_T,
    make_T,
    quat_boxplus,
    quat_from_rotmat,
    so3_exp,
    so3_log,
)
from gaitnet.io.types import ImuNoise, ImuSamples
from gaitnet.vio import covariance
from gaitnet.vio.foot_model import foot_measurement, foot_predict, landmark_from_observation
from gaitnet.vio.imu_propagation import propagate_to
from gaitnet.vio.records import FilterRecord, FilterRecorder, preintegrate
from gaitnet.vio.state import FilterState, ImuState
from gaitnet.vio.tag_model import tag_measurement
from gaitnet.vio.vo_model import vo_measurement

G = 9.81


@dataclass(frozen=True)
class SynthConfig:
    duration_s: float = 4.0
    fps: float = 30.0
    imu_rate_hz: float = 200.0
    gyro_density: float = 2.4e-4  # rad/s/√Hz (BMI055 class)
    accel_density: float = 1.5e-3  # m/s²/√Hz
    gyro_bias_std: float = 0.005  # rad/s
    accel_bias_std: float = 0.05  # m/s²
    vo_rot_std: float = 2e-3  # rad
    vo_trans_std: float = 3e-3  # m
    foot_std: float = 0.01  # m
    tag_std: float = 0.005  # m
    end_sheet_eps2: float = 0.01**2
    step_s: float = 0.55
    stance_s: float = 0.6
    prior_att_std: float = 2e-3
    prior_pos_std: float = 0.005
    prior_vel_std: float = 0.05


@dataclass
class SynthProblem:
    """The record of the filter run, the truth per frame (``q``, ``p``, ``v`` (N, ·)), the
    true biases, the true landmarks {id: (x, y)}, and the filter's final landmark estimates."""

    record: FilterRecord
    q: np.ndarray
    p: np.ndarray
    v: np.ndarray
    b_g: np.ndarray
    b_a: np.ndarray
    landmarks: dict[int, np.ndarray]
    filter_landmarks: dict[int, np.ndarray]
    imu: ImuSamples
    noise: ImuNoise


def _pose(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Analytic IMU pose: ``R_WfromI`` (..., 3, 3) and ``p_IinW`` (..., 3)."""
    w = 2 * np.pi * 1.8  # step frequency
    p = np.stack(
        [
            1.2 * t + 0.02 * np.sin(w * t),
            0.03 * np.sin(0.5 * w * t) + 0.05 * np.sin(0.2 * t),
            1.0 + 0.02 * np.cos(w * t),
        ],
        axis=-1,
    )
    yaw = 0.15 * np.sin(0.3 * t) + 0.04 * np.sin(0.5 * w * t)
    pitch = 0.03 * np.sin(w * t + 0.3)
    roll = 0.04 * np.sin(0.5 * w * t)
    rv = np.stack([roll, pitch, yaw], axis=-1)
    Rz = so3_exp(rv * np.array([0, 0, 1.0]))
    Ry = so3_exp(rv * np.array([0, 1.0, 0]))
    Rx = so3_exp(rv * np.array([1.0, 0, 0]))
    return Rz @ Ry @ Rx, p


def _kinematics(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``R``, ``p``, ``v``, ``a`` (world) and body rate ``ω`` by central differences of the
    analytic pose (step 1e-4 s: error ~1e-8)."""
    d = 1e-4
    R, p = _pose(t)
    Rm, pm = _pose(t - d)
    Rp, pp = _pose(t + d)
    v = (pp - pm) / (2 * d)
    a = (pp - 2 * p + pm) / (d * d)
    w = so3_log(np.swapaxes(Rm, -1, -2) @ Rp) / (2 * d)
    return R, p, v, a, w


def camera_extrinsic() -> np.ndarray:
    """``T_CfromI``: a camera at the waist looking forward and down (IMU x forward, z up)."""
    z_c = np.array([1.0, 0.0, -1.5]) / np.linalg.norm([1.0, 0.0, -1.5])
    x_c = np.array([0.0, -1.0, 0.0])
    y_c = np.cross(z_c, x_c)
    R_IfromC = np.stack([x_c, y_c, z_c], axis=1)
    return invert_T(make_T(R_IfromC, np.array([0.08, 0.01, 0.04])))


def make_problem(cfg: SynthConfig, seed: int) -> SynthProblem:
    """Simulate and filter one synthetic session (module docstring)."""
    rng = np.random.default_rng(seed)
    T_CfromI = camera_extrinsic()
    noise = ImuNoise(cfg.gyro_density, cfg.accel_density, 1e-6, 1e-5)
    # IMU stream (starts before the first frame, offset from the frame clock).
    t_imu = np.arange(-0.05, cfg.duration_s + 0.1, 1.0 / cfg.imu_rate_hz) + 0.0017
    R, _, _, a, w = _kinematics(t_imu)
    b_g = rng.normal(0.0, cfg.gyro_bias_std, 3)
    b_a = rng.normal(0.0, cfg.accel_bias_std, 3)
    g = np.array([0.0, 0.0, G])
    sq = np.sqrt(cfg.imu_rate_hz)
    gyro = w + b_g + rng.normal(0.0, cfg.gyro_density * sq, w.shape)
    f = (np.swapaxes(R, -1, -2) @ (a + g)[..., None])[..., 0]
    accel = f + b_a + rng.normal(0.0, cfg.accel_density * sq, f.shape)
    imu = ImuSamples(np.round(t_imu * 1e9).astype(np.int64), accel, gyro)

    n = int(round(cfg.duration_s * cfg.fps))
    t_f = np.arange(n) / cfg.fps
    Rf, pf, vf, _, _ = _kinematics(t_f)
    qf = quat_from_rotmat(Rf)

    # Stance landmarks: ahead of the body, alternating sides.
    n_lm = int(cfg.duration_s / cfg.step_s)
    lm_true: dict[int, np.ndarray] = {}
    windows: dict[int, tuple[float, float]] = {}
    for j in range(n_lm):
        t0 = 0.1 + j * cfg.step_s
        _, p0 = _pose(np.array(t0))
        side = 1.0 if j % 2 else -1.0
        lm_true[j] = np.array([p0[0] + 0.45, p0[1] + 0.1 * side])
        windows[j] = (t0, t0 + cfg.stance_s)

    # Prior (the initialisation): truth perturbed by its own covariance.
    P0 = np.diag(
        np.r_[
            np.full(3, cfg.prior_att_std**2),
            np.full(3, cfg.prior_pos_std**2),
            np.full(3, cfg.prior_vel_std**2),
            np.full(3, cfg.gyro_bias_std**2),
            np.full(3, cfg.accel_bias_std**2),
        ]
    )
    d0 = rng.multivariate_normal(np.zeros(9), P0[:9, :9])
    x0 = ImuState(
        quat_boxplus(qf[0], d0[0:3]),
        pf[0] + d0[3:6],
        vf[0] + d0[6:9],
        np.zeros(3),
        np.zeros(3),
        0.0,
    )
    state = FilterState.new(x0, P0)
    rec = FilterRecorder(T_CfromI, G)
    rec.set_prior(state)
    cov6 = np.diag(np.r_[np.full(3, cfg.vo_rot_std**2), np.full(3, cfg.vo_trans_std**2)])
    R3 = np.eye(3) * cfg.foot_std**2
    tag_cov6 = np.diag(np.r_[np.full(3, 1e-4), np.full(3, cfg.tag_std**2)])
    T_IfromC = invert_T(T_CfromI)
    closed: set[int] = set()

    def T_WfromC(k: int) -> np.ndarray:
        return make_T(Rf[k], pf[k]) @ T_IfromC

    for k in range(n):
        if k > 0:
            before = state.imu.copy()
            interval, _ = preintegrate(before, imu, t_f[k], noise, gravity_mps2=G)
            propagate_to(state, imu, t_f[k], noise, gravity_mps2=G)
            rec.add_interval(interval)
            # VO between k-1 and k: p_Ck = R p_Ck-1 + t.
            T_rel = invert_T(T_WfromC(k)) @ T_WfromC(k - 1)
            R_meas = so3_exp(rng.normal(0.0, cfg.vo_rot_std, 3)) @ T_rel[:3, :3]
            t_meas = T_rel[:3, 3] + rng.normal(0.0, cfg.vo_trans_std, 3)
            m = vo_measurement(state, T_CfromI, R_meas, t_meas, cov6)
            if covariance.update(state, m).accepted:
                rec.add_vo(R_meas, t_meas, cov6)
        # End sheet: tag positions in the last 5 frames.
        if k >= n - 5:
            T_meas = T_WfromC(k).copy()
            T_meas[:3, 3] += rng.normal(0.0, cfg.tag_std, 3)
            T_meas[:2, 3] += rng.normal(0.0, np.sqrt(cfg.end_sheet_eps2), 2)
            m = tag_measurement(
                state, T_CfromI, T_meas, tag_cov6, end_sheet_eps2=cfg.end_sheet_eps2
            )
            if covariance.update(state, m).accepted:
                rec.add_tag(T_meas, tag_cov6, end_sheet_eps2=cfg.end_sheet_eps2)
        for j, (ta, tb) in windows.items():
            if not ta <= t_f[k] < tb or j in closed:
                continue
            p_FinC = foot_predict(qf[k], pf[k], lm_true[j], T_CfromI) + rng.normal(
                0.0, cfg.foot_std, 3
            )
            if j not in state.landmarks:
                aug = landmark_from_observation(state, T_CfromI, p_FinC, R3)
                covariance.augment_landmark(state, j, aug)
                rec.add_foot(j, p_FinC, R3, is_first=True)
            else:
                m = foot_measurement(state, T_CfromI, j, p_FinC, R3)
                if covariance.update(state, m).accepted:
                    rec.add_foot(j, p_FinC, R3)
        rec.add_frame(state, k)
        for j in list(state.landmarks):
            if t_f[k] >= windows[j][1] - 1.0 / cfg.fps:
                covariance.marginalise_landmark(state, j)
                closed.add(j)
        covariance.clone(state)
    record = rec.finish()
    return SynthProblem(
        record=record,
        q=qf,
        p=pf,
        v=vf,
        b_g=b_g,
        b_a=b_a,
        landmarks={j: lm_true[j] for j in record.landmarks},
        filter_landmarks=dict(record.landmarks),
        imu=imu,
        noise=noise,
    )
