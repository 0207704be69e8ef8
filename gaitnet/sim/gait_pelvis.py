"""Pelvis trajectory: smooth (C²+) progression, oscillations and a reach-limited height.

Pelvis frame P: origin at the SMPL pelvis joint, x forward, y left, z up. Its pose is six
channels — position ``(x, y, z)`` and Z-Y-X Euler angles ``(ψ yaw, θ tilt, φ obliquity)`` with
``R_WfromP = Rz(ψ) Ry(θ) Rx(φ)`` (positive tilt = anterior, front down; positive obliquity =
left side up). The channels are built on a 1 kHz grid and interpolated by one quintic spline,
so positions, velocities, accelerations and angular rates all come from the same C⁴ spline
and are exactly consistent with each other.

Construction (step phase ``Φ(t)``: a C² spline through ``Φ(h_k) = k`` at the heel strikes;
``E(t)``: a C³ envelope rising from 0 at the end of standing to 1 at the first heel strike and
back to 0 when the walk ends; ``Φ_L``: the phase of a left heel strike):
- progression ``s(t)`` along the path: a piecewise-linear curve through "pelvis over the
  stance ankle ``_OVER_ANKLE`` steps after its heel strike" knots, convolved with a smooth
  kernel; it is constant while standing, so the start-up and slow-down are smooth;
- lateral sway ``E·A_lat·cos π(Φ − Φ_L − 0.6)`` (toward the stance foot, peak at mid-stance),
  rotation ``−E·A_rot·cos π(Φ − Φ_L)`` (left hip forward at left HS), obliquity
  ``E·A_obl·cos π(Φ − Φ_L − 0.3)`` (swing side drops in loading response), tilt
  ``E·A_tilt·cos 2π(Φ − 0.9)``;
- height (:func:`nominal_height`, :func:`lower_to_fit`, :func:`build_pelvis`): a nominal
  ``z_stand − E·A_v·(1 + cos 2π(Φ − _PHASE_LOWEST))`` (lowest at heel strike / double
  support, highest at mid-stance) lowered as a whole until both hip–ankle distances stay
  below the reach, then soft-minimised (``−k log Σ exp(−z_i/k)``, below every argument) with
  the per-leg reach bounds. So both ankles are always reachable and there is no kink.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import BSpline, CubicSpline, make_interp_spline
from scipy.ndimage import maximum_filter1d

from gaitnet.sim.gait_plan import LEFT, StepPlan, WalkPath, smoothstep7

__all__ = [
    "PelvisGrid",
    "PelvisParams",
    "PelvisTrajectory",
    "build_pelvis",
    "euler_zyx_matrix",
    "lower_to_fit",
    "motion_end_time",
    "nominal_height",
    "pelvis_grid",
    "reach_bounds",
    "standing_height",
]

GRID_DT_S = 1e-3
_SOFTMIN_K_M = 0.001
_REACH_MARGIN_M = 2e-4
_STAND_GAP_M = 5e-4  # the nominal height stays this far below the reach bound when standing,
_WALK_GAP_M = 0.004  # ... and this much further when walking
_PHASE_LOWEST = 0.0  # step phase of the lowest pelvis (double support)
_OVER_ANKLE = 0.45  # the pelvis passes over the stance ankle this many steps after its HS


@dataclass(frozen=True)
class PelvisParams:
    """Amplitudes [m, rad] and smoothing widths [s] of the pelvis motion."""

    vertical_m: float
    lateral_m: float
    rotation_rad: float
    obliquity_rad: float
    tilt_rad: float
    progression_smooth_s: float = 0.4
    height_smooth_s: float = 0.25


def euler_zyx_matrix(yaw: np.ndarray, tilt: np.ndarray, obl: np.ndarray) -> np.ndarray:
    """``Rz(yaw) Ry(tilt) Rx(obl)`` for arrays of angles → ``(..., 3, 3)``."""
    cz, sz, cy, sy, cx, sx = (f(a) for a in (yaw, tilt, obl) for f in (np.cos, np.sin))
    return np.stack(
        [
            np.stack([cz * cy, cz * sy * sx - sz * cx, cz * sy * cx + sz * sx], axis=-1),
            np.stack([sz * cy, sz * sy * sx + cz * cx, sz * sy * cx - cz * sx], axis=-1),
            np.stack([-sy, cy * sx, cy * cx], axis=-1),
        ],
        axis=-2,
    )


def _omega_body(ang: np.ndarray, d1: np.ndarray) -> np.ndarray:
    """Body angular velocity of Z-Y-X Euler angles ``(ψ, θ, φ)`` with rates ``d1``."""
    _, th, ph = ang.T
    dps, dth, dph = d1.T
    return np.stack(
        [
            dph - dps * np.sin(th),
            dth * np.cos(ph) + dps * np.cos(th) * np.sin(ph),
            -dth * np.sin(ph) + dps * np.cos(th) * np.cos(ph),
        ],
        axis=-1,
    )


def _alpha_body(ang: np.ndarray, d1: np.ndarray, d2: np.ndarray) -> np.ndarray:
    """Time derivative of :func:`_omega_body` (body angular acceleration)."""
    _, th, ph = ang.T
    dps, dth, dph = d1.T
    aps, ath, aph = d2.T
    sth, cth, sph, cph = np.sin(th), np.cos(th), np.sin(ph), np.cos(ph)
    return np.stack(
        [
            aph - aps * sth - dps * cth * dth,
            ath * cph
            - dth * sph * dph
            + aps * cth * sph
            - dps * sth * dth * sph
            + dps * cth * cph * dph,
            -ath * sph
            - dth * cph * dph
            + aps * cth * cph
            - dps * sth * dth * cph
            - dps * cth * sph * dph,
        ],
        axis=-1,
    )


@dataclass(frozen=True, eq=False)
class PelvisTrajectory:
    """Quintic spline of the six pelvis channels ``(x, y, z, yaw, tilt, obliquity)``."""

    spline: BSpline
    t_end: float

    def _eval(self, t: np.ndarray, nu: int) -> np.ndarray:
        t = np.clip(np.asarray(t, dtype=np.float64), 0.0, self.t_end)
        return self.spline(t, nu)

    def pose(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``R_WfromP (n, 3, 3)`` and ``p_PinW (n, 3)``."""
        c = self._eval(t, 0)
        return euler_zyx_matrix(c[:, 3], c[:, 4], c[:, 5]), c[:, :3]

    def kinematics(self, t: np.ndarray) -> tuple[np.ndarray, ...]:
        """``R_WfromP, p_PinW, v_PinW, a_PinW, omega_PinP`` (angular rate in the pelvis frame)."""
        c0, c1, c2 = (self._eval(t, nu) for nu in (0, 1, 2))
        R = euler_zyx_matrix(c0[:, 3], c0[:, 4], c0[:, 5])
        return R, c0[:, :3], c1[:, :3], c2[:, :3], _omega_body(c0[:, 3:], c1[:, 3:])

    def angular_acceleration(self, t: np.ndarray) -> np.ndarray:
        """``dω_P/dt`` in the pelvis frame (n, 3)."""
        c0, c1, c2 = (self._eval(t, nu) for nu in (0, 1, 2))
        return _alpha_body(c0[:, 3:], c1[:, 3:], c2[:, 3:])


def _kernel_smooth(x: np.ndarray, half_width_s: float) -> np.ndarray:
    """Convolution with a normalised triweight kernel ``(1 − u²)³`` (edges held constant)."""
    n = max(1, int(round(half_width_s / GRID_DT_S)))
    u = np.arange(-n, n + 1) / (n + 1)
    k = (1.0 - u * u) ** 3
    k /= k.sum()
    padded = np.concatenate([np.full(n, x[0]), x, np.full(n, x[-1])])
    return np.convolve(padded, k, mode="valid")


def _progression(t: np.ndarray, plan: StepPlan, ankle_x: float, w: float) -> np.ndarray:
    """Arc length of the pelvis: PL through mid-stance knots, smoothed by the kernel."""
    h, arc = plan.step_hs, plan.step_arc
    n = len(h) - 1
    T = np.diff(h)
    knots_t = [plan.t_first_move] + [h[k] + _OVER_ANKLE * T[k - 1] for k in range(1, n + 1)]
    knots_s = [0.0] + [arc[k] for k in range(1, n)] + [arc[n - 1]]
    s_pl = np.interp(t, knots_t, np.asarray(knots_s) + ankle_x)
    return _kernel_smooth(s_pl, w)


def _phase(plan: StepPlan) -> CubicSpline:
    h = plan.step_hs
    T0, T1 = h[1] - h[0], h[-1] - h[-2]
    times = np.concatenate([[h[0] - T0], h, [h[-1] + T1]])
    return CubicSpline(times, np.arange(-1, len(h) + 1, dtype=float))


def _envelope(t: np.ndarray, t_up0: float, t_up1: float, t_dn0: float, t_dn1: float) -> np.ndarray:
    up = smoothstep7((t - t_up0) / (t_up1 - t_up0))
    return up * (1.0 - smoothstep7((t - t_dn0) / (t_dn1 - t_dn0)))


def motion_end_time(plan: StepPlan, p: PelvisParams) -> float:
    """When the pelvis comes to rest after the last step (before the final standing)."""
    h = plan.step_hs
    return float(h[-1] + _OVER_ANKLE * (h[-1] - h[-2]) + p.progression_smooth_s)


@dataclass(frozen=True, eq=False)
class PelvisGrid:
    """Planar pelvis channels on the 1 kHz grid (everything except the height)."""

    t: np.ndarray
    xy: np.ndarray  # (n, 2)
    yaw: np.ndarray
    tilt: np.ndarray
    obliquity: np.ndarray
    envelope: np.ndarray  # E(t) ∈ [0, 1]
    phase: np.ndarray  # Φ(t), Φ(h_k) = k
    phase_last_hs: float  # Φ of the closing step's heel strike (= number of steps)

    def rotation(self) -> np.ndarray:
        """``R_WfromP`` on the grid (n, 3, 3)."""
        return euler_zyx_matrix(self.yaw, self.tilt, self.obliquity)

    def hips(self, z: np.ndarray, hips_in_P: np.ndarray) -> np.ndarray:
        """Hip joints (n, 2, 3) for pelvis heights ``z`` (n,)."""
        p = np.column_stack([self.xy, z])
        return p[:, None, :] + np.einsum("nij,sj->nsi", self.rotation(), hips_in_P)


def pelvis_grid(
    plan: StepPlan, path: WalkPath, p: PelvisParams, *, t_go: float, t_end: float, ankle_x: float
) -> PelvisGrid:
    """Progression, sway and rotations on the grid over ``[0, t_end]`` (moving from ``t_go``).

    ``ankle_x`` is the ankle's forward offset from the sole centre (shoe frame).
    """
    t = np.arange(0.0, t_end + 0.5 * GRID_DT_S, GRID_DT_S)
    s = _progression(t, plan, ankle_x, p.progression_smooth_s)
    phi = _phase(plan)(t)
    h = plan.step_hs
    E = _envelope(t, t_go, h[1], h[-2], motion_end_time(plan, p))
    k_left = 1.0 if plan.step_side[0] == LEFT else 2.0
    yaw = path.heading(s) - E * p.rotation_rad * np.cos(np.pi * (phi - k_left))
    obl = E * p.obliquity_rad * np.cos(np.pi * (phi - k_left - 0.3))
    tilt = E * p.tilt_rad * np.cos(2 * np.pi * (phi - 0.9))
    lateral = E * p.lateral_m * np.cos(np.pi * (phi - k_left - 0.6))
    xy = path.point(s) + path.normal(s) * lateral[:, None]
    return PelvisGrid(t, xy, yaw, tilt, obl, E, phi, float(len(h) - 1))


def reach_bounds(
    grid: PelvisGrid, ankles: np.ndarray, hips_in_P: np.ndarray, reach: float
) -> np.ndarray:
    """Highest pelvis z per leg (n, 2) keeping the hip–ankle distance ≤ ``reach`` − margin."""
    off = np.einsum("nij,sj->nsi", grid.rotation(), hips_in_P)  # (n, 2, 3)
    dxy = grid.xy[:, None, :] + off[..., :2] - ankles[..., :2]
    rest = reach**2 - np.sum(dxy * dxy, axis=-1)
    if np.any(rest < (0.3 * reach) ** 2):
        raise ValueError("gait geometry out of reach: steps too long for the legs")
    return ankles[..., 2] + np.sqrt(rest) - off[..., 2] - _REACH_MARGIN_M


def standing_height(bounds: np.ndarray) -> float:
    """Pelvis height while standing (just below the reach bound at t = 0)."""
    return float(np.min(bounds[0])) - _STAND_GAP_M


def nominal_height(grid: PelvisGrid, p: PelvisParams, z_stand: float) -> np.ndarray:
    """Sinusoidal walking height: top at the standing height, ``2·vertical_m`` peak to peak.

    Lowest at step phase ``_PHASE_LOWEST`` (double support), highest half a step later.
    """
    wave = 1.0 + np.cos(2 * np.pi * (grid.phase - _PHASE_LOWEST))  # 2 at the lowest point
    return z_stand - grid.envelope * p.vertical_m * wave


def lower_to_fit(grid: PelvisGrid, z_nominal: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    """``z_nominal − E·δ`` with the smallest ``δ ≥ 0`` that keeps the steady walk (from the
    second heel strike to one step before the last) ``_STAND_GAP_M + _WALK_GAP_M`` below the
    reach bounds."""
    E = grid.envelope
    bound = np.min(bounds, axis=1) - _STAND_GAP_M - E * _WALK_GAP_M
    steady = (E > 0.99) & (grid.phase >= 2.0) & (grid.phase <= grid.phase_last_hs - 1.0)
    delta = max(0.0, float(np.max((z_nominal - bound)[steady]))) if np.any(steady) else 0.0
    return z_nominal - E * delta


def build_pelvis(
    grid: PelvisGrid, p: PelvisParams, z_nominal: np.ndarray, bounds: np.ndarray
) -> PelvisTrajectory:
    """Final pelvis: the nominal height lowered where needed, soft-min with the reach bounds.

    The lowering is :func:`lower_to_fit` plus a dilated-and-smoothed local term for what
    remains (start-up, slow-down), so the nominal keeps ``_STAND_GAP_M + E·_WALK_GAP_M`` below
    the bounds and the soft-min hardly bends it.
    """
    z0 = lower_to_fit(grid, z_nominal, bounds)
    bound = np.min(bounds, axis=1) - _STAND_GAP_M - grid.envelope * _WALK_GAP_M
    local = np.maximum(z0 - bound, 0.0)
    z0 = z0 - _kernel_smooth(_dilate(local, p.height_smooth_s), p.height_smooth_s)
    z = _softmin(np.column_stack([z0, bounds]))
    channels = np.stack(
        [grid.xy[:, 0], grid.xy[:, 1], z, grid.yaw, grid.tilt, grid.obliquity], axis=-1
    )
    t = grid.t
    return PelvisTrajectory(make_interp_spline(t, channels, k=5), float(t[-1]))


def _dilate(x: np.ndarray, half_width_s: float) -> np.ndarray:
    n = max(1, int(round(half_width_s / GRID_DT_S)))
    return maximum_filter1d(x, size=2 * n + 1, mode="nearest")


def _softmin(z: np.ndarray) -> np.ndarray:
    """``−k log Σ_i exp(−z_i/k)`` over the last axis (smooth, ≤ every ``z_i``)."""
    k = _SOFTMIN_K_M
    m = np.min(z, axis=-1, keepdims=True)
    return (m - k * np.log(np.sum(np.exp(-(z - m) / k), axis=-1, keepdims=True)))[..., 0]
