"""SO(3) helpers on rotation matrices (numpy, batched).

All matrices here are ordinary *active* rotation matrices ``R`` (``v' = R v``); ``so3_exp(phi)``
rotates by ``|phi|`` about ``phi/|phi|`` and equals ``rotmat_from_quat(quat_from_rotvec(phi))``.
For the thesis world-to-body DCM use ``C = R.T`` (see :mod:`gaitnet.geometry.quaternion`).

Jacobians follow Solà et al., "A micro Lie theory for state estimation in robotics" (2018):
``so3_exp(phi + d) ≈ so3_exp(phi) @ so3_exp(Jr(phi) @ d)`` and
``so3_exp(phi + d) ≈ so3_exp(Jl(phi) @ d) @ so3_exp(phi)``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gaitnet.geometry.quaternion import quat_from_rotmat, rotvec_from_quat
from gaitnet.geometry.single_rotation import so3_exp_one, so3_log_one

FloatArray = NDArray[np.float64]

__all__ = [
    "skew",
    "so3_exp",
    "so3_left_jacobian",
    "so3_left_jacobian_inv",
    "so3_log",
    "so3_right_jacobian",
    "so3_right_jacobian_inv",
    "unskew",
]

_SERIES_ANGLE = 0.1  # below this angle the Jacobian coefficients use their Taylor series


def _as_vec3(v: ArrayLike) -> FloatArray:
    v = np.asarray(v, dtype=np.float64)
    if v.shape[-1:] != (3,):
        raise ValueError(f"expected a last axis of length 3, got shape {v.shape}")
    return v


def skew(v: ArrayLike) -> FloatArray:
    """``[v×]``: the skew-symmetric matrix with ``[v×] w = v × w``; ``(..., 3) -> (..., 3, 3)``."""
    v = _as_vec3(v)
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    S = np.zeros((*v.shape[:-1], 3, 3))
    S[..., 0, 1] = -z
    S[..., 0, 2] = y
    S[..., 1, 0] = z
    S[..., 1, 2] = -x
    S[..., 2, 0] = -y
    S[..., 2, 1] = x
    return S


def unskew(S: ArrayLike) -> FloatArray:
    """Inverse of :func:`skew` (of the antisymmetric part of ``S``). ``(..., 3, 3) -> (..., 3)``."""
    S = np.asarray(S, dtype=np.float64)
    if S.shape[-2:] != (3, 3):
        raise ValueError(f"expected trailing shape (3, 3), got {S.shape}")
    return 0.5 * np.stack(
        [S[..., 2, 1] - S[..., 1, 2], S[..., 0, 2] - S[..., 2, 0], S[..., 1, 0] - S[..., 0, 1]],
        axis=-1,
    )


def _exp_coeffs(theta: FloatArray) -> tuple[FloatArray, FloatArray]:
    """``A = sin θ / θ`` and ``B = (1 - cos θ) / θ²``, both exact as θ → 0."""
    A = np.sinc(theta / np.pi)
    half = np.sinc(theta / (2.0 * np.pi))  # sin(θ/2) / (θ/2)
    B = 0.5 * half * half
    return A, B


def so3_exp(phi: ArrayLike) -> FloatArray:
    """Rodrigues' formula: rotation vector ``(..., 3)`` → rotation matrix ``(..., 3, 3)``.

    ``R = I + (sin θ/θ)[φ×] + ((1 - cos θ)/θ²)[φ×]²``, evaluated without cancellation so it is
    accurate for tiny angles (and exactly ``I`` at ``φ = 0``).
    """
    phi = _as_vec3(phi)
    if phi.ndim == 1 and np.isfinite(phi).all():
        one = so3_exp_one(*phi.tolist())
        if one is not None:
            return one
    theta = np.linalg.norm(phi, axis=-1)
    A, B = _exp_coeffs(theta)
    K = skew(phi)
    return np.eye(3) + A[..., None, None] * K + B[..., None, None] * (K @ K)


def so3_log(R: ArrayLike) -> FloatArray:
    """Rotation vector of ``R`` (inverse of :func:`so3_exp`), angle in ``[0, π]``.

    Goes through the Shepperd/Markley quaternion and ``atan2``, so it is accurate near 0
    and near π (where the trace-based ``arccos`` formula loses precision). At exactly π the
    sign of the returned vector is arbitrary (both signs are the same rotation).
    """
    R = np.asarray(R, dtype=np.float64)
    if R.shape == (3, 3) and np.isfinite(R).all():
        return so3_log_one(R.tolist())
    return rotvec_from_quat(quat_from_rotmat(R))


def _jacobian_coeffs(theta: FloatArray) -> tuple[FloatArray, FloatArray]:
    """``B = (1 - cos θ)/θ²`` and ``Cc = (θ - sin θ)/θ³`` (series below ``_SERIES_ANGLE``)."""
    _, B = _exp_coeffs(theta)
    small = theta < _SERIES_ANGLE
    t = np.where(small, 1.0, theta)
    t2 = theta * theta
    Cc = np.where(
        small,
        1.0 / 6.0 - t2 / 120.0 + t2 * t2 / 5040.0 - t2 * t2 * t2 / 362880.0,
        (t - np.sin(t)) / (t * t * t),
    )
    return B, Cc


def so3_right_jacobian(phi: ArrayLike) -> FloatArray:
    """Right Jacobian ``Jr(φ) = I - ((1 - cos θ)/θ²)[φ×] + ((θ - sin θ)/θ³)[φ×]²``.

    ``so3_exp(φ + δ) ≈ so3_exp(φ) so3_exp(Jr(φ) δ)``. ``(..., 3) -> (..., 3, 3)``.
    """
    phi = _as_vec3(phi)
    B, Cc = _jacobian_coeffs(np.linalg.norm(phi, axis=-1))
    K = skew(phi)
    return np.eye(3) - B[..., None, None] * K + Cc[..., None, None] * (K @ K)


def so3_left_jacobian(phi: ArrayLike) -> FloatArray:
    """Left Jacobian ``Jl(φ) = Jr(-φ) = Jr(φ).T``; also the SE(3) ``V`` matrix."""
    return so3_right_jacobian(-_as_vec3(phi))


def so3_right_jacobian_inv(phi: ArrayLike) -> FloatArray:
    """``Jr(φ)⁻¹ = I + ½[φ×] + (1/θ² - (1 + cos θ)/(2θ sin θ))[φ×]²`` (valid for θ < 2π)."""
    phi = _as_vec3(phi)
    theta = np.linalg.norm(phi, axis=-1)
    small = theta < _SERIES_ANGLE
    t = np.where(small, 1.0, theta)
    t2 = theta * theta
    D = np.where(
        small,
        1.0 / 12.0 + t2 / 720.0 + t2 * t2 / 30240.0 + t2 * t2 * t2 / 1209600.0,
        1.0 / (t * t) - (1.0 + np.cos(t)) / (2.0 * t * np.sin(t)),
    )
    K = skew(phi)
    return np.eye(3) + 0.5 * K + D[..., None, None] * (K @ K)


def so3_left_jacobian_inv(phi: ArrayLike) -> FloatArray:
    """``Jl(φ)⁻¹ = Jr(-φ)⁻¹``."""
    return so3_right_jacobian_inv(-_as_vec3(phi))
