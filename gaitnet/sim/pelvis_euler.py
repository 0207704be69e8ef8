"""Z-Y-X Euler angles of the pelvis: rotation matrix, body angular velocity and acceleration.

``R_WfromP = Rz(ψ) Ry(θ) Rx(φ)`` with yaw ``ψ``, tilt ``θ``, obliquity ``φ``
(:mod:`gaitnet.sim.gait_pelvis`).
"""

from __future__ import annotations

import numpy as np

__all__ = ["alpha_body", "euler_zyx_matrix", "omega_body"]


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


def omega_body(ang: np.ndarray, d1: np.ndarray) -> np.ndarray:
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


def alpha_body(ang: np.ndarray, d1: np.ndarray, d2: np.ndarray) -> np.ndarray:
    """Time derivative of :func:`omega_body` (body angular acceleration)."""
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
