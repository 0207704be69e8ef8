"""Torch rotations: agreement with the numpy versions and safe gradients at zero angle."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from gaitnet.geometry import quat_from_rotmat, rotmat_from_quat, skew, so3_exp, so3_log
from gaitnet.geometry.torch_rotations import (
    quat_from_rotmat_torch,
    rotmat_from_quat_torch,
    skew_torch,
    so3_exp_torch,
    so3_log_torch,
)


def random_rotvecs(rng: np.random.Generator, n: int, max_angle: float = np.pi) -> np.ndarray:
    phi = rng.normal(size=(n, 3))
    phi /= np.linalg.norm(phi, axis=-1, keepdims=True)
    return phi * rng.uniform(0.0, max_angle, (n, 1))


def test_skew_torch_matches_numpy() -> None:
    v = np.random.default_rng(0).normal(size=(4, 5, 3))
    np.testing.assert_array_equal(skew_torch(torch.from_numpy(v)).numpy(), skew(v))


def test_so3_exp_torch_matches_numpy() -> None:
    rng = np.random.default_rng(1)
    phi = np.concatenate([random_rotvecs(rng, 100), np.zeros((1, 3)), [[1e-9, 0, -1e-9]]])
    R = so3_exp_torch(torch.from_numpy(phi))
    assert R.dtype == torch.float64
    np.testing.assert_allclose(R.numpy(), so3_exp(phi), atol=1e-15)
    batched = so3_exp_torch(torch.from_numpy(phi[:100].reshape(4, 25, 3)))
    assert batched.shape == (4, 25, 3, 3)
    np.testing.assert_allclose(batched.numpy().reshape(100, 3, 3), so3_exp(phi[:100]), atol=1e-15)


@pytest.mark.parametrize("phi", [[4e-4, 1e-4, -2e-4], [5e-4, 0.0, 0.0], [1e-3, 2e-3, -1e-3]])
def test_so3_exp_torch_float32_small_angle_gradients(phi: list[float]) -> None:
    """Just above the series switch, a naive (1 - cos θ)/θ² makes float32 gradients ~1e-5 off."""
    p = torch.tensor(phi)
    R32 = so3_exp_torch(p.float())
    assert R32.dtype == torch.float32
    np.testing.assert_allclose(R32.double().numpy(), so3_exp(np.array(phi)), atol=1e-7)
    J32 = torch.autograd.functional.jacobian(so3_exp_torch, p.float())
    J64 = torch.autograd.functional.jacobian(so3_exp_torch, p.double())
    np.testing.assert_allclose(J32.double().numpy(), J64.numpy(), atol=1e-6)


def test_so3_exp_torch_gradcheck() -> None:
    rng = np.random.default_rng(2)
    phi = torch.tensor(random_rotvecs(rng, 6), dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(so3_exp_torch, (phi,), eps=1e-6, atol=1e-8)
    for tiny in ([0.0, 0.0, 0.0], [1e-9, -2e-9, 1e-9], [1e-5, 0.0, 0.0]):
        p = torch.tensor([tiny], dtype=torch.float64, requires_grad=True)
        assert torch.autograd.gradcheck(so3_exp_torch, (p,), eps=1e-6, atol=1e-8)


def test_so3_exp_torch_gradient_at_zero_is_finite_and_equals_generators() -> None:
    phi = torch.zeros(3, dtype=torch.float64, requires_grad=True)
    J = torch.autograd.functional.jacobian(so3_exp_torch, phi)  # (3, 3, 3): dR_ij / dphi_k
    assert torch.isfinite(J).all()
    for k in range(3):
        np.testing.assert_allclose(J[..., k].numpy(), skew(np.eye(3)[k]), atol=1e-15)
    # a loss through the zero rotation back-propagates finite values in float32 too
    p32 = torch.zeros(5, 3, requires_grad=True)
    loss = (so3_exp_torch(p32) @ torch.ones(3)).square().sum()
    loss.backward()
    assert p32.grad is not None and torch.isfinite(p32.grad).all()


def test_so3_log_torch_matches_numpy_and_round_trips() -> None:
    rng = np.random.default_rng(3)
    phi = np.concatenate(
        [random_rotvecs(rng, 100), [[np.pi - 1e-9, 0.0, 0.0], [1e-10, 0.0, 0.0], [0.0, 0.0, 0.0]]]
    )
    R = so3_exp(phi)
    out = so3_log_torch(torch.from_numpy(R))
    np.testing.assert_allclose(out.numpy(), so3_log(R), atol=1e-15)
    np.testing.assert_allclose(out.numpy(), phi, atol=1e-13)
    back = so3_log_torch(so3_exp_torch(torch.from_numpy(phi)))
    np.testing.assert_allclose(back.numpy(), phi, atol=1e-13)


def test_so3_log_torch_gradients() -> None:
    rng = np.random.default_rng(4)
    phi = torch.tensor(
        random_rotvecs(rng, 5, max_angle=2.5), dtype=torch.float64, requires_grad=True
    )

    def log_exp(p: torch.Tensor) -> torch.Tensor:
        return so3_log_torch(so3_exp_torch(p))

    assert torch.autograd.gradcheck(log_exp, (phi,), eps=1e-6, atol=1e-7)
    # at the identity, d log(exp(φ))/dφ = I (finite, no NaN from |v| = 0)
    zero = torch.zeros(3, dtype=torch.float64, requires_grad=True)
    J = torch.autograd.functional.jacobian(log_exp, zero)
    np.testing.assert_allclose(J.numpy(), np.eye(3), atol=1e-12)


def test_quaternion_torch_matches_numpy() -> None:
    rng = np.random.default_rng(5)
    q = rng.normal(size=(50, 4))
    R = rotmat_from_quat_torch(torch.from_numpy(q)).numpy()
    np.testing.assert_allclose(R, rotmat_from_quat(q), atol=1e-15)
    q_back = quat_from_rotmat_torch(torch.from_numpy(R)).numpy()
    np.testing.assert_allclose(q_back, quat_from_rotmat(R), atol=1e-15)
    assert np.all(q_back[:, 0] >= 0)


def test_shape_errors() -> None:
    with pytest.raises(ValueError):
        so3_exp_torch(torch.zeros(4))
    with pytest.raises(ValueError):
        so3_log_torch(torch.zeros(4, 4))
    with pytest.raises(ValueError):
        rotmat_from_quat_torch(torch.zeros(3))
