"""Rigid transforms as 4×4 homogeneous matrices (numpy, batched ``(..., 4, 4)``).

Naming follows :mod:`gaitnet.io.types`: ``T_AfromB`` maps points in frame B to frame A,
``p_A = R_AfromB @ p_B + t_AfromB``, and ``compose(T_AfromB, T_BfromC) == T_AfromC``.

TUM trajectory rows
-------------------
A TUM row ``(tx, ty, tz, qx, qy, qz, qw)`` stores ``T_WfromS`` (world from sensor): the
translation is the sensor origin in the world and the quaternion is the Hamilton *active*
rotation ``R_WfromS`` (scipy's convention) in scalar-LAST order. Converting to our scalar-first
storage, ``q = [qw, qx, qy, qz]`` satisfies ``rotmat_from_quat(q) == R_WfromS`` and
``dcm_from_quat(q) == R_WfromS.T == R_SfromW``: the same four numbers are the thesis
world-to-body attitude of the sensor. :func:`tum_from_T` writes ``qw >= 0``.

SE(3) exponential
-----------------
Twists are ``xi = [rho, phi]`` (translation part first, then rotation vector), with
``se3_exp(xi) = [[so3_exp(phi), Jl(phi) rho], [0, 1]]`` (Solà et al. 2018).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gaitnet.geometry._timeinterp import OutOfRange, bracket_times
from gaitnet.geometry.quaternion import (
    quat_from_rotmat,
    quat_normalize,
    quat_slerp,
    quat_wxyz_from_xyzw,
    quat_xyzw_from_wxyz,
    rotmat_from_quat,
)
from gaitnet.geometry.rotation import (
    so3_exp,
    so3_left_jacobian,
    so3_left_jacobian_inv,
    so3_log,
)

FloatArray = NDArray[np.float64]

__all__ = [
    "T_from_tum",
    "compose",
    "interpolate_poses",
    "invert_T",
    "make_T",
    "se3_exp",
    "se3_log",
    "transform_points",
    "tum_from_T",
]


def _as_T(T: ArrayLike) -> FloatArray:
    T = np.asarray(T, dtype=np.float64)
    if T.shape[-2:] != (4, 4):
        raise ValueError(f"homogeneous transforms need trailing shape (4, 4), got {T.shape}")
    return T


def make_T(R: ArrayLike, t: ArrayLike) -> FloatArray:
    """Homogeneous transform from rotation ``R`` (..., 3, 3) and translation ``t`` (..., 3).

    Batch shapes broadcast. ``R`` is used as given (not re-orthonormalized).
    """
    R = np.asarray(R, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64)
    if R.shape[-2:] != (3, 3) or t.shape[-1:] != (3,):
        raise ValueError(f"make_T needs R (..., 3, 3) and t (..., 3), got {R.shape}, {t.shape}")
    batch = np.broadcast_shapes(R.shape[:-2], t.shape[:-1])
    T = np.zeros((*batch, 4, 4))
    T[..., :3, :3] = R
    T[..., :3, 3] = t
    T[..., 3, 3] = 1.0
    return T


def invert_T(T: ArrayLike) -> FloatArray:
    """Inverse of a rigid transform: ``[R.T, -R.T t]`` (exact, no general matrix inverse)."""
    T = _as_T(T)
    Rt = np.swapaxes(T[..., :3, :3], -1, -2)
    t = T[..., :3, 3]
    return make_T(Rt, -np.matmul(Rt, t[..., None])[..., 0])


def compose(*Ts: ArrayLike) -> FloatArray:
    """Matrix product of transforms left to right: ``compose(T_AfromB, T_BfromC) = T_AfromC``."""
    if not Ts:
        raise ValueError("compose needs at least one transform")
    out = _as_T(Ts[0])
    for T in Ts[1:]:
        out = np.matmul(out, _as_T(T))
    return out


def transform_points(T: ArrayLike, p: ArrayLike) -> FloatArray:
    """Apply ``T`` (..., 4, 4) to points ``p`` (..., 3): ``R p + t`` (batch shapes broadcast).

    A single transform applied to many points: ``transform_points(T, pts)`` with ``T`` (4, 4)
    and ``pts`` (N, 3) or (H, W, 3).
    """
    T = _as_T(T)
    p = np.asarray(p, dtype=np.float64)
    if p.shape[-1:] != (3,):
        raise ValueError(f"points need a last axis of length 3, got {p.shape}")
    if T.ndim == 2:  # common case: one transform, many points
        return p @ T[:3, :3].T + T[:3, 3]
    return np.matmul(T[..., :3, :3], p[..., None])[..., 0] + T[..., :3, 3]


def se3_exp(xi: ArrayLike) -> FloatArray:
    """Twist ``xi = [rho, phi]`` (..., 6) → transform ``[[exp(phi), Jl(phi) rho], [0, 1]]``."""
    xi = np.asarray(xi, dtype=np.float64)
    if xi.shape[-1:] != (6,):
        raise ValueError(f"twists need a last axis of length 6, got {xi.shape}")
    rho, phi = xi[..., :3], xi[..., 3:]
    t = np.matmul(so3_left_jacobian(phi), rho[..., None])[..., 0]
    return make_T(so3_exp(phi), t)


def se3_log(T: ArrayLike) -> FloatArray:
    """Inverse of :func:`se3_exp`: ``[Jl(phi)⁻¹ t, phi]`` with ``phi = so3_log(R)``."""
    T = _as_T(T)
    phi = so3_log(T[..., :3, :3])
    rho = np.matmul(so3_left_jacobian_inv(phi), T[..., :3, 3][..., None])[..., 0]
    return np.concatenate([rho, phi], axis=-1)


def tum_from_T(T_WfromS: ArrayLike) -> FloatArray:
    """TUM row(s) ``(tx, ty, tz, qx, qy, qz, qw)`` of ``T_WfromS`` (..., 4, 4), with ``qw >= 0``.

    The quaternion is the Hamilton active ``R_WfromS`` in scalar-last order (see module doc).
    """
    T = _as_T(T_WfromS)
    q_wxyz = quat_from_rotmat(T[..., :3, :3])
    return np.concatenate([T[..., :3, 3], quat_xyzw_from_wxyz(q_wxyz)], axis=-1)


def T_from_tum(row: ArrayLike) -> FloatArray:
    """``T_WfromS`` (..., 4, 4) from TUM row(s) ``(tx, ty, tz, qx, qy, qz, qw)`` (..., 7).

    The quaternion is normalized (TUM files often round to a few digits). A leading timestamp
    column is not accepted: pass ``rows[:, 1:]`` for ``timestamp tx ... qw`` lines.
    """
    row = np.asarray(row, dtype=np.float64)
    if row.shape[-1:] != (7,):
        raise ValueError(f"TUM pose rows need 7 values (tx ty tz qx qy qz qw), got {row.shape}")
    q_wxyz = quat_normalize(quat_wxyz_from_xyzw(row[..., 3:]))
    return make_T(rotmat_from_quat(q_wxyz), row[..., :3])


def interpolate_poses(
    times: ArrayLike,
    T: ArrayLike,
    query_times: ArrayLike,
    *,
    out_of_range: OutOfRange = "raise",
) -> FloatArray:
    """Interpolate poses ``T`` (N, 4, 4) sampled at ``times`` (N,) at ``query_times``.

    Translation is interpolated linearly and rotation by slerp (the usual choice for
    trajectories; it is not the SE(3) geodesic, which couples the two). ``times`` must be
    strictly increasing; ``out_of_range`` as in :func:`~gaitnet.geometry.quat_interpolate`
    (``"nan"`` yields all-NaN matrices). Returns ``(*query_times.shape, 4, 4)``.
    """
    T = _as_T(T)
    if T.ndim != 3:
        raise ValueError(f"T must have shape (N, 4, 4), got {T.shape}")
    i0, i1, alpha, valid = bracket_times(times, query_times, len(T), out_of_range)
    q = quat_from_rotmat(T[:, :3, :3])
    q_i = quat_slerp(q[i0], q[i1], alpha)
    a = alpha[..., None]
    t_i = (1.0 - a) * T[i0, :3, 3] + a * T[i1, :3, 3]
    out = make_T(rotmat_from_quat(q_i), t_i)
    return np.where(valid[..., None, None], out, np.nan)
