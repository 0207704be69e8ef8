"""Synthetic IMU: exact specific force and angular rate of the rig, plus BMI055-like errors.

Measurement model (thesis eq. (3.2), world z up, ``g̃ = [0, 0, g]``)::

    y_a = C(q) (a + g̃) + b_a + η_a        (specific force in the IMU frame)
    y_g = ω_I + b_g + η_g                  (angular rate in the IMU frame)

with ``C(q) = R_IfromW``. The IMU is rigidly attached to the pelvis at ``T_PfromI``:
``p_I = p_P + R_WP p_IinP``, ``ω_I = R_IP ω_P``, and
``a_I = a_P + R_WP (α_P × p_IinP + ω_P × (ω_P × p_IinP))`` where ``α_P = dω_P/dt`` (pelvis
frame). Noise: white noise of density ``σ`` gives per-sample std ``σ √f``; the bias random walk
of density ``σ_b`` adds ``σ_b √Δt · N(0, 1)`` per sample; each session starts with a constant
bias drawn from ``N(0, initial_bias_std²)``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from gaitnet.checks import check_range
from gaitnet.io.types import ImuNoise, ImuSamples

# (R_WfromP (n,3,3), p_PinW (n,3), v (n,3), a (n,3), omega_P (n,3)) at times t (n,)
PelvisKinematics = Callable[
    [np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]
]

DEG = np.pi / 180.0
G_UG = 9.80665e-6  # one micro-g in m/s²


@dataclass(frozen=True)
class ImuConfig:
    """IMU rate and error model. Defaults: the D455's BMI055 (datasheet densities).

    Gyro noise 0.014 °/s/√Hz, accelerometer 150 µg/√Hz (BMI055 class, docs/references.md,
    *Sensors*); bias random walks and initial biases are typical BMI055-class values.
    ``timestamp_jitter_s`` is the std of the sampling instants around the nominal grid.

    Valid values (SI): ``rate_hz`` 50–2000; ``gravity_mps2`` 9.7–9.9 (Earth's surface);
    ``gyro_noise_density`` 0–0.01 rad/s/√Hz; ``accel_noise_density`` 0–0.1 m/s²/√Hz;
    ``gyro_bias_random_walk`` 0–0.01 rad/s²/√Hz; ``accel_bias_random_walk`` 0–0.1 m/s³/√Hz;
    ``gyro_initial_bias_std`` 0–0.2 rad/s; ``accel_initial_bias_std`` 0–1 m/s²;
    ``timestamp_jitter_s`` from 0 to a tenth of the sample period.
    """

    rate_hz: float = 200.0
    gravity_mps2: float = 9.81
    gyro_noise_density: float = 0.014 * DEG
    accel_noise_density: float = 150.0 * G_UG
    gyro_bias_random_walk: float = 2.0e-5
    accel_bias_random_walk: float = 3.0e-4
    gyro_initial_bias_std: float = 0.3 * DEG
    accel_initial_bias_std: float = 0.05
    timestamp_jitter_s: float = 2.0e-5
    noise_free: bool = False

    def __post_init__(self) -> None:
        check_range("rate_hz", self.rate_hz, 50.0, 2000.0, " Hz")
        check_range("gravity_mps2", self.gravity_mps2, 9.7, 9.9, " m/s²")
        for name, hi in (
            ("gyro_noise_density", 0.01),
            ("accel_noise_density", 0.1),
            ("gyro_bias_random_walk", 0.01),
            ("accel_bias_random_walk", 0.1),
            ("gyro_initial_bias_std", 0.2),
            ("accel_initial_bias_std", 1.0),
        ):
            check_range(name, getattr(self, name), 0.0, hi)
        check_range("timestamp_jitter_s", self.timestamp_jitter_s, 0.0, 0.1 / self.rate_hz, " s")

    def noise(self) -> ImuNoise:
        return ImuNoise(
            gyro_noise_density=self.gyro_noise_density,
            accel_noise_density=self.accel_noise_density,
            gyro_bias_random_walk=self.gyro_bias_random_walk,
            accel_bias_random_walk=self.accel_bias_random_walk,
        )


@dataclass(frozen=True)
class ImuTruth:
    """The exact IMU signals and biases at the sample times (for ground truth and tests)."""

    t_s: np.ndarray
    R_WfromI: np.ndarray
    p_IinW: np.ndarray
    v_IinW: np.ndarray
    specific_force: np.ndarray
    omega_I: np.ndarray
    gyro_bias: np.ndarray
    accel_bias: np.ndarray


def imu_sample_times(t0_s: float, t1_s: float, cfg: ImuConfig, rng: np.random.Generator):
    """Jittered sampling instants on the nominal grid ``t0 + k / rate`` within [t0, t1]."""
    n = int(np.floor((t1_s - t0_s) * cfg.rate_hz)) + 1
    t = t0_s + np.arange(n) / cfg.rate_hz
    if cfg.timestamp_jitter_s > 0:
        t = t + rng.normal(0.0, cfg.timestamp_jitter_s, size=n)
    return np.clip(t, t0_s, t1_s)


def rig_imu_truth(
    pelvis: PelvisKinematics, T_PfromI: np.ndarray, t_s: np.ndarray, gravity: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Exact IMU pose, velocity, specific force and angular rate at times ``t_s``.

    ``α_P`` comes from a central difference of ``ω_P`` (step 1e-4 s; the pelvis motion is
    smooth, so its error is ~1e-8 relative).
    """
    R_WP, p_P, v_P, a_P, w_P = pelvis(t_s)
    h = 1e-4
    alpha_P = (pelvis(t_s + h)[4] - pelvis(t_s - h)[4]) / (2 * h)
    R_PI, p_IinP = T_PfromI[:3, :3], T_PfromI[:3, 3]
    R_WI = R_WP @ R_PI
    p_I = p_P + R_WP @ p_IinP
    lever_v = np.cross(w_P, p_IinP)
    v_I = v_P + np.einsum("nij,nj->ni", R_WP, lever_v)
    lever_a = np.cross(alpha_P, p_IinP) + np.cross(w_P, lever_v)
    a_I = a_P + np.einsum("nij,nj->ni", R_WP, lever_a)
    g_tilde = np.array([0.0, 0.0, gravity])
    f_I = np.einsum("nji,nj->ni", R_WI, a_I + g_tilde)
    w_I = w_P @ R_PI  # R_PI^T ω_P for each row
    return R_WI, p_I, v_I, f_I, w_I


def simulate_imu(
    pelvis: PelvisKinematics,
    T_PfromI: np.ndarray,
    t0_s: float,
    t1_s: float,
    cfg: ImuConfig,
    rng: np.random.Generator,
) -> tuple[ImuSamples, ImuTruth]:
    """Measured IMU stream over [t0, t1] and the exact signals behind it."""
    t = imu_sample_times(t0_s, t1_s, cfg, rng)
    R_WI, p_I, v_I, f_I, w_I = rig_imu_truth(pelvis, T_PfromI, t, cfg.gravity_mps2)
    n = len(t)
    if cfg.noise_free:
        b_g = np.zeros((n, 3))
        b_a = np.zeros((n, 3))
        accel, gyro = f_I.copy(), w_I.copy()
    else:
        dt = np.diff(t, prepend=t[0])[:, None]
        b_g = rng.normal(0, cfg.gyro_initial_bias_std, 3) + np.cumsum(
            cfg.gyro_bias_random_walk * np.sqrt(dt) * rng.standard_normal((n, 3)), axis=0
        )
        b_a = rng.normal(0, cfg.accel_initial_bias_std, 3) + np.cumsum(
            cfg.accel_bias_random_walk * np.sqrt(dt) * rng.standard_normal((n, 3)), axis=0
        )
        sq = np.sqrt(cfg.rate_hz)
        gyro = w_I + b_g + cfg.gyro_noise_density * sq * rng.standard_normal((n, 3))
        accel = f_I + b_a + cfg.accel_noise_density * sq * rng.standard_normal((n, 3))
    t_ns = np.round(t * 1e9).astype(np.int64)
    samples = ImuSamples(t_ns=t_ns, accel=accel, gyro=gyro)
    truth = ImuTruth(
        t_s=t,
        R_WfromI=R_WI,
        p_IinW=p_I,
        v_IinW=v_I,
        specific_force=f_I,
        omega_I=w_I,
        gyro_bias=b_g,
        accel_bias=b_a,
    )
    return samples, truth
