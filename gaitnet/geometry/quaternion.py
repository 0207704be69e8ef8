"""Unit quaternions in the thesis (D.-C. Dang) convention.

Storage and product
-------------------
A quaternion is a float64 numpy array ``[w, x, y, z]`` (scalar FIRST); batches have shape
``(..., 4)``. Products are Hamilton products (``i*j = k``), see :func:`quat_multiply`.

Which matrix is which
---------------------
For a unit quaternion ``q`` there are two matrices, transposes of each other:

* ``R(q)`` = :func:`rotmat_from_quat` — the usual Hamilton *active* rotation matrix
  (the one scipy's ``Rotation.from_quat(q_xyzw).as_matrix()`` returns). It maps body-frame
  vectors to world-frame vectors: ``v_W = R(q) @ v_B``; ``R(p ⊗ q) = R(p) @ R(q)``.
* ``C(q)`` = :func:`dcm_from_quat` = ``R(q).T`` — the thesis' direction cosine matrix,
  world-to-body: ``v_B = C(q) @ v_W``; therefore ``C(p ⊗ q) = C(q) @ C(p)``.

The thesis says "``q`` rotates world to body": the same four numbers give ``R`` (body-to-world
active rotation) and ``C`` (world-to-body DCM). In particular a pose ``T_WfromB`` with rotation
``R_WfromB`` has thesis attitude ``q = quat_from_rotmat(R_WfromB)`` and ``C(q) = R_BfromW``.
A TUM trajectory row's ``(qx, qy, qz, qw)`` (world-from-sensor, Hamilton, scalar last) is
therefore the thesis attitude of the sensor reordered to ``[qw, qx, qy, qz]``.

Error-state model (thesis eq. (3.1))
------------------------------------
``q = q̂ ⊗ f_quat(q̄_e)`` with ``f_quat(q̄_e) = [sqrt(1 - |q̄_e|²); q̄_e]`` (first order:
``[1; q̄_e]``), so ``C(q) ≈ (I - 2[q̄_e×]) C(q̂)`` and ``R(q) ≈ R(q̂) (I + 2[q̄_e×])``: the error
is a rotation of the body frame. The 3-vector ``dtheta = 2 q̄_e`` is the small rotation vector
used by :func:`quat_boxplus` / :func:`quat_boxminus`.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gaitnet.geometry._timeinterp import OutOfRange, bracket_times
from gaitnet.geometry.single_rotation import (
    SERIES_BELOW,
    quat_from_rotmat_floats,
    rotmat_from_quat_one,
)

FloatArray = NDArray[np.float64]
Chart = Literal["fquat", "exp"]

__all__ = [
    "Chart",
    "axis_angle_from_quat",
    "dcm_from_quat",
    "f_quat",
    "quat_boxminus",
    "quat_boxplus",
    "quat_conjugate",
    "quat_from_axis_angle",
    "quat_from_dcm",
    "quat_from_rotmat",
    "quat_from_rotvec",
    "quat_identity",
    "quat_interpolate",
    "quat_inverse",
    "quat_make_continuous",
    "quat_multiply",
    "quat_normalize",
    "quat_positive",
    "quat_slerp",
    "quat_wxyz_from_xyzw",
    "quat_xyzw_from_wxyz",
    "rotate_body_to_world",
    "rotate_world_to_body",
    "rotmat_from_quat",
    "rotvec_from_quat",
]

_SMALL = SERIES_BELOW  # below this |vector part| the series forms are exact to float64


def _as_quat(q: ArrayLike) -> FloatArray:
    q = np.asarray(q, dtype=np.float64)
    if q.shape[-1:] != (4,):
        raise ValueError(f"quaternion arrays need a last axis of length 4, got shape {q.shape}")
    return q


def _as_vec3(v: ArrayLike, name: str = "vector") -> FloatArray:
    v = np.asarray(v, dtype=np.float64)
    if v.shape[-1:] != (3,):
        raise ValueError(f"{name} arrays need a last axis of length 3, got shape {v.shape}")
    return v


def _as_mat3(m: ArrayLike) -> FloatArray:
    m = np.asarray(m, dtype=np.float64)
    if m.shape[-2:] != (3, 3):
        raise ValueError(f"rotation matrices need trailing shape (3, 3), got shape {m.shape}")
    return m


# --------------------------------------------------------------------------- basic algebra


def quat_identity(shape: tuple[int, ...] = ()) -> FloatArray:
    """Identity quaternion(s) ``[1, 0, 0, 0]`` of batch shape ``shape``."""
    q = np.zeros((*shape, 4))
    q[..., 0] = 1.0
    return q


def quat_multiply(p: ArrayLike, q: ArrayLike) -> FloatArray:
    """Hamilton product ``p ⊗ q`` (batched, broadcasting).

    ``R(p ⊗ q) = R(p) R(q)`` and ``C(p ⊗ q) = C(q) C(p)``.
    """
    p = _as_quat(p)
    q = _as_quat(q)
    pw, pv = p[..., :1], p[..., 1:]
    qw, qv = q[..., :1], q[..., 1:]
    w = pw * qw - np.sum(pv * qv, axis=-1, keepdims=True)
    v = pw * qv + qw * pv + np.cross(pv, qv)
    return np.concatenate([w, v], axis=-1)


def quat_conjugate(q: ArrayLike) -> FloatArray:
    """Conjugate ``q* = [w, -x, -y, -z]`` (the inverse of a unit quaternion)."""
    q = _as_quat(q)
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def quat_normalize(q: ArrayLike) -> FloatArray:
    """Scale ``q`` to unit norm. Raises ``ValueError`` for a zero quaternion; NaN propagates."""
    q = _as_quat(q)
    n = np.linalg.norm(q, axis=-1, keepdims=True)
    if np.any(n < 1e-300):
        raise ValueError("cannot normalize a zero quaternion")
    return q / n


def quat_inverse(q: ArrayLike) -> FloatArray:
    """Multiplicative inverse ``q* / |q|²`` (equals the conjugate for unit quaternions)."""
    q = _as_quat(q)
    return quat_conjugate(q) / np.sum(q * q, axis=-1, keepdims=True)


def quat_positive(q: ArrayLike) -> FloatArray:
    """Representative of ``±q`` with ``w >= 0`` (quaternions double-cover rotations)."""
    q = _as_quat(q)
    return np.where(q[..., :1] < 0.0, -q, q)


def quat_make_continuous(quats: ArrayLike) -> FloatArray:
    """Flip signs along axis 0 so consecutive quaternions have a non-negative dot product.

    Useful before plotting or averaging a trajectory; the rotations are unchanged.
    """
    q = _as_quat(quats).copy()
    if q.shape[0] < 2:
        return q
    dots = np.sum(q[1:] * q[:-1], axis=-1)
    flips = np.cumsum(dots < 0.0, axis=0) % 2  # parity of sign changes so far
    sign = np.concatenate([np.ones((1, *flips.shape[1:])), 1.0 - 2.0 * flips], axis=0)
    return q * sign[..., None]


def quat_wxyz_from_xyzw(q_xyzw: ArrayLike) -> FloatArray:
    """Reorder scalar-last ``[x, y, z, w]`` (scipy, TUM, ROS) to scalar-first ``[w, x, y, z]``."""
    q = _as_quat(q_xyzw)
    return np.concatenate([q[..., 3:], q[..., :3]], axis=-1)


def quat_xyzw_from_wxyz(q_wxyz: ArrayLike) -> FloatArray:
    """Reorder our scalar-first ``[w, x, y, z]`` to scalar-last ``[x, y, z, w]``."""
    q = _as_quat(q_wxyz)
    return np.concatenate([q[..., 1:], q[..., :1]], axis=-1)


# --------------------------------------------------------------------------- matrices


def rotmat_from_quat(q: ArrayLike) -> FloatArray:
    """``R(q)``: the Hamilton active rotation matrix, body-to-world (``v_W = R v_B``).

    ``q`` is normalized first. Shape ``(..., 4) -> (..., 3, 3)``. ``R(q) = C(q).T``.
    """
    q = _as_quat(q)
    if q.shape == (4,) and np.isfinite(q).all():
        return rotmat_from_quat_one(*q.tolist())
    w, x, y, z = np.moveaxis(quat_normalize(q), -1, 0)
    xx, yy, zz = x * x, y * y, z * z
    xy, xz, yz = x * y, x * z, y * z
    wx, wy, wz = w * x, w * y, w * z
    R = np.empty((*w.shape, 3, 3))
    R[..., 0, 0] = 1.0 - 2.0 * (yy + zz)
    R[..., 0, 1] = 2.0 * (xy - wz)
    R[..., 0, 2] = 2.0 * (xz + wy)
    R[..., 1, 0] = 2.0 * (xy + wz)
    R[..., 1, 1] = 1.0 - 2.0 * (xx + zz)
    R[..., 1, 2] = 2.0 * (yz - wx)
    R[..., 2, 0] = 2.0 * (xz - wy)
    R[..., 2, 1] = 2.0 * (yz + wx)
    R[..., 2, 2] = 1.0 - 2.0 * (xx + yy)
    return R


def dcm_from_quat(q: ArrayLike) -> FloatArray:
    """``C(q)``: the thesis direction cosine matrix, world-to-body (``v_B = C v_W``).

    ``C(q) = R(q).T`` and ``C(p ⊗ q) = C(q) C(p)``. Shape ``(..., 4) -> (..., 3, 3)``.
    """
    return np.swapaxes(rotmat_from_quat(q), -1, -2)


def quat_from_rotmat(R: ArrayLike) -> FloatArray:
    """Inverse of :func:`rotmat_from_quat`: unit ``q`` with ``R(q) = R`` and ``w >= 0``.

    Shepperd/Markley method: of the four algebraically equivalent formulas the one with the
    largest pivot (``1 + trace`` or ``1 + 2 R_ii - trace``) is used, so it is accurate for every
    rotation including angles near π. A slightly non-orthogonal ``R`` yields the quaternion of
    a nearby rotation. Shape ``(..., 3, 3) -> (..., 4)``.
    """
    R = _as_mat3(R)
    if R.shape == (3, 3) and np.isfinite(R).all():
        return np.array(quat_from_rotmat_floats(R.tolist()))
    r00, r01, r02 = R[..., 0, 0], R[..., 0, 1], R[..., 0, 2]
    r10, r11, r12 = R[..., 1, 0], R[..., 1, 1], R[..., 1, 2]
    r20, r21, r22 = R[..., 2, 0], R[..., 2, 1], R[..., 2, 2]
    tr = r00 + r11 + r22
    # Row k of M equals 4 q_k q (symmetric); pick the row with the largest diagonal 4 q_k².
    M = np.stack(
        [
            np.stack([1.0 + tr, r21 - r12, r02 - r20, r10 - r01], axis=-1),
            np.stack([r21 - r12, 1.0 + 2.0 * r00 - tr, r01 + r10, r02 + r20], axis=-1),
            np.stack([r02 - r20, r01 + r10, 1.0 + 2.0 * r11 - tr, r12 + r21], axis=-1),
            np.stack([r10 - r01, r02 + r20, r12 + r21, 1.0 + 2.0 * r22 - tr], axis=-1),
        ],
        axis=-2,
    )
    diag = np.stack([tr, r00, r11, r22], axis=-1)
    k = np.argmax(diag, axis=-1)
    row = np.take_along_axis(M, k[..., None, None], axis=-2)[..., 0, :]
    q = row / np.linalg.norm(row, axis=-1, keepdims=True)
    return quat_positive(q)


def quat_from_dcm(C: ArrayLike) -> FloatArray:
    """Inverse of :func:`dcm_from_quat`: unit ``q`` (``w >= 0``) with ``C(q) = C``."""
    return quat_from_rotmat(np.swapaxes(_as_mat3(C), -1, -2))


def rotate_body_to_world(q: ArrayLike, v_B: ArrayLike) -> FloatArray:
    """``R(q) @ v_B`` (batched): a body-frame vector expressed in the world frame."""
    v = _as_vec3(v_B)
    return np.matmul(rotmat_from_quat(q), v[..., None])[..., 0]


def rotate_world_to_body(q: ArrayLike, v_W: ArrayLike) -> FloatArray:
    """``C(q) @ v_W`` (batched): a world-frame vector expressed in the body frame."""
    v = _as_vec3(v_W)
    return np.matmul(dcm_from_quat(q), v[..., None])[..., 0]


# --------------------------------------------------------------------------- axis-angle


def quat_from_rotvec(phi: ArrayLike) -> FloatArray:
    """Quaternion of the rotation vector ``phi`` (angle ``|phi|`` about ``phi/|phi|``).

    ``R(quat_from_rotvec(phi)) = so3_exp(phi)`` (active rotation). Exact for tiny angles.
    Shape ``(..., 3) -> (..., 4)``.
    """
    phi = _as_vec3(phi, "rotation vector")
    theta = np.linalg.norm(phi, axis=-1, keepdims=True)
    # sin(θ/2)/θ = 0.5 sinc(θ/(2π)) with numpy's normalized sinc; exact at θ = 0.
    s = 0.5 * np.sinc(theta / (2.0 * np.pi))
    return np.concatenate([np.cos(0.5 * theta), s * phi], axis=-1)


def rotvec_from_quat(q: ArrayLike) -> FloatArray:
    """Rotation vector of ``q`` (inverse of :func:`quat_from_rotvec`), angle in ``[0, π]``.

    ``q`` and ``-q`` give the same result. Uses ``atan2`` so it is accurate near 0 and near π.
    Shape ``(..., 4) -> (..., 3)``.
    """
    q = quat_positive(quat_normalize(q))
    w = q[..., :1]
    v = q[..., 1:]
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    small = n < _SMALL
    n_safe = np.where(small, 1.0, n)
    w_safe = np.where(small, w, 1.0)
    # For n → 0 (w → 1): 2 atan2(n, w) / n = (2/w)(1 - n²/(3w²) + ...).
    scale = np.where(
        small,
        (2.0 / w_safe) * (1.0 - n * n / (3.0 * w_safe * w_safe)),
        2.0 * np.arctan2(n_safe, w) / n_safe,
    )
    return scale * v


def quat_from_axis_angle(axis: ArrayLike, angle: ArrayLike) -> FloatArray:
    """Quaternion rotating (actively, ``R(q)``) by ``angle`` [rad] about ``axis``.

    ``axis`` (..., 3) is normalized here; ``angle`` (...) broadcasts with the axis batch.
    In thesis terms ``C(q)`` is the rotation by ``-angle``.
    """
    axis = _as_vec3(axis, "axis")
    n = np.linalg.norm(axis, axis=-1, keepdims=True)
    if np.any(n < 1e-300):
        raise ValueError("rotation axis must be non-zero")
    half = 0.5 * np.asarray(angle, dtype=np.float64)[..., None]
    batch = np.broadcast_shapes(axis.shape[:-1], half.shape[:-1])
    w = np.broadcast_to(np.cos(half), (*batch, 1))
    v = np.broadcast_to(np.sin(half) * axis / n, (*batch, 3))
    return np.concatenate([w, v], axis=-1)


def axis_angle_from_quat(q: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """``(axis (..., 3), angle (...))`` of ``q`` with ``angle`` in ``[0, π]``.

    For the identity rotation (angle 0) the axis is arbitrary and returned as ``[1, 0, 0]``.
    """
    phi = rotvec_from_quat(q)
    angle = np.linalg.norm(phi, axis=-1)
    zero = angle[..., None] == 0.0
    axis = np.where(zero, np.array([1.0, 0.0, 0.0]), phi / np.where(zero, 1.0, angle[..., None]))
    return axis, angle


# --------------------------------------------------------------------------- error state


def f_quat(q_err: ArrayLike, *, first_order: bool = False) -> FloatArray:
    """Thesis ``f_quat``: error quaternion from the 3-vector ``q̄_e`` (half rotation vector).

    ``f_quat(q̄_e) = [sqrt(1 - |q̄_e|²); q̄_e]`` (thesis eq. (3.1)); when ``|q̄_e| > 1`` (not a
    small error, usually a diverged filter) ``[1; q̄_e] / sqrt(1 + |q̄_e|²)`` is returned
    instead so the result stays a unit quaternion. ``first_order=True`` returns the
    un-normalized first-order form ``[1; q̄_e]``.
    """
    e = _as_vec3(q_err, "error vector")
    one = np.ones((*e.shape[:-1], 1))
    if first_order:
        return np.concatenate([one, e], axis=-1)
    n2 = np.sum(e * e, axis=-1, keepdims=True)
    inside = n2 <= 1.0
    exact = np.concatenate([np.sqrt(np.where(inside, 1.0 - n2, 0.0)), e], axis=-1)
    fallback = np.concatenate([one, e], axis=-1) / np.sqrt(1.0 + n2)
    return np.where(inside, exact, fallback)


def quat_boxplus(q_hat: ArrayLike, dtheta: ArrayLike, *, chart: Chart = "fquat") -> FloatArray:
    """``q̂ ⊞ dθ``: apply a body-frame rotation error ``dθ`` (..., 3) to ``q̂`` (..., 4).

    ``chart="fquat"`` (default) is thesis eq. (3.1), ``q = q̂ ⊗ f_quat(dθ / 2)``;
    ``chart="exp"`` uses the exact exponential, ``q = q̂ ⊗ quat_from_rotvec(dθ)``. The two agree
    to second order in ``dθ``. Either way ``C(q) ≈ (I - [dθ×]) C(q̂)`` and
    ``R(q) ≈ R(q̂) (I + [dθ×])``. The result is normalized.
    """
    dtheta = _as_vec3(dtheta, "dtheta")
    if chart == "fquat":
        dq = f_quat(0.5 * dtheta)
    elif chart == "exp":
        dq = quat_from_rotvec(dtheta)
    else:
        raise ValueError(f"unknown chart {chart!r}; use 'fquat' or 'exp'")
    return quat_normalize(quat_multiply(q_hat, dq))


def quat_boxminus(q: ArrayLike, q_hat: ArrayLike, *, chart: Chart = "fquat") -> FloatArray:
    """``q ⊟ q̂``: the error ``dθ`` with ``quat_boxplus(q̂, dθ, chart=chart) == ±q``.

    ``δq = q̂* ⊗ q`` taken with ``w >= 0``; ``chart="fquat"`` returns ``2 vec(δq)`` (exact inverse
    of the boxplus for ``|dθ| <= 2``), ``chart="exp"`` returns the rotation vector of ``δq``
    (exact inverse for ``|dθ| <= π``).
    """
    dq = quat_positive(quat_multiply(quat_conjugate(quat_normalize(q_hat)), quat_normalize(q)))
    if chart == "fquat":
        return 2.0 * dq[..., 1:]
    if chart == "exp":
        return rotvec_from_quat(dq)
    raise ValueError(f"unknown chart {chart!r}; use 'fquat' or 'exp'")


# --------------------------------------------------------------------------- interpolation


def quat_slerp(q0: ArrayLike, q1: ArrayLike, t: ArrayLike) -> FloatArray:
    """Spherical linear interpolation along the shorter arc (batched, broadcasting).

    ``t`` (...) in ``[0, 1]`` (values outside extrapolate along the same geodesic). Computed as
    ``q0 ⊗ exp(t · log(q0* ⊗ q1))``, which is stable for nearly equal and nearly opposite
    rotations. Returns unit quaternions with the sign continuing ``q0``.
    """
    q0 = quat_normalize(q0)
    q1 = quat_normalize(q1)
    t = np.asarray(t, dtype=np.float64)
    dq = quat_multiply(quat_conjugate(q0), q1)
    phi = rotvec_from_quat(dq)
    return quat_multiply(q0, quat_from_rotvec(t[..., None] * phi))


def quat_interpolate(
    times: ArrayLike,
    quats: ArrayLike,
    query_times: ArrayLike,
    *,
    out_of_range: OutOfRange = "raise",
) -> FloatArray:
    """Slerp a quaternion trajectory ``quats`` (N, 4) sampled at ``times`` (N,) at ``query_times``.

    ``times`` must be strictly increasing. Queries outside ``[times[0], times[-1]]`` raise
    ``ValueError`` (``out_of_range="raise"``), take the end value (``"clamp"``) or give NaN
    (``"nan"``). Returns shape ``(*query_times.shape, 4)``.
    """
    quats = _as_quat(quats)
    if quats.ndim != 2:
        raise ValueError(f"quats must have shape (N, 4), got {quats.shape}")
    i0, i1, alpha, valid = bracket_times(times, query_times, len(quats), out_of_range)
    out = quat_slerp(quats[i0], quats[i1], alpha)
    return np.where(valid[..., None], out, np.nan)
