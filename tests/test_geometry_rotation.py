"""SO(3): skew, exp/log (against scipy) and Jacobians (against central differences)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from gaitnet.geometry import (
    quat_from_rotvec,
    rotmat_from_quat,
    skew,
    so3_exp,
    so3_left_jacobian,
    so3_left_jacobian_inv,
    so3_log,
    so3_right_jacobian,
    so3_right_jacobian_inv,
    unskew,
)


def unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def test_skew_is_cross_product_and_unskew_inverts() -> None:
    rng = np.random.default_rng(0)
    v, w = rng.normal(size=(2, 50, 3))
    S = skew(v)
    assert S.shape == (50, 3, 3)
    np.testing.assert_allclose((S @ w[..., None])[..., 0], np.cross(v, w), atol=1e-15)
    np.testing.assert_array_equal(S, -np.swapaxes(S, -1, -2))
    np.testing.assert_array_equal(unskew(S), v)
    # unskew keeps only the antisymmetric part
    sym = rng.normal(size=(3, 3))
    np.testing.assert_allclose(unskew(skew(v[0]) + sym + sym.T), v[0], atol=1e-15)
    with pytest.raises(ValueError):
        skew(np.zeros(4))


def test_so3_exp_matches_scipy() -> None:
    rng = np.random.default_rng(1)
    angles = np.concatenate([rng.uniform(0, 2 * np.pi, 200), [0.0, 1e-12, 1e-9, 1e-5, np.pi]])
    phi = unit(rng.normal(size=(len(angles), 3))) * angles[:, None]
    R = so3_exp(phi)
    np.testing.assert_allclose(R, Rotation.from_rotvec(phi).as_matrix(), atol=1e-14)
    np.testing.assert_allclose(R, rotmat_from_quat(quat_from_rotvec(phi)), atol=1e-14)
    np.testing.assert_allclose(
        R @ np.swapaxes(R, -1, -2), np.broadcast_to(np.eye(3), R.shape), atol=1e-14
    )
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-14)
    np.testing.assert_array_equal(so3_exp(np.zeros(3)), np.eye(3))


def test_so3_exp_tiny_angle_is_first_order_exact() -> None:
    phi = np.array([1e-9, -2e-9, 0.5e-9])
    # I + [φ×] is exact to O(1e-18) here; a cancelling formula would lose the off-diagonals.
    np.testing.assert_allclose(so3_exp(phi) - np.eye(3), skew(phi), rtol=1e-8, atol=1e-24)


def test_so3_log_round_trip_and_scipy() -> None:
    rng = np.random.default_rng(2)
    phi = unit(rng.normal(size=(300, 3))) * rng.uniform(0, np.pi, (300, 1))
    back = so3_log(so3_exp(phi))
    np.testing.assert_allclose(back, phi, atol=2e-15)
    R = Rotation.from_rotvec(phi).as_matrix()
    np.testing.assert_allclose(so3_log(R), Rotation.from_matrix(R).as_rotvec(), atol=2e-15)


@pytest.mark.parametrize("angle", [1e-12, 1e-9, 1e-7, 1e-4])
def test_so3_log_near_zero(angle: float) -> None:
    rng = np.random.default_rng(3)
    phi = unit(rng.normal(size=(20, 3))) * angle
    back = so3_log(Rotation.from_rotvec(phi).as_matrix())
    np.testing.assert_allclose(back, phi, rtol=1e-7, atol=0.0)
    np.testing.assert_array_equal(so3_log(np.eye(3)), np.zeros(3))


@pytest.mark.parametrize("delta", [0.0, 1e-12, 1e-9, 1e-6, 1e-3])
def test_so3_log_near_pi(delta: float) -> None:
    rng = np.random.default_rng(4)
    axes = np.concatenate([np.eye(3), unit(rng.normal(size=(20, 3)))])
    phi = axes * (np.pi - delta)
    R = Rotation.from_rotvec(phi).as_matrix()
    back = so3_log(R)
    angle = np.linalg.norm(back, axis=-1)
    np.testing.assert_allclose(angle, np.pi - delta, atol=1e-13)
    # near π the axis is recovered up to sign only at exactly π
    if delta == 0.0:
        np.testing.assert_allclose(np.abs(np.sum(unit(back) * axes, axis=-1)), 1.0, atol=1e-14)
    else:
        np.testing.assert_allclose(back, phi, atol=1e-13)
    np.testing.assert_allclose(so3_exp(back), R, atol=1e-14)


def test_so3_log_batched_shape() -> None:
    rng = np.random.default_rng(5)
    phi = rng.normal(size=(4, 5, 3))
    phi *= 0.9 * np.pi / np.maximum(np.linalg.norm(phi, axis=-1, keepdims=True), np.pi)
    assert so3_exp(phi).shape == (4, 5, 3, 3)
    np.testing.assert_allclose(so3_log(so3_exp(phi)), phi, atol=1e-14)


# --------------------------------------------------------------------------- Jacobians

JACOBIAN_POINTS = [
    np.zeros(3),
    np.array([1e-7, -2e-7, 3e-7]),  # series branch
    np.array([0.03, 0.05, -0.04]),  # series branch, near the switch
    np.array([0.2, -0.1, 0.3]),
    np.array([1.0, 2.0, -0.5]),
    np.array([0.0, 0.0, 3.0]),
]


def numeric_right_jacobian(phi: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """J[:, i] = d/dε Log(Exp(φ)ᵀ Exp(φ + ε e_i)) at ε = 0 (central differences)."""
    R0t = so3_exp(phi).T
    J = np.empty((3, 3))
    for i in range(3):
        e = np.zeros(3)
        e[i] = h
        J[:, i] = (so3_log(R0t @ so3_exp(phi + e)) - so3_log(R0t @ so3_exp(phi - e))) / (2 * h)
    return J


def numeric_left_jacobian(phi: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """J[:, i] = d/dε Log(Exp(φ + ε e_i) Exp(φ)ᵀ) at ε = 0 (central differences)."""
    R0t = so3_exp(phi).T
    J = np.empty((3, 3))
    for i in range(3):
        e = np.zeros(3)
        e[i] = h
        J[:, i] = (so3_log(so3_exp(phi + e) @ R0t) - so3_log(so3_exp(phi - e) @ R0t)) / (2 * h)
    return J


@pytest.mark.parametrize("phi", JACOBIAN_POINTS, ids=lambda p: f"{np.linalg.norm(p):.1e}")
def test_right_and_left_jacobians_match_finite_differences(phi: np.ndarray) -> None:
    np.testing.assert_allclose(so3_right_jacobian(phi), numeric_right_jacobian(phi), atol=1e-8)
    np.testing.assert_allclose(so3_left_jacobian(phi), numeric_left_jacobian(phi), atol=1e-8)


@pytest.mark.parametrize("phi", JACOBIAN_POINTS, ids=lambda p: f"{np.linalg.norm(p):.1e}")
def test_jacobian_inverses_and_identities(phi: np.ndarray) -> None:
    Jr = so3_right_jacobian(phi)
    np.testing.assert_allclose(Jr @ so3_right_jacobian_inv(phi), np.eye(3), atol=1e-14)
    np.testing.assert_allclose(
        so3_left_jacobian(phi) @ so3_left_jacobian_inv(phi), np.eye(3), atol=1e-14
    )
    np.testing.assert_allclose(so3_left_jacobian(phi), Jr.T, atol=1e-15)
    np.testing.assert_allclose(Jr @ phi, phi, atol=1e-15)  # the axis is unchanged


def test_jacobians_continuous_across_series_switch() -> None:
    d = unit(np.array([0.3, -0.7, 0.2]))
    for f in (so3_right_jacobian, so3_right_jacobian_inv):
        below = f(d * (0.1 - 1e-12))
        above = f(d * (0.1 + 1e-12))
        np.testing.assert_allclose(below, above, atol=1e-13)


def test_jacobians_batched() -> None:
    rng = np.random.default_rng(6)
    phi = rng.normal(size=(3, 4, 3))
    J = so3_right_jacobian(phi)
    assert J.shape == (3, 4, 3, 3)
    np.testing.assert_allclose(J[2, 1], so3_right_jacobian(phi[2, 1]))
    np.testing.assert_allclose(
        so3_right_jacobian_inv(phi)[0, 3], np.linalg.inv(J[0, 3]), atol=1e-12
    )


def _hard_rotation_vectors() -> np.ndarray:
    rng = np.random.default_rng(21)
    axes = rng.normal(size=(40, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    angles = [0.0, 1e-300, 1e-12, 1e-9, 1e-5, 0.05, 0.1, 1.0, 2.0, 3.0, np.pi - 1e-9, np.pi]
    near = [a * ax for a in angles for ax in axes[:5]]
    exact_pi = [np.pi * np.eye(3)[k] for k in range(3)] + [np.pi * axes[0]]
    return np.array([*near, *exact_pi, *(rng.normal(size=(300, 3)) * 1.5)])


def test_single_rotation_fast_paths_match_the_batched_formulas() -> None:
    """One vector / one matrix take a Python-float path; it must give the batched result."""
    phis = _hard_rotation_vectors()
    for phi in phis:
        R = so3_exp(phi)
        np.testing.assert_allclose(R, so3_exp(phi[None])[0], rtol=0, atol=4e-15)
        log_one, log_batched = so3_log(R), so3_log(R[None])[0]
        np.testing.assert_allclose(log_one, log_batched, rtol=0, atol=4e-15)
    # a slightly non-orthogonal matrix and a plain list take the same path
    R = so3_exp(np.array([0.4, -1.1, 0.3])) + 1e-7
    np.testing.assert_allclose(so3_log(R), so3_log(R[None])[0], rtol=0, atol=4e-15)
    np.testing.assert_allclose(so3_log(R.tolist()), so3_log(R), rtol=0, atol=0)


def test_single_rotation_fast_paths_pass_nan_on() -> None:
    assert np.isnan(so3_exp(np.array([np.nan, 0.0, 0.0]))).all()
    with np.errstate(invalid="ignore", over="ignore"):
        huge = so3_exp(np.array([1e160, 0.0, 0.0]))  # its square overflows: the batched path
        np.testing.assert_array_equal(huge, so3_exp(np.array([[1e160, 0.0, 0.0]]))[0])
    with np.errstate(invalid="ignore"):
        assert np.isnan(so3_log(np.full((3, 3), np.nan))).all()
        assert np.isnan(so3_log(np.diag([np.inf, 1.0, 1.0]))).any()
