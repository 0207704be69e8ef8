"""The rig's motion relative to the pelvis: heel-strike shocks and the camera's wobble on its strap.

The pelvis joint trajectory (:class:`gaitnet.sim.gait.Walk`) is smooth and drives the skeleton;
the rig (camera with its IMU, one rigid body) sits on the belly on a strap and does not follow
it exactly. Its pose in the pelvis frame is the nominal mount (:meth:`MountConfig.T_PfromC`)
displaced by ``e(t)`` (pelvis frame) and turned by ``δθ(t)``::

    p_CinP(t) = p_nominal + e(t),   R_PfromC(t) = exp([δθ(t)]×) R_nominal,
    e = d_impact + x_wobble,        δθ = κ (ẑ × e)

- ``d_impact``: the shock of each heel strike as it reaches the rig — per initial contact a
  damped oscillation ``D (1 − e^{−τ/τ_r})⁵ e^{−ζ ω τ} sin(ω_d τ)`` (``τ`` time since the
  strike, ``τ_r`` = 5 ms: half the envelope after 10 ms, ``ω = 2π impact_freq_hz``), scaled
  so that its acceleration peaks at ``impact_peak_g · g · (v / 1.3 m/s)`` (``v`` the
  pelvis's horizontal speed at the strike) times a per-strike factor ``1 + 0.2 N(0, 1)``
  (clipped to 0.5–1.5), along a mostly vertical, slightly backward (braking) and medial
  direction. The displacement, its velocity and its acceleration are zero at the strike and
  decay to zero (no net motion), at sub-millimetre amplitude. Magnitudes: docs/references.md,
  *Simulator realism: IMU and timing*.
- ``x_wobble``: a damped spring per axis, ``ẍ + 2ζ_w ω_w ẋ + ω_w² x = −γ u`` with ``u`` the
  pelvis acceleration in the pelvis frame plus the impact acceleration (the strap is shaken
  by the body; ``γ = wobble_gain`` is the compliance as a fraction of a free spring-mass, 0 =
  rigid), integrated from rest at ``t = 0`` (bilinear transform at 1 kHz). Above its natural
  frequency the spring gives way, so the rig keeps about ``1 − γ`` of the shock's 10–30 Hz
  content (``impact_peak_g`` is the shock at the pelvis).
- ``κ`` (``wobble_tilt_deg_per_mm``): the rig rocks about its belt clip, so a fore-aft or
  lateral displacement tilts it (pitch / roll about the pelvis y / x axes).

``e`` is sampled at 1 kHz over the walk and interpolated by a cubic spline; poses, velocities
and accelerations all come from that spline, so the camera poses and the IMU agree exactly.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from scipy.interpolate import CubicSpline

from gaitnet.filters import lfilter2
from gaitnet.geometry import make_T, so3_exp, so3_right_jacobian
from gaitnet.sim.scene import SIDES

if TYPE_CHECKING:
    from gaitnet.sim.gait import Walk
    from gaitnet.sim.rig import MountConfig

__all__ = [
    "GRID_HZ",
    "MountMotion",
    "build_mount_motion",
    "compose_kinematics",
    "spring_response",
]

GRID_HZ = 1000.0  # sampling of e(t) before the spline
IMPACT_RISE_S = 0.005  # onset time constant of the shock (heel-pad compression)
IMPACT_ONSET_POWER = 5  # (1 − e^{−τ/τ_r})^5: a smooth onset (C⁴ at the strike)
IMPACT_STEP_CV = 0.2  # strike-to-strike variation of the shock amplitude
IMPACT_WINDOW_S = 0.4  # a shock has decayed to < 1e-4 of its peak by then (ζ ≥ 0.05, f ≥ 5 Hz)
G0 = 9.80665
REFERENCE_SPEED_MPS = 1.3  # impact_peak_g is the peak at this walking speed
# Shock direction in the pelvis frame (x forward, y left, z up) for a left heel strike; the
# right one mirrors y. Mostly vertical, with braking (backward) and medial components.
IMPACT_DIRECTION_LEFT = np.array([-0.35, -0.15, 1.0]) / np.linalg.norm([-0.35, -0.15, 1.0])


def _shock(tau: np.ndarray, freq_hz: float, damping: float) -> np.ndarray:
    """Unit shock displacement at times ``tau`` ≥ 0 after the strike (module docstring)."""
    w = 2 * np.pi * freq_hz
    wd = w * np.sqrt(max(1.0 - damping**2, 1e-6))
    onset = (1.0 - np.exp(-tau / IMPACT_RISE_S)) ** IMPACT_ONSET_POWER
    return onset * np.exp(-damping * w * tau) * np.sin(wd * tau)


def _shock_peak_acceleration(freq_hz: float, damping: float) -> float:
    """Peak |acceleration| of the unit shock (second differences on a 20 kHz grid)."""
    h = 5e-5
    d = _shock(np.arange(0.0, IMPACT_WINDOW_S, h), freq_hz, damping)
    return float(np.abs(np.diff(d, 2)).max() / h**2)


@dataclass(frozen=True, eq=False)
class MountMotion:
    """The camera pose in the pelvis frame over time (module docstring).

    ``spline`` interpolates ``[d_impact, x_wobble]`` (6 columns, metres, pelvis frame); None
    means a rigid mount. ``tilt_rad_per_m`` is ``κ``.
    """

    T_PfromC_nominal: np.ndarray
    spline: CubicSpline | None
    tilt_rad_per_m: float

    def _kappa(self) -> np.ndarray:
        # δθ = κ (ẑ × e) = K e
        return self.tilt_rad_per_m * np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]])

    def parts(self, t_s: np.ndarray, nu: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """``d_impact`` and ``x_wobble`` (n, 3) each (or their ``nu``-th derivatives)."""
        t = np.atleast_1d(np.asarray(t_s, dtype=np.float64))
        if self.spline is None:
            z = np.zeros((len(t), 3))
            return z, z.copy()
        v = self.spline(t, nu)
        return v[:, :3], v[:, 3:]

    def displacement(self, t_s: np.ndarray, nu: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """``e`` and ``δθ`` (n, 3) each, or their ``nu``-th time derivatives."""
        d, x = self.parts(t_s, nu)
        e = d + x
        return e, e @ self._kappa().T

    def T_PfromC(self, t_s: np.ndarray) -> np.ndarray:
        """Camera poses in the pelvis frame (n, 4, 4) at times ``t_s`` (n,)."""
        e, th = self.displacement(t_s)
        R0, p0 = self.T_PfromC_nominal[:3, :3], self.T_PfromC_nominal[:3, 3]
        return make_T(so3_exp(th) @ R0, p0 + e)

    def kinematics(self, t_s: np.ndarray) -> tuple[np.ndarray, ...]:
        """``(R_PfromC, p_CinP, v, a, ω)``: pose, velocity and acceleration of the camera centre
        relative to the pelvis (pelvis frame) and its angular rate relative to the pelvis
        (camera frame), exact derivatives of the spline."""
        t = np.atleast_1d(np.asarray(t_s, dtype=np.float64))
        e, th = self.displacement(t)
        de, dth = self.displacement(t, 1)
        dde, _ = self.displacement(t, 2)
        R0, p0 = self.T_PfromC_nominal[:3, :3], self.T_PfromC_nominal[:3, 3]
        # R_PC = exp(δθ) R0: R_PC^T dR_PC = R0^T [Jr(δθ) δθ̇]× R0
        w_body = np.einsum("nij,nj->ni", so3_right_jacobian(th), dth)
        return so3_exp(th) @ R0, p0 + e, de, dde, w_body @ R0


def compose_kinematics(parent, child):
    """Kinematics of a body moving relative to a moving parent (both like
    :data:`gaitnet.sim.imu.PelvisKinematics`: ``t -> (R_WfromB, p, v, a, ω_B)``; the child's
    relative ``(R_PfromC, p_CinP, v, a)`` in the parent frame and ``ω`` in its own frame).

    ``a_C = a_P + R_WP (α_P × p + ω_P × (ω_P × p) + 2 ω_P × ṗ + p̈)`` with ``α_P`` from a
    central difference of the parent's rate (step 1e-4 s).
    """

    def kin(t_s: np.ndarray) -> tuple[np.ndarray, ...]:
        t = np.atleast_1d(np.asarray(t_s, dtype=np.float64))
        R_WP, p_P, v_P, a_P, w_P = parent(t)
        h = 1e-4
        alpha_P = (parent(t + h)[4] - parent(t - h)[4]) / (2 * h)
        R_PC, p, dp, ddp, w_rel = child(t)
        wxp = np.cross(w_P, p)
        v = v_P + np.einsum("nij,nj->ni", R_WP, wxp + dp)
        a_rel = np.cross(alpha_P, p) + np.cross(w_P, wxp) + 2 * np.cross(w_P, dp) + ddp
        a = a_P + np.einsum("nij,nj->ni", R_WP, a_rel)
        w_C = np.einsum("nji,nj->ni", R_PC, w_P) + w_rel
        return R_WP @ R_PC, p_P + np.einsum("nij,nj->ni", R_WP, p), v, a, w_C

    return kin


def spring_response(u: np.ndarray, gain: float, w: float, zeta: float, fs: float) -> np.ndarray:
    """The damped spring ``ẍ + 2ζωẋ + ω²x = −γ u`` driven by ``u`` (N, …) sampled at ``fs``,
    from rest: the bilinear (Tustin) transform of ``−γ / (s² + 2ζωs + ω²)``, i.e. ``s = k (z −
    1) / (z + 1)``, ``k = 2 fs``, run as its difference equation along axis 0.

    Written out rather than taken from ``scipy.signal`` (``bilinear`` gives the same
    coefficients; a test compares them): :mod:`gaitnet.filters` runs the difference equation.
    """
    u = np.asarray(u, np.float64)
    k = 2.0 * fs
    a0 = k * k + 2 * zeta * w * k + w * w
    a = [1.0, (2 * w * w - 2 * k * k) / a0, (k * k - 2 * zeta * w * k + w * w) / a0]
    b = [-gain / a0, -2 * gain / a0, -gain / a0]  # numerator −γ (1 + z⁻¹)²
    return lfilter2(b, a, u)


def build_mount_motion(
    walk: Walk, mount: MountConfig, T_PfromC_nominal: np.ndarray, rng: np.random.Generator
) -> MountMotion:
    """The rig's motion for ``walk`` from the ``mount`` config's impact and wobble keys
    (:class:`gaitnet.sim.rig.MountConfig`); ``rng`` draws the per-strike amplitudes (only when
    impacts are on)."""
    kappa = float(np.deg2rad(mount.wobble_tilt_deg_per_mm) * 1000.0)
    impacts_on = mount.impact_peak_g > 0
    wobble_on = mount.wobble_gain > 0
    if not impacts_on and not wobble_on:
        return MountMotion(np.asarray(T_PfromC_nominal, np.float64), None, kappa)
    dt = 1.0 / GRID_HZ
    t = np.arange(0.0, walk.duration_s + 0.05, dt)
    d_imp = np.zeros((len(t), 3))
    if impacts_on:
        f_imp, z_imp = mount.impact_freq_hz, mount.impact_damping_ratio
        acc_peak = _shock_peak_acceleration(f_imp, z_imp)
        n_win = int(IMPACT_WINDOW_S / dt)
        strikes = [(side, hs) for side in SIDES for hs in walk.events[side].hs_s if np.isfinite(hs)]
        strikes.sort(key=lambda s: s[1])
        for side, hs in strikes:
            _, _, v, _, _ = walk.pelvis_kinematics(np.array([hs]))
            speed = float(np.linalg.norm(v[0, :2]))
            factor = float(np.clip(1.0 + IMPACT_STEP_CV * rng.standard_normal(), 0.5, 1.5))
            peak = mount.impact_peak_g * G0 * speed / REFERENCE_SPEED_MPS * factor
            direction = IMPACT_DIRECTION_LEFT * (1.0 if side == "left" else np.array([1, -1, 1]))
            k0 = int(np.ceil(hs / dt - 1e-9))
            tau0 = k0 * dt - hs  # grid offset of the first sample after the strike
            n = min(n_win, len(t) - k0)
            if n <= 0:
                continue
            shock = _shock(tau0 + np.arange(n) * dt, f_imp, z_imp)
            d_imp[k0 : k0 + n] += np.outer(shock * peak / acc_peak, direction)
    x = np.zeros((len(t), 3))
    if wobble_on:
        R_WP, _, _, a_P, _ = walk.pelvis_kinematics(t)
        u = np.einsum("nji,nj->ni", R_WP, a_P)
        if impacts_on:
            u = u + CubicSpline(t, d_imp)(t, 2)
        w = 2 * np.pi * mount.wobble_freq_hz
        x = spring_response(u, mount.wobble_gain, w, mount.wobble_damping_ratio, GRID_HZ)
    spline = CubicSpline(t, np.concatenate([d_imp, x], axis=1))
    return MountMotion(np.asarray(T_PfromC_nominal, np.float64), spline, kappa)
