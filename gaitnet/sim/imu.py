"""Synthetic IMU: exact specific force and angular rate of the rig, plus BMI055-like errors.

Measurement model (thesis eq. (3.2), world z up, ``g̃ = [0, 0, g]``)::

    y_a = Q(M_a C(q) (a + g̃) + b_a + η_a)        (specific force in the IMU frame)
    y_g = Q(M_g ω_I + b_g + η_g)                  (angular rate in the IMU frame)

with ``C(q) = R_IfromW``, ``M`` the session's scale / cross-axis errors and ``Q`` the
quantisation (:class:`ImuCalibration`); ``f`` and ``ω`` are averaged over each sample period
(:func:`averaged_signals`, a decimation filter). The IMU is rigidly attached at ``T_BfromI`` to
a body B (the camera, which moves on the pelvis: :mod:`gaitnet.sim.mount_dynamics`):
``p_I = p_B + R_WB p_IinB``, ``ω_I = R_IB ω_B``, and
``a_I = a_B + R_WB (α_B × p_IinB + ω_B × (ω_B × p_IinB))`` where ``α_B = dω_B/dt`` (body
frame). Noise: white noise of density ``σ`` gives per-sample std ``σ √f``; the bias random walk
of density ``σ_b`` adds ``σ_b √Δt · N(0, 1)`` per sample; each session starts with a constant
bias drawn from ``N(0, initial_bias_std²)``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from gaitnet.checks import check_range
from gaitnet.io.types import ImuNoise, ImuSamples

# (R_WfromP (n,3,3), p_PinW (n,3), v (n,3), a (n,3), omega_P (n,3)) at times t (n,)
PelvisKinematics = Callable[
    [np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]
]

DEG = np.pi / 180.0
G_UG = 9.80665e-6  # one micro-g in m/s²
ACCEL_LSB_4G = 8.0 * 9.80665 / 4096  # ±4 g over 12 bit: 1.95 mg
GYRO_LSB_1000DPS = 2000.0 * DEG / 65536  # ±1000 °/s over 16 bit: 0.0305 °/s


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

    Sensor errors a filter must estimate (drawn once per session by
    :func:`draw_imu_calibration`; docs/references.md, *Simulator realism: IMU and timing*):
    per-axis scale factor errors uniform within ±``accel_scale_tol`` / ±``gyro_scale_tol``
    (BMI055 sensitivity tolerance; 0–0.1) and cross-axis sensitivities (axis misalignment)
    uniform within ±``accel_cross_axis_tol`` / ±``gyro_cross_axis_tol`` (0–0.1); outputs
    quantised to ``accel_lsb_mps2`` (0–0.5 m/s²; default ±4 g at 12 bit) and ``gyro_lsb_rad_s``
    (0–0.01 rad/s; default ±1000 °/s at 16 bit), 0 = not quantised. ``noise_free`` gives the
    exact signals: no noise, bias, scale, misalignment or quantisation.
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
    accel_scale_tol: float = 0.02
    gyro_scale_tol: float = 0.01
    accel_cross_axis_tol: float = 0.01
    gyro_cross_axis_tol: float = 0.01
    accel_lsb_mps2: float = ACCEL_LSB_4G
    gyro_lsb_rad_s: float = GYRO_LSB_1000DPS
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
        for name in ("accel_scale_tol", "gyro_scale_tol", "accel_cross_axis_tol",
                     "gyro_cross_axis_tol"):  # fmt: skip
            check_range(name, getattr(self, name), 0.0, 0.1)
        check_range("accel_lsb_mps2", self.accel_lsb_mps2, 0.0, 0.5, " m/s²")
        check_range("gyro_lsb_rad_s", self.gyro_lsb_rad_s, 0.0, 0.01, " rad/s")

    def noise(self) -> ImuNoise:
        return ImuNoise(
            gyro_noise_density=self.gyro_noise_density,
            accel_noise_density=self.accel_noise_density,
            gyro_bias_random_walk=self.gyro_bias_random_walk,
            accel_bias_random_walk=self.accel_bias_random_walk,
        )


@dataclass(frozen=True)
class ImuCalibration:
    """One session's sensor errors (truth for ``groundtruth/imu_calibration.yaml``).

    Measured ``y_a = Q(M_a f + b_a + η_a)`` and ``y_g = Q(M_g ω + b_g + η_g)`` with ``M = I +
    diag(scale) + cross-axis`` and ``Q`` rounding to the LSB; IMU timestamps are the true
    sampling instants plus ``time_offset_s`` (the camera's clock is the reference).
    """

    accel_matrix: np.ndarray = field(default_factory=lambda: np.eye(3))
    gyro_matrix: np.ndarray = field(default_factory=lambda: np.eye(3))
    accel_lsb_mps2: float = 0.0
    gyro_lsb_rad_s: float = 0.0
    time_offset_s: float = 0.0

    def as_dict(self) -> dict[str, object]:
        return {
            "accel_matrix": np.round(self.accel_matrix, 9).tolist(),
            "accel_scale": np.round(np.diag(self.accel_matrix) - 1.0, 9).tolist(),
            "gyro_matrix": np.round(self.gyro_matrix, 9).tolist(),
            "gyro_scale": np.round(np.diag(self.gyro_matrix) - 1.0, 9).tolist(),
            "accel_lsb_mps2": float(self.accel_lsb_mps2),
            "gyro_lsb_rad_s": float(self.gyro_lsb_rad_s),
            "imu_time_offset_s": round(float(self.time_offset_s), 12),
        }


def _error_matrix(scale_tol: float, cross_tol: float, rng: np.random.Generator) -> np.ndarray:
    scale = rng.uniform(-1.0, 1.0, 3) * scale_tol
    cross = rng.uniform(-1.0, 1.0, (3, 3)) * cross_tol
    np.fill_diagonal(cross, 0.0)
    return np.eye(3) + np.diag(scale) + cross


def draw_imu_calibration(
    cfg: ImuConfig, rng: np.random.Generator, time_offset_s: float = 0.0
) -> ImuCalibration:
    """The session's scale / misalignment errors (uniform within the tolerances) and LSBs;
    ``rng`` is drawn from only when a tolerance is non-zero. Identity when ``noise_free``."""
    if cfg.noise_free:
        return ImuCalibration(time_offset_s=time_offset_s)
    eye = np.eye(3)
    accel = (
        _error_matrix(cfg.accel_scale_tol, cfg.accel_cross_axis_tol, rng)
        if cfg.accel_scale_tol > 0 or cfg.accel_cross_axis_tol > 0
        else eye
    )
    gyro = (
        _error_matrix(cfg.gyro_scale_tol, cfg.gyro_cross_axis_tol, rng)
        if cfg.gyro_scale_tol > 0 or cfg.gyro_cross_axis_tol > 0
        else eye
    )
    return ImuCalibration(accel, gyro, cfg.accel_lsb_mps2, cfg.gyro_lsb_rad_s, time_offset_s)


def quantise(values: np.ndarray, lsb: float) -> np.ndarray:
    """``values`` rounded to multiples of ``lsb`` (unchanged when ``lsb`` is 0)."""
    return np.round(values / lsb) * lsb if lsb > 0 else values


@dataclass(frozen=True)
class ImuTruth:
    """The exact IMU signals and biases at the true sample times ``t_s`` (for ground truth and
    tests); ``t_ns`` are the samples' timestamps in ``imu.csv`` (``t_s`` + the time offset).
    Poses and velocities are at ``t_s``; ``specific_force`` and ``omega_I`` are averaged over
    the sample period centred on ``t_s`` (:func:`averaged_signals`)."""

    t_s: np.ndarray
    R_WfromI: np.ndarray
    p_IinW: np.ndarray
    v_IinW: np.ndarray
    specific_force: np.ndarray
    omega_I: np.ndarray
    gyro_bias: np.ndarray
    accel_bias: np.ndarray
    t_ns: np.ndarray | None = None


def imu_sample_times(t0_s: float, t1_s: float, cfg: ImuConfig, rng: np.random.Generator):
    """Jittered sampling instants on the nominal grid ``t0 + k / rate`` within [t0, t1]."""
    n = int(np.floor((t1_s - t0_s) * cfg.rate_hz)) + 1
    t = t0_s + np.arange(n) / cfg.rate_hz
    if cfg.timestamp_jitter_s > 0:
        t = t + rng.normal(0.0, cfg.timestamp_jitter_s, size=n)
    return np.clip(t, t0_s, t1_s)


def rig_imu_truth(
    body: PelvisKinematics, T_BfromI: np.ndarray, t_s: np.ndarray, gravity: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Exact IMU pose, velocity, specific force and angular rate at times ``t_s`` for an IMU
    rigidly attached at ``T_BfromI`` to a body B moving as ``body`` (the pelvis, or the camera
    when the mount moves: :func:`gaitnet.sim.mount_dynamics.compose_kinematics`).

    ``α_B`` comes from a central difference of ``ω_B`` (step 1e-4 s; the motion is smooth, so
    its error is ~1e-8 relative).
    """
    R_WP, p_P, v_P, a_P, w_P = body(t_s)
    h = 1e-4
    alpha_P = (body(t_s + h)[4] - body(t_s - h)[4]) / (2 * h)
    R_PI, p_IinP = T_BfromI[:3, :3], T_BfromI[:3, 3]
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


def averaged_signals(
    body: PelvisKinematics, T_BfromI: np.ndarray, t_s: np.ndarray, cfg: ImuConfig
) -> tuple[np.ndarray, np.ndarray]:
    """Specific force and angular rate averaged over each sample period centred on ``t_s``
    (4-point Gauss–Legendre), as a MEMS IMU's decimation filter delivers them: the samples
    keep the integral of the signal (Δv, Δθ), so the heel-strike shocks' 10–30 Hz content
    integrates correctly at 200 Hz instead of aliasing (:mod:`gaitnet.sim.mount_dynamics`)."""
    nodes, weights = np.polynomial.legendre.leggauss(4)
    half = 0.5 / cfg.rate_hz
    f = np.zeros((len(t_s), 3))
    w = np.zeros((len(t_s), 3))
    for x, weight in zip(nodes, weights, strict=True):
        _, _, _, f_k, w_k = rig_imu_truth(body, T_BfromI, t_s + half * x, cfg.gravity_mps2)
        f += 0.5 * weight * f_k
        w += 0.5 * weight * w_k
    return f, w


def simulate_imu(
    body: PelvisKinematics,
    T_BfromI: np.ndarray,
    t0_s: float,
    t1_s: float,
    cfg: ImuConfig,
    rng: np.random.Generator,
    calibration: ImuCalibration | None = None,
) -> tuple[ImuSamples, ImuTruth]:
    """Measured IMU stream over [t0, t1] and the exact signals behind it.

    ``body``/``T_BfromI``: see :func:`rig_imu_truth`. ``calibration``: the session's scale,
    misalignment, quantisation and time offset (:func:`draw_imu_calibration`); None = ideal.
    Samples whose timestamp would be negative (a negative offset at ``t0 = 0``) are left out.
    """
    cal = calibration if calibration is not None else ImuCalibration()
    t = imu_sample_times(t0_s, t1_s, cfg, rng)
    t = t[t + cal.time_offset_s >= 0.0]
    R_WI, p_I, v_I, _, _ = rig_imu_truth(body, T_BfromI, t, cfg.gravity_mps2)
    f_I, w_I = averaged_signals(body, T_BfromI, t, cfg)
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
        gyro = (
            w_I @ cal.gyro_matrix.T
            + b_g
            + cfg.gyro_noise_density * sq * rng.standard_normal((n, 3))
        )
        accel = (
            f_I @ cal.accel_matrix.T
            + b_a
            + cfg.accel_noise_density * sq * rng.standard_normal((n, 3))
        )
        gyro = quantise(gyro, cal.gyro_lsb_rad_s)
        accel = quantise(accel, cal.accel_lsb_mps2)
    t_ns = np.round((t + cal.time_offset_s) * 1e9).astype(np.int64)
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
        t_ns=t_ns,
    )
    return samples, truth
