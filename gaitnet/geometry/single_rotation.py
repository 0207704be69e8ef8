"""One rotation at a time, on Python floats: the formulas of :mod:`gaitnet.geometry.quaternion`
and :mod:`gaitnet.geometry.rotation` written for a single quaternion, matrix or rotation vector.

The filter and the pose tracking convert single rotations thousands of times per session, where
numpy's per-call overhead dominates: these take 2.4–2.8 µs against 15–47 µs through the batched
arrays (docs/benchmarks.md). The batched functions call them for one finite rotation; the
quaternion paths give the batched bits, ``so3_exp_one`` and ``so3_log_one`` the batched values
within 2e-15 (tests/test_geometry_rotation.py, tests/test_geometry_quaternion.py).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

__all__ = [
    "SERIES_BELOW",
    "quat_from_rotmat_floats",
    "rotmat_from_quat_one",
    "so3_exp_one",
    "so3_log_one",
]

SERIES_BELOW = 1e-8
"""Below this norm of a quaternion's vector part its series forms are exact to float64."""


def rotmat_from_quat_one(w: float, x: float, y: float, z: float) -> FloatArray:
    """:func:`~gaitnet.geometry.quaternion.rotmat_from_quat` of one finite quaternion: the
    same formula on Python floats."""
    norm = math.sqrt(w * w + x * x + y * y + z * z)
    if norm < 1e-300:
        raise ValueError("cannot normalize a zero quaternion")
    w, x, y, z = w / norm, x / norm, y / norm, z / norm
    xx, yy, zz = x * x, y * y, z * z
    xy, xz, yz = x * y, x * z, y * z
    wx, wy, wz = w * x, w * y, w * z
    return np.array(
        [
            [1.0 - 2.0 * (yy + zz), 2.0 * (xy - wz), 2.0 * (xz + wy)],
            [2.0 * (xy + wz), 1.0 - 2.0 * (xx + zz), 2.0 * (yz - wx)],
            [2.0 * (xz - wy), 2.0 * (yz + wx), 1.0 - 2.0 * (xx + yy)],
        ]
    )


def quat_from_rotmat_floats(r: list[list[float]]) -> tuple[float, float, float, float]:
    """:func:`~gaitnet.geometry.quaternion.quat_from_rotmat` of one finite matrix given as
    nested lists: the same pivot and formulas on Python floats; ``(w, x, y, z)`` with
    ``w >= 0``."""
    (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = r
    tr = r00 + r11 + r22
    rows = (
        (1.0 + tr, r21 - r12, r02 - r20, r10 - r01),
        (r21 - r12, 1.0 + 2.0 * r00 - tr, r01 + r10, r02 + r20),
        (r02 - r20, r01 + r10, 1.0 + 2.0 * r11 - tr, r12 + r21),
        (r10 - r01, r02 + r20, r12 + r21, 1.0 + 2.0 * r22 - tr),
    )
    diag = (tr, r00, r11, r22)
    w, x, y, z = rows[max(range(4), key=diag.__getitem__)]  # the first of equal pivots
    # the four pivots sum to 4, so the largest is at least 1 and so is the row's norm
    norm = math.sqrt(w * w + x * x + y * y + z * z)
    if w < 0.0:
        norm = -norm
    return w / norm, x / norm, y / norm, z / norm


def so3_exp_one(x: float, y: float, z: float) -> FloatArray | None:
    """:func:`~gaitnet.geometry.rotation.so3_exp` of one rotation vector: the same formula on
    Python floats; None where its square overflows (the batched path then)."""
    theta = math.sqrt(x * x + y * y + z * z)
    if not math.isfinite(theta):
        return None
    if theta > 0.0:
        A = math.sin(theta) / theta
        half = math.sin(0.5 * theta) / (0.5 * theta)
    else:
        A = half = 1.0
    B = 0.5 * half * half
    xx, yy, zz, xy, xz, yz = x * x, y * y, z * z, x * y, x * z, y * z
    return np.array(
        [
            [1.0 - B * (yy + zz), -A * z + B * xy, A * y + B * xz],
            [A * z + B * xy, 1.0 - B * (xx + zz), -A * x + B * yz],
            [-A * y + B * xz, A * x + B * yz, 1.0 - B * (xx + yy)],
        ]
    )


def so3_log_one(r: list[list[float]]) -> FloatArray:
    """:func:`~gaitnet.geometry.rotation.so3_log` of one finite matrix (nested lists): the
    Shepperd/Markley quaternion of :func:`quat_from_rotmat_floats` and the ``atan2`` of
    :func:`~gaitnet.geometry.quaternion.rotvec_from_quat`, on Python floats."""
    w, a, b, c = quat_from_rotmat_floats(r)
    n = math.sqrt(a * a + b * b + c * c)
    # below SERIES_BELOW: 2 atan2(n, w) / n = (2/w)(1 − n²/(3w²) + …), as rotvec_from_quat
    small = n < SERIES_BELOW
    scale = (2.0 / w) * (1.0 - n * n / (3.0 * w * w)) if small else 2.0 * math.atan2(n, w) / n
    return np.array([scale * a, scale * b, scale * c])
