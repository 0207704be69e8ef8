"""Pelvis trajectory: smooth (C²+) progression and oscillations, and a height set by the legs.

Pelvis frame P: origin at the SMPL pelvis joint, x forward, y left, z up. Its pose is six
channels — position ``(x, y, z)`` and Z-Y-X Euler angles ``(ψ yaw, θ tilt, φ obliquity)`` with
``R_WfromP = Rz(ψ) Ry(θ) Rx(φ)`` (positive tilt = anterior, front down; positive obliquity =
left side up). The channels are built on a 1 kHz grid and interpolated by one quintic spline,
so positions, velocities, accelerations and angular rates all come from the same C⁴ spline
and are exactly consistent with each other.

Construction (step phase ``Φ(t)``: a C² spline through ``Φ(h_k) = k`` at the heel strikes;
``E(t)``: a C³ envelope rising from 0 at the end of standing to 1 at the first heel strike and
back to 0 when the walk ends; ``Φ_L``: the phase of a left heel strike):
- progression ``s(t)`` along the path: a piecewise-linear curve through "midway between the
  feet at each heel strike" and "over the new stance ankle ``_OVER_ANKLE`` steps later" knots,
  convolved with a smooth kernel; it is constant while standing, so the start-up and
  slow-down are smooth;
- lateral sway ``E·A_lat·cos π(Φ − Φ_L − 0.6)`` (toward the stance foot, peak at mid-stance),
  rotation ``−E·A_rot·cos π(Φ − Φ_L)`` (left hip forward at left HS), obliquity
  ``E·A_obl·cos π(Φ − Φ_L − 0.3)`` (swing side drops in loading response), tilt
  ``E·A_tilt·cos 2π(Φ − 0.9)``;
- height: set by the legs, not prescribed. :func:`gaitnet.sim.gait_knee.stance_knee` designs
  the knee flexion of each leg while it carries the body (extended at heel strike and in mid-
  stance, a loading-response bump, bending as the leg stops counting in terminal stance;
  both legs extended while standing). :func:`design_heights` turns a knee angle into the
  pelvis height at which that leg's hip–ankle distance equals the two-link length.
  :func:`fit_height` fits a discrete smoothing spline (jerk penalty) to the weighted design
  heights — where both legs count the higher design yields to the lower one — subject to
  staying ``_FIT_GAP_M`` below both legs' reach bounds (a banded QP, solved by ADMM);
  :func:`build_pelvis` soft-minimises it (``−k log Σ exp(−z_i/k)``, below every argument)
  with the reach bounds. So the pelvis vaults over the nearly straight stance leg and is
  lowest in double support; its vertical excursion follows from the step and leg lengths
  (about 3–5 cm per step at 1.2–1.4 m/s).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import BSpline, CubicSpline, make_interp_spline
from scipy.linalg import cho_solve_banded, cholesky_banded, solveh_banded
from scipy.ndimage import maximum_filter1d

from gaitnet.sim.gait_plan import LEFT, StepPlan, WalkPath, smoothstep7
from gaitnet.sim.pelvis_euler import alpha_body, euler_zyx_matrix, omega_body

__all__ = [
    "PelvisGrid",
    "PelvisParams",
    "PelvisTrajectory",
    "build_pelvis",
    "design_heights",
    "euler_zyx_matrix",
    "fit_height",
    "motion_end_time",
    "pelvis_grid",
    "reach_bounds",
]

GRID_DT_S = 1e-3
_SOFTMIN_K_M = 3e-5
_REACH_MARGIN_M = 2e-5
_FIT_GAP_M = 1.5e-4  # the fitted height stays this far below the reach bounds
_OVER_ANKLE = 0.5  # the pelvis passes over the stance ankle this many steps after its HS
_YIELD_M = 5e-4  # a leg whose design is this much higher than the other's counts e times less
_ADMM_RHO = 1000.0  # the constrained fit (z ≤ bound): ADMM penalty and iterations (what is
_ADMM_ITERATIONS = 100  # ... left above the bound, a few µm, goes by the smooth correction)


@dataclass(frozen=True)
class PelvisParams:
    """Amplitudes [m, rad] and smoothing widths [s] of the pelvis motion.

    ``height_fit_s``: smoothing scale of the height fit; ``height_fix_s``: half width of the
    correction that removes what the constrained fit leaves above the bounds (µm);
    ``height_hold_s``: the height is blended to constant over this long around standing.
    """

    lateral_m: float
    rotation_rad: float
    obliquity_rad: float
    tilt_rad: float
    progression_smooth_s: float = 0.4
    height_fit_s: float = 0.05
    height_fix_s: float = 0.05
    height_hold_s: float = 0.25


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
        return R, c0[:, :3], c1[:, :3], c2[:, :3], omega_body(c0[:, 3:], c1[:, 3:])

    def angular_acceleration(self, t: np.ndarray) -> np.ndarray:
        """``dω_P/dt`` in the pelvis frame (n, 3)."""
        c0, c1, c2 = (self._eval(t, nu) for nu in (0, 1, 2))
        return alpha_body(c0[:, 3:], c1[:, 3:], c2[:, 3:])


def _kernel_smooth(x: np.ndarray, half_width_s: float) -> np.ndarray:
    """Convolution with a normalised triweight kernel ``(1 − u²)³`` (edges held constant)."""
    n = max(1, int(round(half_width_s / GRID_DT_S)))
    u = np.arange(-n, n + 1) / (n + 1)
    k = (1.0 - u * u) ** 3
    k /= k.sum()
    padded = np.concatenate([np.full(n, x[0]), x, np.full(n, x[-1])])
    return np.convolve(padded, k, mode="valid")


def _progression(t: np.ndarray, plan: StepPlan, ankle_x: float, w: float) -> np.ndarray:
    """Arc length of the pelvis: PL through heel-strike and mid-stance knots, smoothed.

    At each heel strike the pelvis is midway between the feet, ``_OVER_ANKLE`` of that step
    later over the new stance ankle (the closing step lands beside: the pelvis stops there).
    """
    h, arc = plan.step_hs, plan.step_arc
    n = len(h) - 1
    T = np.diff(h)
    knots_t, knots_s = [plan.t_first_move], [0.0]
    for k in range(1, n + 1):
        knots_t += [h[k], h[k] + _OVER_ANKLE * T[k - 1]]
        knots_s += [0.5 * (arc[k - 1] + arc[k]), arc[k]]
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
    plan: StepPlan,
    path: WalkPath,
    p: PelvisParams,
    *,
    t_go: float,
    t_end: float,
    ankle_x: float,
    sway: Callable[[np.ndarray], np.ndarray] | None = None,
) -> PelvisGrid:
    """Progression, sway and rotations on the grid over ``[0, t_end]`` (moving from ``t_go``).

    ``ankle_x`` is the ankle's forward offset from the sole centre (shoe frame); ``sway(t)``
    (n, 2) the postural sway (forward, left) [m] while standing, faded out by ``1 − E``.
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
    normal = path.normal(s)
    xy = path.point(s) + normal * lateral[:, None]
    if sway is not None:
        ap_ml = sway(t) * (1.0 - E)[:, None]
        forward = np.stack([normal[:, 1], -normal[:, 0]], axis=-1)
        xy = xy + forward * ap_ml[:, :1] + normal * ap_ml[:, 1:]
    return PelvisGrid(t, xy, yaw, tilt, obl, E, phi, float(len(h) - 1))


def reach_bounds(
    grid: PelvisGrid, ankles: np.ndarray, hips_in_P: np.ndarray, reach: float | np.ndarray
) -> np.ndarray:
    """Highest pelvis z per leg (n, 2) keeping the hip–ankle distance ≤ ``reach`` − margin.

    ``reach`` is a scalar or per time and leg (n, 2).
    """
    reach = np.broadcast_to(np.asarray(reach, dtype=np.float64), ankles.shape[:2])
    off = np.einsum("nij,sj->nsi", grid.rotation(), hips_in_P)  # (n, 2, 3)
    dxy = grid.xy[:, None, :] + off[..., :2] - ankles[..., :2]
    rest = reach**2 - np.sum(dxy * dxy, axis=-1)
    if np.any(rest < (0.3 * reach) ** 2):
        raise ValueError("gait geometry out of reach: steps too long for the legs")
    return ankles[..., 2] + np.sqrt(rest) - off[..., 2] - _REACH_MARGIN_M


def _leg_reach(thigh_m: np.ndarray, shank_m: np.ndarray, knee_rad: np.ndarray) -> np.ndarray:
    """Hip–ankle distance of a two-link leg (per side, last axis) with knee flexion ``knee_rad``."""
    return np.sqrt(thigh_m**2 + shank_m**2 + 2.0 * thigh_m * shank_m * np.cos(knee_rad))


def design_heights(
    grid: PelvisGrid,
    ankles: np.ndarray,
    hips_in_P: np.ndarray,
    knee: np.ndarray,
    thigh_m: np.ndarray,
    shank_m: np.ndarray,
) -> np.ndarray:
    """Pelvis height (n, 2) at which each leg has the designed knee flexion (NaN where none)."""
    designed = np.isfinite(knee)
    reach = _leg_reach(thigh_m, shank_m, np.where(designed, knee, 0.0))
    return np.where(designed, reach_bounds(grid, ankles, hips_in_P, reach), np.nan)


def fit_height(
    grid: PelvisGrid,
    targets: np.ndarray,
    weights: np.ndarray,
    upper: np.ndarray,
    p: PelvisParams,
    still: tuple[float, float],
    constrained: bool = True,
) -> tuple[np.ndarray, np.ndarray]:
    """Smooth pelvis height on the grid that follows the legs' designs and stays reachable.

    ``targets``/``weights`` (n, 2) from :func:`design_heights` and
    :func:`gaitnet.sim.gait_knee.stance_knee`; where both legs count, the weight of the higher
    design is divided by ``1 + w_other·exp(Δ/_YIELD_M)``.
    The desired height minimises ``Σ_i w_i (z − target_i)² + (s/Δt)⁶ Σ (Δ³z)²`` (a discrete
    smoothing spline penalising jerk, ``s = p.height_fit_s``); with ``constrained`` the same
    objective is minimised subject to ``z ≤ upper − _FIT_GAP_M`` (a banded QP, by ADMM) and the
    few µm that leaves above go by a smooth correction (the excess dilated and smoothed over
    ``p.height_fix_s``). Both are made exactly constant before ``still[0]`` and after
    ``still[1]`` (standing) by a C³ blend over ``p.height_hold_s`` (they hardly change there).
    Returns the height (the desired one if not ``constrained``) and the desired height.
    """
    w = np.where(np.isfinite(targets), weights, 0.0)
    y = np.where(w > 0.0, targets, 0.0)
    # Where both legs count, the higher one yields to the lower one (a smooth soft-min).
    rise = np.clip((y - y[:, ::-1]) / _YIELD_M, -50.0, 50.0)
    w = w / (1.0 + w[:, ::-1] * np.exp(rise))
    w_sum = np.sum(w, axis=1)
    rhs = np.sum(w * y, axis=1)
    base = float(np.sum(rhs) / np.sum(w_sum))
    ab = _jerk_normal_matrix(len(w_sum), (p.height_fit_s / GRID_DT_S) ** 6)
    t, ramp = grid.t, p.height_hold_s
    i0 = min(int(np.searchsorted(t, still[0])), len(t) - 1)
    up = smoothstep7((t - still[0]) / ramp)
    i1 = min(int(np.searchsorted(t, still[1])), len(t) - 1)
    down = smoothstep7((still[1] - t) / ramp)

    def hold(z: np.ndarray) -> np.ndarray:
        z = z[i0] + up * (z - z[i0])
        return z[i1] + down * (z - z[i1])

    m = ab.copy()
    m[3] += w_sum
    q = rhs - base * w_sum
    desired = hold(solveh_banded(m, q) + base)
    if not constrained:
        return desired, desired
    bound = upper - _FIT_GAP_M
    z = desired
    if np.max(desired - bound) > 0.0:
        z = hold(_admm_below(m, q, desired - base, bound - base) + base)
    excess = np.maximum(z - bound, 0.0)
    if np.max(excess) > 0.0:
        z = hold(z - _kernel_smooth(_dilate(excess, p.height_fix_s), p.height_fix_s))
    return z, desired


def _admm_below(ab: np.ndarray, q: np.ndarray, z0: np.ndarray, ub: np.ndarray) -> np.ndarray:
    """``argmin ½zᵀAz − qᵀz`` subject to ``z ≤ ub`` by ADMM (``A`` banded, upper storage)."""
    m = ab.copy()
    m[3] += _ADMM_RHO
    chol = cholesky_banded(m)
    v = np.minimum(z0, ub)
    lam = np.zeros_like(v)
    z = z0
    for _ in range(_ADMM_ITERATIONS):
        z = cho_solve_banded((chol, False), q + _ADMM_RHO * (v - lam))
        v = np.minimum(z + lam, ub)
        lam += z - v
    return z


def _jerk_normal_matrix(n: int, mu: float) -> np.ndarray:
    """``μ D₃ᵀ D₃`` (third differences) in upper banded storage (4, n)."""
    c = np.array([-1.0, 3.0, -3.0, 1.0])
    ab = np.zeros((4, n))
    for a in range(4):
        for b in range(a, 4):
            ab[3 - (b - a), b : n - 3 + b] += mu * c[a] * c[b]
    return ab


def _dilate(x: np.ndarray, half_width_s: float) -> np.ndarray:
    n = max(1, int(round(half_width_s / GRID_DT_S)))
    return maximum_filter1d(x, size=2 * n + 1, mode="nearest")


def build_pelvis(grid: PelvisGrid, z_fit: np.ndarray, bounds: np.ndarray) -> PelvisTrajectory:
    """Final pelvis: the fitted height soft-minimised with the reach bounds (n, 2).

    ``z_fit`` from :func:`fit_height` keeps ``_FIT_GAP_M`` below the bounds, so the soft-min
    only guarantees reach and hardly changes it.
    """
    z = _softmin(np.column_stack([z_fit, bounds]))
    channels = np.stack(
        [grid.xy[:, 0], grid.xy[:, 1], z, grid.yaw, grid.tilt, grid.obliquity], axis=-1
    )
    t = grid.t
    return PelvisTrajectory(make_interp_spline(t, channels, k=5), float(t[-1]))


def _softmin(z: np.ndarray) -> np.ndarray:
    """``−k log Σ_i exp(−z_i/k)`` over the last axis (smooth, ≤ every ``z_i``)."""
    k = _SOFTMIN_K_M
    m = np.min(z, axis=-1, keepdims=True)
    return (m - k * np.log(np.sum(np.exp(-(z - m) / k), axis=-1, keepdims=True)))[..., 0]
