"""Differentiable, batched rotation functions in torch (for forward kinematics / L-BFGS fits).

Same conventions as the numpy modules: rotation matrices are active (``v' = R v``),
quaternions are Hamilton ``[w, x, y, z]`` with ``rotmat_from_quat_torch(q) = R(q)`` (body-to-
world; the thesis world-to-body DCM is its transpose). Every function keeps the input's dtype
and device, accepts any leading batch shape, and has finite gradients at the identity
(``phi = 0``), where the naive formulas divide by zero.
"""

from __future__ import annotations

import torch

__all__ = [
    "quat_from_rotmat_torch",
    "rotmat_from_quat_torch",
    "skew_torch",
    "so3_exp_torch",
    "so3_log_torch",
]


def _check_last(x: torch.Tensor, n: int, name: str) -> None:
    if x.shape[-1:] != (n,):
        raise ValueError(f"{name} needs a last axis of length {n}, got shape {tuple(x.shape)}")


def skew_torch(v: torch.Tensor) -> torch.Tensor:
    """``[v×]`` for ``v`` (..., 3) → (..., 3, 3)."""
    _check_last(v, 3, "skew_torch")
    x, y, z = v.unbind(-1)
    o = torch.zeros_like(x)
    return torch.stack(
        [
            torch.stack([o, -z, y], dim=-1),
            torch.stack([z, o, -x], dim=-1),
            torch.stack([-y, x, o], dim=-1),
        ],
        dim=-2,
    )


def so3_exp_torch(phi: torch.Tensor) -> torch.Tensor:
    """Rotation vector ``phi`` (..., 3) → rotation matrix (..., 3, 3) (Rodrigues).

    ``R = I + (sin θ/θ)[φ×] + ((1 - cos θ)/θ²)[φ×]²``. The coefficients switch to their Taylor
    series for ``θ² < eps(dtype)``, so the value is exact and the gradient finite (equal to the
    generators ``[e_i×]``) at ``phi = 0``. ``(1 - cos θ)/θ²`` is evaluated as
    ``2 (sin(θ/2)/θ)²`` to avoid cancellation in float32.
    """
    _check_last(phi, 3, "so3_exp_torch")
    theta2 = (phi * phi).sum(-1)
    small = theta2 < torch.finfo(phi.dtype).eps
    theta2_safe = torch.where(small, torch.ones_like(theta2), theta2)
    theta = torch.sqrt(theta2_safe)
    a_series = 1.0 - theta2 / 6.0 + theta2 * theta2 / 120.0
    b_series = 0.5 - theta2 / 24.0 + theta2 * theta2 / 720.0
    s_half = torch.sin(0.5 * theta) / theta
    A = torch.where(small, a_series, torch.sin(theta) / theta)
    B = torch.where(small, b_series, 2.0 * s_half * s_half)
    K = skew_torch(phi)
    eye = torch.eye(3, dtype=phi.dtype, device=phi.device)
    return eye + A[..., None, None] * K + B[..., None, None] * (K @ K)


def rotmat_from_quat_torch(q: torch.Tensor) -> torch.Tensor:
    """``R(q)`` (..., 3, 3) of Hamilton quaternions ``[w, x, y, z]`` (..., 4), normalized first."""
    _check_last(q, 4, "rotmat_from_quat_torch")
    q = q / torch.linalg.vector_norm(q, dim=-1, keepdim=True)
    w, x, y, z = q.unbind(-1)
    return torch.stack(
        [
            torch.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            torch.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            torch.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        dim=-2,
    )


def quat_from_rotmat_torch(R: torch.Tensor) -> torch.Tensor:
    """Unit quaternion ``[w, x, y, z]`` (``w >= 0``) with ``R(q) = R`` (Shepperd/Markley)."""
    if R.shape[-2:] != (3, 3):
        raise ValueError(f"quat_from_rotmat_torch needs (..., 3, 3), got {tuple(R.shape)}")
    r00, r01, r02 = R[..., 0, 0], R[..., 0, 1], R[..., 0, 2]
    r10, r11, r12 = R[..., 1, 0], R[..., 1, 1], R[..., 1, 2]
    r20, r21, r22 = R[..., 2, 0], R[..., 2, 1], R[..., 2, 2]
    tr = r00 + r11 + r22
    M = torch.stack(
        [
            torch.stack([1 + tr, r21 - r12, r02 - r20, r10 - r01], -1),
            torch.stack([r21 - r12, 1 + 2 * r00 - tr, r01 + r10, r02 + r20], -1),
            torch.stack([r02 - r20, r01 + r10, 1 + 2 * r11 - tr, r12 + r21], -1),
            torch.stack([r10 - r01, r02 + r20, r12 + r21, 1 + 2 * r22 - tr], -1),
        ],
        dim=-2,
    )
    k = torch.stack([tr, r00, r11, r22], -1).argmax(-1)
    idx = k[..., None, None].expand(*k.shape, 1, 4)
    row = torch.gather(M, -2, idx).squeeze(-2)
    q = row / torch.linalg.vector_norm(row, dim=-1, keepdim=True)
    return torch.where(q[..., :1] < 0, -q, q)


def so3_log_torch(R: torch.Tensor) -> torch.Tensor:
    """Rotation vector (..., 3) of ``R`` (..., 3, 3), angle in ``[0, π]``; inverse of exp.

    Via :func:`quat_from_rotmat_torch` and ``atan2`` (accurate near 0 and π). The gradient is
    finite at the identity; at exactly π the log is not differentiable (sign ambiguity).
    """
    q = quat_from_rotmat_torch(R)
    w = q[..., :1]
    v = q[..., 1:]
    n2 = (v * v).sum(-1, keepdim=True)
    small = n2 < torch.finfo(R.dtype).eps
    n_safe = torch.sqrt(torch.where(small, torch.ones_like(n2), n2))
    w_safe = torch.where(small, w, torch.ones_like(w))
    scale = torch.where(
        small,
        (2.0 / w_safe) * (1.0 - n2 / (3.0 * w_safe * w_safe)),
        2.0 * torch.atan2(n_safe, w) / n_safe,
    )
    return scale * v
