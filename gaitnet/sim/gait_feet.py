"""Shoe trajectories: foot rockers in stance and a C² swing between them.

A shoe's pose is described by five channels: the horizontal midpoint ``m`` (2) of its heel and
toe sole edges, its yaw ``ψ``, and the heights ``z_h``, ``z_t`` of the rear and front bottom
edges (shoe-frame points ``(∓L/2, 0, 0)``). Then pitch ``θ = asin((z_t − z_h)/L)`` (toe up
positive), ``R_WfromShoe = Rz(ψ) Ry(−θ)`` (no roll), and the sole centre is
``(m, (z_h + z_t)/2)``. With zero roll the lowest points of the sole are the heel or toe edge.

Phases of one foot:
- foot flat: all channels constant (the sole does not move at all);
- heel rocker (HS → FF): the heel edge is fixed, ``θ = θ_HS·g(u)``;
- toe rocker (HO → TO): the toe edge is fixed, heel-up angle ``φ = φ_TO·h(u)``;
- swing (TO → HS): every channel is a quintic Hermite polynomial matching value, rate and
  acceleration of the neighbouring rockers (so the shoe pose is C² at the junctions), plus
  ``A·64u³(1 − u)³`` bumps: a vertical one sized so the lowest sole point clears the floor by
  the configured toe clearance at mid-swing, and a sideways one that keeps the swing shoe clear
  of the standing one.

``g(u) = (1 − u)³(1 + 1.2u + 0.6u²)`` falls monotonically from 1 to 0 with ``g'(0) = −1.8``
(the foot rolls down fastest right at heel strike, so the landing ankle still moves forward
and down and the leg straightens close to the heel strike rather than well before it),
``g''(0) = 0`` and a triple zero at 1; ``h(u) = u³(2 − u)`` rises monotonically from 0 to 1
with a triple zero at 0, ``h'(1) = 2`` (a fast push-off) and ``h''(1) = 0``. So the rockers
join foot flat with C² continuity.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from gaitnet.sim.gait_plan import FootStance

__all__ = [
    "N_COEFFS",
    "FootTrajectory",
    "PitchTarget",
    "adapt_heel_off",
    "build_foot_trajectory",
    "required_heel_rise",
    "shoe_pose",
]

FLAT, HEEL, TOE, SWING = 0, 1, 2, 3
#: ``(u, t, R_WfromShoe, p_SoleCentre_W)`` of a swing → the toe-up pitch [rad] it should have
PitchTarget = Callable[[np.ndarray, np.ndarray, np.ndarray, np.ndarray], np.ndarray]
_G_A, _G_B = 1.2, 0.6
_G_D0 = _G_A - 3.0  # g'(0)
_H_D1 = 2.0  # h'(1)
_H_C = (10.0 - 4.0 * _H_D1, 7.0 * _H_D1 - 15.0, 6.0 - 3.0 * _H_D1)  # h(1) = 1, h''(1) = 0
_MID_SWING = (0.3, 0.7)  # window (fraction of swing) where the clearance is imposed
_LATERAL_GAP_M = 0.02


def _g(u: np.ndarray) -> np.ndarray:
    return (1.0 - u) ** 3 * (1.0 + u * (_G_A + _G_B * u))


def _h(u: np.ndarray) -> np.ndarray:
    return u**3 * (_H_C[0] + u * (_H_C[1] + u * _H_C[2]))


def _bump(u: np.ndarray) -> np.ndarray:
    return 64.0 * u**3 * (1.0 - u) ** 3


N_COEFFS = 10  # swing polynomials up to degree 9 (quintic + bumps + pitch correction)
_BUMP_COEFFS = np.pad([0.0, 0.0, 0.0, 64.0, -192.0, 192.0, -64.0], (0, N_COEFFS - 7))
_PITCH_BASIS = 4  # u³(1 − u)³ u^j, j < this: the swing pitch correction (zero, C² at both ends)
_Z_ONLY = np.array([0.0, 0.0, 0.0, 1.0, 1.0])[:, None]  # the vertical bump lifts z_h and z_t
_MAX_LIFT = 1.5  # a steered swing lifted more than this × clearance in mid-swing stays plain
_PITCH_FIT = (0.0, 1.0)  # swing fractions where the pitch is fitted to its target


def _quintic_coeffs(p0: np.ndarray, v0: np.ndarray, a0: np.ndarray, p1, v1, a1) -> np.ndarray:
    """Coefficients ``(..., N_COEFFS)`` (powers 0..) of the quintic Hermite on u ∈ [0, 1]."""
    d = p1 - p0
    c3 = 10 * d - 6 * v0 - 4 * v1 - 1.5 * a0 + 0.5 * a1
    c4 = -15 * d + 8 * v0 + 7 * v1 + 1.5 * a0 - a1
    c5 = 6 * d - 3 * (v0 + v1) - 0.5 * a0 + 0.5 * a1
    zero = np.zeros_like(p0)
    return np.stack([p0, v0, 0.5 * a0, c3, c4, c5, *([zero] * (N_COEFFS - 6))], axis=-1)


def _polyval(c: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Evaluate coefficients ``(..., N_COEFFS)`` at ``u`` (broadcast over the leading axes)."""
    out = np.zeros(np.broadcast_shapes(c.shape[:-1], u.shape))
    for k in range(c.shape[-1] - 1, -1, -1):
        out = out * u + c[..., k]
    return out


def _dir(yaw: float) -> np.ndarray:
    return np.array([np.cos(yaw), np.sin(yaw)])


def _toe_off_state(st: FootStance, L: float, dur: float) -> np.ndarray:
    """Channels (mx, my, yaw, zh, zt) × (value, rate, acc) at the end of the toe rocker."""
    phi, dphi = st.to_pitch_rad, _H_D1 * st.to_pitch_rad / dur  # h''(1) = 0
    u = _dir(st.yaw)
    toe = np.asarray(st.xy) + 0.5 * L * u
    m = toe - 0.5 * L * np.cos(phi) * u
    dm = 0.5 * L * np.sin(phi) * dphi * u
    ddm = 0.5 * L * np.cos(phi) * dphi**2 * u
    zh = np.array([L * np.sin(phi), L * np.cos(phi) * dphi, -L * np.sin(phi) * dphi**2])
    return np.array(
        [[m[0], dm[0], ddm[0]], [m[1], dm[1], ddm[1]], [st.yaw, 0, 0], zh, [0.0, 0.0, 0.0]]
    )


def _heel_strike_state(st: FootStance, L: float, dur: float) -> np.ndarray:
    """Channels × (value, rate, acc) at the start of the heel rocker."""
    th, dth = st.hs_pitch_rad, st.hs_pitch_rad * _G_D0 / dur
    u = _dir(st.yaw)
    heel = np.asarray(st.xy) - 0.5 * L * u
    m = heel + 0.5 * L * np.cos(th) * u
    dm = -0.5 * L * np.sin(th) * dth * u
    ddm = -0.5 * L * np.cos(th) * dth**2 * u
    zt = np.array([L * np.sin(th), L * np.cos(th) * dth, -L * np.sin(th) * dth**2])
    return np.array(
        [[m[0], dm[0], ddm[0]], [m[1], dm[1], ddm[1]], [st.yaw, 0, 0], [0.0, 0.0, 0.0], zt]
    )


def _swing_coeffs(
    a: FootStance,
    b: FootStance,
    other_xy: np.ndarray,
    L: float,
    W: float,
    clearance: float,
    pitch_target: PitchTarget | None = None,
) -> np.ndarray:
    """Polynomial coefficients (5 channels, N_COEFFS) of the swing from stance ``a`` to ``b``.

    ``pitch_target(u, t, R_shoe, p_sole)`` → toe-up pitch (k,): where given, the pitch is
    corrected toward it (:func:`_pitch_correction`) before the clearance bump is sized;
    a steered swing whose toe would dip near the ends so much that the bump lifts it more than
    ``_MAX_LIFT`` × clearance in mid-swing (short first / closing swings) stays plain.
    """
    dur = b.t_hs - a.t_to
    s0 = _toe_off_state(a, L, a.t_to - a.t_ho)
    s1 = _heel_strike_state(b, L, b.t_ff - b.t_hs)
    scale = np.array([1.0, dur, dur * dur])
    s0, s1 = s0 * scale, s1 * scale
    c = _quintic_coeffs(s0[:, 0], s0[:, 1], s0[:, 2], s1[:, 0], s1[:, 1], s1[:, 2])
    c[:2] += np.outer(_lateral_bulge(c, other_xy, W), _BUMP_COEFFS)
    plain = c + _vertical_bump(c, clearance) * _BUMP_COEFFS * _Z_ONLY
    if pitch_target is None:
        return plain
    u = np.linspace(0.0, 1.0, 41)
    target = pitch_target(u, a.t_to + u * dur, *_channel_pose(c, u, L))
    delta = _pitch_correction(c, L, u, target)  # the shoe turns about its sole centre
    c[3] -= 0.5 * delta
    c[4] += 0.5 * delta
    steered = c + _vertical_bump(c, clearance) * _BUMP_COEFFS * _Z_ONLY
    mid = u[(u >= _MID_SWING[0]) & (u <= _MID_SWING[1])]
    lowest = np.minimum(_polyval(steered[3], mid), _polyval(steered[4], mid)).min()
    if lowest > _MAX_LIFT * clearance:
        return plain  # the steered toe would dip near toe off / heel strike: plain swing
    return steered


def _channel_pose(c: np.ndarray, u: np.ndarray, L: float) -> tuple[np.ndarray, np.ndarray]:
    """Shoe poses ``R (k, 3, 3)``, ``p (k, 3)`` of swing coefficients ``c`` at fractions ``u``."""
    poly = _polyval(c, u[:, None])
    return shoe_pose(poly[:, :2], poly[:, 2], poly[:, 3], poly[:, 4], L)


def _pitch_correction(c: np.ndarray, L: float, u: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Coefficients (N_COEFFS,) of ``Δ(z_t − z_h)``: a sum of ``u³(1 − u)³ u^j`` fitted (least
    squares over :data:`_PITCH_FIT`) so that the pitch follows ``target`` (k,) [rad]."""
    d = _polyval(c[4], u) - _polyval(c[3], u)
    want = L * np.sin(np.clip(target, -1.3, 1.3))
    base = np.zeros((_PITCH_BASIS, N_COEFFS))
    for j in range(_PITCH_BASIS):
        base[j, 3 + j : 7 + j] = (1.0, -3.0, 3.0, -1.0)
    A = np.stack([_polyval(b, u) for b in base], axis=-1)
    m = (u >= _PITCH_FIT[0]) & (u <= _PITCH_FIT[1])
    coef = np.linalg.lstsq(A[m], (want - d)[m], rcond=None)[0]
    return coef @ base


def _lateral_bulge(c: np.ndarray, other_xy: np.ndarray, W: float) -> np.ndarray:
    """Sideways bump vector (2,) that keeps the swing sole ``W + gap`` from the other foot."""
    p0 = np.array([c[0, 0], c[1, 0]])
    p1 = np.array([c[0, :].sum(), c[1, :].sum()])
    d = p1 - p0
    if np.linalg.norm(d) < 1e-6:
        return np.zeros(2)
    perp = np.array([-d[1], d[0]]) / np.linalg.norm(d)
    side = float(np.dot(p0 - other_xy, perp))
    if side < 0:
        perp, side = -perp, -side
    return perp * max(0.0, W + _LATERAL_GAP_M - side)


def _vertical_bump(c: np.ndarray, clearance: float) -> float:
    """Bump amplitude so that min(z_h, z_t) = clearance in mid-swing and ≥ 0 everywhere."""
    u = np.linspace(0.0, 1.0, 401)[1:-1]
    low = np.minimum(_polyval(c[3], u), _polyval(c[4], u))
    b = _bump(u)
    mid = (u >= _MID_SWING[0]) & (u <= _MID_SWING[1])
    lo, hi = -1.0, 1.0
    for _ in range(60):
        amp = 0.5 * (lo + hi)
        if np.min(low[mid] + amp * b[mid]) < clearance:
            lo = amp
        else:
            hi = amp
    floor = np.max(-low / b)  # smallest amplitude keeping the whole swing above the floor
    return max(hi, floor + 1e-9)


@dataclass(frozen=True, eq=False)
class FootTrajectory:
    """Piecewise shoe trajectory of one foot (segments sorted by start time)."""

    shoe_length_m: float
    t0: np.ndarray  # (S,) segment start times
    dur: np.ndarray  # (S,) durations (inf for the last foot flat)
    kind: np.ndarray  # (S,) FLAT / HEEL / TOE / SWING
    anchor_xy: np.ndarray  # (S, 2) sole centre (flat), heel edge (HEEL), toe edge (TOE)
    yaw: np.ndarray  # (S,)
    amp: np.ndarray  # (S,) θ_HS (HEEL) or φ_TO (TOE)
    coeffs: np.ndarray  # (S, 5, N_COEFFS) swing polynomials in u

    def channels(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``m (n, 2), yaw (n,), z_heel (n,), z_toe (n,)`` at times ``t (n,)``."""
        t = np.asarray(t, dtype=np.float64)
        i = np.clip(np.searchsorted(self.t0, t, side="right") - 1, 0, len(self.t0) - 1)
        kind, L = self.kind[i], self.shoe_length_m
        u = np.clip(np.where(np.isfinite(self.dur[i]), (t - self.t0[i]) / self.dur[i], 0.0), 0, 1)
        yaw = self.yaw[i]
        d = np.stack([np.cos(yaw), np.sin(yaw)], axis=-1)
        ang = np.where(kind == HEEL, self.amp[i] * _g(u), self.amp[i] * _h(u))
        ang = np.where((kind == HEEL) | (kind == TOE), ang, 0.0)
        sign = np.where(kind == HEEL, 1.0, np.where(kind == TOE, -1.0, 0.0))
        m = self.anchor_xy[i] + (sign * 0.5 * L * np.cos(ang))[:, None] * d
        zh = np.where(kind == TOE, L * np.sin(ang), 0.0)
        zt = np.where(kind == HEEL, L * np.sin(ang), 0.0)
        swing = kind == SWING
        if np.any(swing):
            poly = _polyval(self.coeffs[i[swing]], u[swing, None])  # (k, 5)
            yaw = yaw.copy()
            m[swing], yaw[swing] = poly[:, :2], poly[:, 2]
            zh[swing], zt[swing] = poly[:, 3], poly[:, 4]
        return m, yaw, zh, zt

    def pose(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``R_WfromShoe (n, 3, 3)`` and sole centre ``p_SoleCentre_W (n, 3)``."""
        return shoe_pose(*self.channels(t), self.shoe_length_m)


def shoe_pose(
    m: np.ndarray, yaw: np.ndarray, zh: np.ndarray, zt: np.ndarray, L: float
) -> tuple[np.ndarray, np.ndarray]:
    """``R_WfromShoe = Rz(yaw) Ry(−θ)`` and the sole centre from the five channels."""
    theta = np.arcsin(np.clip((zt - zh) / L, -1.0, 1.0))
    cy, sy, ct, st = np.cos(yaw), np.sin(yaw), np.cos(theta), np.sin(theta)
    # columns = shoe x, y, z axes in the world
    R = np.stack(
        [
            np.stack([cy * ct, -sy, -cy * st], axis=-1),
            np.stack([sy * ct, cy, -sy * st], axis=-1),
            np.stack([st, np.zeros_like(st), ct], axis=-1),
        ],
        axis=-2,
    )
    p = np.concatenate([m, (0.5 * (zh + zt))[:, None]], axis=-1)
    return R, p


def build_foot_trajectory(
    stances: tuple[FootStance, ...],
    other: tuple[FootStance, ...],
    shoe_length_m: float,
    shoe_width_m: float,
    clearance_m: float,
    pitch_target: PitchTarget | None = None,
) -> FootTrajectory:
    """Segments of one foot from its stances; ``other`` (the other foot) sizes the side bulge;
    ``pitch_target`` (optional) steers the swing pitch (:func:`_swing_coeffs`)."""
    L = shoe_length_m
    rows: list[tuple] = []
    zero = np.zeros((5, N_COEFFS))
    for i, st in enumerate(stances):
        d = _dir(st.yaw)
        xy = np.asarray(st.xy)
        if i > 0:
            rows.append(
                (st.t_hs, st.t_ff - st.t_hs, HEEL, xy - 0.5 * L * d, st.yaw, st.hs_pitch_rad, zero)
            )
        t_flat = 0.0 if i == 0 else st.t_ff
        end = st.t_ho if np.isfinite(st.t_ho) else np.inf
        rows.append((t_flat, end - t_flat, FLAT, xy, st.yaw, 0.0, zero))
        if i + 1 < len(stances):
            nxt = stances[i + 1]
            rows.append(
                (st.t_ho, st.t_to - st.t_ho, TOE, xy + 0.5 * L * d, st.yaw, st.to_pitch_rad, zero)
            )
            other_xy = _standing_other(other, 0.5 * (st.t_to + nxt.t_hs))
            c = _swing_coeffs(st, nxt, other_xy, L, shoe_width_m, clearance_m, pitch_target)
            rows.append((st.t_to, nxt.t_hs - st.t_to, SWING, np.zeros(2), 0.0, 0.0, c))
    cols = list(zip(*rows, strict=True))
    return FootTrajectory(
        shoe_length_m=L,
        t0=np.array(cols[0], dtype=float),
        dur=np.array(cols[1], dtype=float),
        kind=np.array(cols[2], dtype=int),
        anchor_xy=np.array(cols[3], dtype=float),
        yaw=np.array(cols[4], dtype=float),
        amp=np.array(cols[5], dtype=float),
        coeffs=np.array(cols[6], dtype=float),
    )


def _standing_other(other: tuple[FootStance, ...], t: float) -> np.ndarray:
    """Sole centre of the other foot's stance that contains time ``t``."""
    for st in reversed(other):
        if not np.isfinite(st.t_hs) or st.t_hs <= t:
            return np.asarray(st.xy)
    return np.asarray(other[0].xy)


def required_heel_rise(
    st: FootStance, hips: np.ndarray, reach: float, L: float, ankle_S: np.ndarray
) -> np.ndarray:
    """Smallest heel-up angle (n,) about the toe edge that puts the ankle within ``reach``.

    The ankle turns about the toe edge on a circle in the foot's vertical plane; with
    ``D = hip − toe`` and the toe→ankle vector ``r`` the condition ``|D − R(φ) r| ≤ reach`` is
    ``C cos φ + S sin φ ≥ K`` (the ankle lies in the foot's mid-plane, ``ankle_S[1] = 0``).
    Returns ``π/2`` where no angle works.
    """
    u = np.array([np.cos(st.yaw), np.sin(st.yaw), 0.0])
    toe = np.array([*(np.asarray(st.xy) + 0.5 * L * u[:2]), 0.0])
    r_x, r_z = ankle_S[0] - 0.5 * L, ankle_S[2]
    D = hips - toe
    D_u, D_z = D @ u, D[:, 2]
    C = D_u * r_x + D_z * r_z
    S = D_u * r_z - D_z * r_x
    K = 0.5 * (np.sum(D * D, axis=-1) + r_x**2 + r_z**2 - reach**2)
    M = np.hypot(C, S)
    phi = np.arctan2(S, C) - np.arccos(np.clip(K / np.maximum(M, 1e-12), -1.0, 1.0))
    phi = np.where(K > M, 0.5 * np.pi, np.maximum(phi, 0.0))
    return np.where(C >= K, 0.0, phi)


def adapt_heel_off(
    stances: tuple[FootStance, ...],
    t: np.ndarray,
    hips: np.ndarray,
    reach: float,
    L: float,
    ankle_S: np.ndarray,
    max_to_pitch_rad: float,
    t_earliest: float,
    earliest_fraction: float,
    checked: np.ndarray | None = None,
) -> tuple[FootStance, ...]:
    """Move each heel off earlier (never later) so the heel rises before the leg runs out.

    ``hips`` (n, 3) is this side's hip on the grid ``t`` at the desired pelvis height; only the
    times where ``checked`` (n,) is true count (default: all). Heel off
    moves at most ``earliest_fraction`` of the way from its planned time back to foot flat,
    and never before ``t_earliest``; the toe-off angle grows (up to ``max_to_pitch_rad``) if
    the leg needs more at toe off.
    """
    out = []
    for st in stances:
        if not np.isfinite(st.t_ho):
            out.append(st)
            continue
        t_ff = st.t_ff if np.isfinite(st.t_ff) else t_earliest
        m = (t >= t_ff) & (t <= st.t_to)
        need = required_heel_rise(st, hips[m], reach, L, ankle_S)
        if checked is not None:
            need = np.where(checked[m], need, 0.0)
        phi_to = float(np.clip(max(st.to_pitch_rad, need[-1] + 0.02), 0.0, max_to_pitch_rad))
        lo = max(st.t_ho - earliest_fraction * (st.t_ho - t_ff), min(t_earliest, st.t_ho))
        hi = st.t_ho
        if _heel_rise_ok(t[m], need, lo, st.t_to, phi_to):
            for _ in range(40):
                mid = 0.5 * (lo + hi)
                if _heel_rise_ok(t[m], need, mid, st.t_to, phi_to):
                    lo = mid
                else:
                    hi = mid
        out.append(replace(st, t_ho=lo, to_pitch_rad=phi_to))
    return tuple(out)


def _heel_rise_ok(t: np.ndarray, need: np.ndarray, t_ho: float, t_to: float, amp: float) -> bool:
    u = np.clip((t - t_ho) / (t_to - t_ho), 0.0, 1.0)
    return bool(np.all(amp * _h(u) >= need))
