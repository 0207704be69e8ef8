"""A reference strapdown integrator: RK4 on (R, p, v) with spline-interpolated IMU samples.

It checks the simulator's IMU (:mod:`gaitnet.sim.imu`), in the tests and in
``benchmarks/validate_sim.py``: integrating the noise-free IMU from the true initial state must
recover the true trajectory, a real check of the specific-force / angular-rate model because
this code shares nothing with the IMU synthesis. Accuracy over speed (dense RK4 sub-steps); it
is not the estimator's propagation, which belongs to the filter.

Model (world z up, ``g̃ = [0, 0, g]``, ``f`` specific force and ``ω`` angular rate in the IMU
frame): ``Ṙ = R [ω]×``, ``ṗ = v``, ``v̇ = R f − g̃``.
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.spatial.transform import Rotation

from gaitnet.geometry import skew


def _rk4_step(R, p, v, t, h, f_of, w_of, g):
    """One RK4 step of the model (module docstring), re-orthonormalising R."""

    def deriv(R_, v_, tau):
        return R_ @ skew(w_of(tau)), v_, R_ @ f_of(tau) - g

    dR1, dp1, dv1 = deriv(R, v, t)
    dR2, dp2, dv2 = deriv(R + 0.5 * h * dR1, v + 0.5 * h * dv1, t + 0.5 * h)
    dR3, dp3, dv3 = deriv(R + 0.5 * h * dR2, v + 0.5 * h * dv2, t + 0.5 * h)
    dR4, dp4, dv4 = deriv(R + h * dR3, v + h * dv3, t + h)
    R_new = R + h / 6 * (dR1 + 2 * dR2 + 2 * dR3 + dR4)
    u, _, vt = np.linalg.svd(R_new)
    R_new = u @ vt
    p_new = p + h / 6 * (dp1 + 2 * dp2 + 2 * dp3 + dp4)
    v_new = v + h / 6 * (dv1 + 2 * dv2 + 2 * dv3 + dv4)
    return R_new, p_new, v_new


def integrate_imu(
    t_s: np.ndarray,
    accel: np.ndarray,
    gyro: np.ndarray,
    R0: np.ndarray,
    p0: np.ndarray,
    v0: np.ndarray,
    gravity: float,
    substeps: int = 2,
) -> tuple[np.ndarray, list[Rotation]]:
    """IMU positions (n, 3) and orientations at ``t_s`` (n,) in the world, integrated from
    ``R0 = R_WfromI``, ``p0``, ``v0`` at ``t_s[0]`` with ``substeps`` RK4 steps per sample."""
    f_spline = CubicSpline(t_s, accel)
    w_spline = CubicSpline(t_s, gyro)
    g = np.array([0.0, 0.0, gravity])
    R, p, v = np.array(R0, float), np.array(p0, float), np.array(v0, float)
    out = [p.copy()]
    rots = [Rotation.from_matrix(R)]
    for k in range(len(t_s) - 1):
        h = (t_s[k + 1] - t_s[k]) / substeps
        t = t_s[k]
        for _ in range(substeps):
            R, p, v = _rk4_step(R, p, v, t, h, f_spline, w_spline, g)
            t += h
        out.append(p.copy())
        rots.append(Rotation.from_matrix(R))
    return np.array(out), rots
