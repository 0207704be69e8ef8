"""Ankle design: the shoe's pitch at toe off and in swing chosen for textbook ankle angles.

The ankle angle is measured as in gait labs (and in ``benchmarks/realism_gait.py``): the change
of the angle between the shank (ankle → knee) and the foot (ankle → SMPL foot joint, the ball)
from the rest pose; positive = dorsiflexion. Textbook (docs/references.md, *Normal adult
walking*; Perry & Burnfield 2010; Winter 2009): about −15…−20° (plantarflexion) just after toe
off, back to about 0° by mid-swing and held near 0° until the heel strike.

The shoe is rigid, so the pitch that gives an ankle angle depends on the shank, hence on the
knee, which follows by IK from the hip and the ankle. :func:`design_toe_off` sets each stance's
heel-up angle at toe off so that the ankle is at ``target`` there (found by bisection over the
pitch about the toe edge, with the hip where the current pelvis puts it);
:func:`swing_pitch_target` gives the toe-up pitch along a swing that puts the ankle on its
designed course (the shoe's pitch in swing is then corrected toward it in
:mod:`gaitnet.sim.gait_feet`). Both use the previous round's pelvis height
(:func:`gaitnet.sim.gait._fit_feet_and_height` iterates).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from gaitnet.sim.gait_plan import FootStance, smoothstep7

__all__ = ["AnkleGeometry", "design_toe_off", "swing_pitch_target"]

_SWING_SETTLE = 0.5  # the ankle reaches its swing angle at this fraction of the swing
_DIP_AT = 0.15  # ... after its peak plantarflexion here
_MAX_CHANGE_RAD = np.radians(30.0)  # the swing pitch moves at most this far from the plain swing
_MAX_TOE_DOWN_RAD = np.radians(45.0)  # ... and is not steered further toe-down than this


@dataclass(frozen=True)
class AnkleGeometry:
    """One leg: segment lengths, shoe-frame ankle and ball points, rest shank–foot angle."""

    thigh_m: float
    shank_m: float
    shoe_length_m: float
    ankle_S: np.ndarray  # (3,)
    ball_S: np.ndarray  # (3,)
    rest_rad: float  # angle between ankle→knee and ankle→ball in the rest pose

    def knee(self, hip: np.ndarray, ankle: np.ndarray, forward: np.ndarray) -> np.ndarray:
        """Knee (n, 3) of the two-link leg bending toward ``forward`` (as ``leg_chain``)."""
        d_vec = ankle - hip
        d = np.linalg.norm(d_vec, axis=-1, keepdims=True)
        e = d_vec / d
        f = forward - np.sum(forward * e, axis=-1, keepdims=True) * e
        f /= np.linalg.norm(f, axis=-1, keepdims=True)
        L1, L2 = self.thigh_m, self.shank_m
        cos_b = np.clip((L1**2 + d**2 - L2**2) / (2 * L1 * d), -1.0, 1.0)
        return hip + L1 * (cos_b * e + np.sqrt(1.0 - cos_b**2) * f)

    def dorsiflexion(self, knee: np.ndarray, ankle: np.ndarray, ball: np.ndarray) -> np.ndarray:
        """Ankle angle [rad] (n,): rest angle minus the current shank–foot angle."""
        a, b = knee - ankle, ball - ankle
        cos = np.sum(a * b, -1) / np.linalg.norm(a, axis=-1) / np.linalg.norm(b, axis=-1)
        return self.rest_rad - np.arccos(np.clip(cos, -1.0, 1.0))


def _rot(yaw: np.ndarray, toe_up: np.ndarray) -> np.ndarray:
    """``Rz(yaw) Ry(−toe_up)`` (n, 3, 3), the shoe's orientation."""
    cy, sy, ct, st = np.cos(yaw), np.sin(yaw), np.cos(toe_up), np.sin(toe_up)
    z = np.zeros_like(ct)
    return np.stack(
        [
            np.stack([cy * ct, -sy, -cy * st], axis=-1),
            np.stack([sy * ct, cy, -sy * st], axis=-1),
            np.stack([st, z, ct], axis=-1),
        ],
        axis=-2,
    )


def design_toe_off(
    stances: tuple[FootStance, ...],
    t: np.ndarray,
    hips: np.ndarray,
    forward: np.ndarray,
    geo: AnkleGeometry,
    target_rad: float,
    min_rad: float,
    max_rad: float,
) -> tuple[FootStance, ...]:
    """Heel-up angle at each toe off (within ``[min_rad, max_rad]``) for an ankle at ``target``.

    ``hips`` (n, 3) and the pelvis ``forward`` axis (n, 3) of this leg on the grid ``t``.
    Stances whose pitch is scaled down (short steps: ``to_pitch_rad`` below ``min_rad``) keep
    their scale relative to ``min_rad``.
    """
    out = []
    phis = np.linspace(0.0, max_rad, 141)
    for st in stances:
        if not np.isfinite(st.t_to) or st.to_pitch_rad <= 0.0:
            out.append(st)
            continue
        i = min(int(np.searchsorted(t, st.t_to)), len(t) - 1)
        u = np.array([np.cos(st.yaw), np.sin(st.yaw), 0.0])
        toe = np.array([*(np.asarray(st.xy) + 0.5 * geo.shoe_length_m * u[:2]), 0.0])
        toe_S = np.array([0.5 * geo.shoe_length_m, 0.0, 0.0])
        R = _rot(np.full_like(phis, st.yaw), -phis)
        ankle = toe + (R @ (geo.ankle_S - toe_S))
        ball = toe + (R @ (geo.ball_S - toe_S))
        n = len(phis)
        knee = geo.knee(
            np.broadcast_to(hips[i], (n, 3)), ankle, np.broadcast_to(forward[i], (n, 3))
        )
        dorsi = geo.dorsiflexion(knee, ankle, ball)  # falls as the heel rises
        ok = dorsi <= target_rad
        phi = float(phis[np.argmax(ok)]) if np.any(ok) else max_rad
        scale = min(1.0, st.to_pitch_rad / min_rad) if min_rad > 0 else 1.0
        out.append(replace(st, to_pitch_rad=float(np.clip(phi * scale, st.to_pitch_rad, max_rad))))
    return tuple(out)


def swing_pitch_target(
    u: np.ndarray,
    R_shoe: np.ndarray,
    p_sole: np.ndarray,
    hips: np.ndarray,
    forward: np.ndarray,
    geo: AnkleGeometry,
    swing_rad: float,
    dip_rad: float,
) -> np.ndarray:
    """Toe-up pitch (k,) along a swing (fractions ``u``, ``u[0] = 0`` at toe off) that puts the
    ankle on its course: from its toe-off value to ``swing_rad`` by ``_SWING_SETTLE``, then held.

    ``R_shoe``/``p_sole`` the shoe's current poses, ``hips``/``forward`` the hip and pelvis
    forward axis at the same times (k, 3). The knee is taken where the current ankle puts it.
    """
    ankle = p_sole + R_shoe @ geo.ankle_S
    ball = p_sole + R_shoe @ geo.ball_S
    knee = geo.knee(hips, ankle, forward)
    dorsi = geo.dorsiflexion(knee, ankle, ball)
    dip = min(dip_rad, dorsi[0])
    early = smoothstep7(u / _DIP_AT)
    want = dorsi[0] + (dip - dorsi[0]) * early
    want = want + (swing_rad - dip) * smoothstep7((u - _DIP_AT) / (_SWING_SETTLE - _DIP_AT))
    pitch = np.arcsin(np.clip(R_shoe[:, 2, 0], -1.0, 1.0))  # current toe-up pitch
    change = np.clip(want - dorsi, -_MAX_CHANGE_RAD, _MAX_CHANGE_RAD)
    return np.maximum(pitch + change, np.minimum(pitch, -_MAX_TOE_DOWN_RAD))
