"""SE(3): homogeneous transforms, exp/log (against scipy.linalg.expm), TUM rows, interpolation."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm
from scipy.spatial.transform import Rotation, Slerp

from gaitnet.geometry import (
    T_from_tum,
    compose,
    dcm_from_quat,
    interpolate_poses,
    invert_T,
    make_T,
    rotmat_from_quat,
    se3_exp,
    se3_log,
    skew,
    transform_points,
    tum_from_T,
)


def random_T(rng: np.random.Generator, n: int) -> np.ndarray:
    R = Rotation.random(n, rng=rng).as_matrix()
    t = rng.normal(size=(n, 3))
    return make_T(R, t)


def test_make_T_layout_and_broadcast() -> None:
    R = Rotation.from_rotvec([0.1, 0.2, 0.3]).as_matrix()
    t = np.array([1.0, 2.0, 3.0])
    T = make_T(R, t)
    np.testing.assert_array_equal(T[:3, :3], R)
    np.testing.assert_array_equal(T[:3, 3], t)
    np.testing.assert_array_equal(T[3], [0, 0, 0, 1])
    Tb = make_T(R, np.zeros((5, 3)))  # one rotation, many translations
    assert Tb.shape == (5, 4, 4)
    np.testing.assert_array_equal(Tb[4, :3, :3], R)
    with pytest.raises(ValueError):
        make_T(np.eye(3), np.zeros(4))


def test_invert_and_compose() -> None:
    rng = np.random.default_rng(0)
    T = random_T(rng, 50)
    Ti = invert_T(T)
    eye = np.broadcast_to(np.eye(4), T.shape)
    np.testing.assert_allclose(compose(T, Ti), eye, atol=1e-14)
    np.testing.assert_allclose(compose(Ti, T), eye, atol=1e-14)
    np.testing.assert_allclose(Ti, np.linalg.inv(T), atol=1e-13)
    np.testing.assert_array_equal(Ti[:, 3], np.broadcast_to([0, 0, 0, 1.0], (50, 4)))
    A, B, C = random_T(rng, 3)
    np.testing.assert_allclose(compose(A, B, C), A @ B @ C, atol=1e-14)
    np.testing.assert_array_equal(compose(A), A)
    with pytest.raises(ValueError):
        compose()


def test_transform_points_against_manual_formula() -> None:
    rng = np.random.default_rng(1)
    T = random_T(rng, 1)[0]
    p = rng.normal(size=(6, 7, 3))
    manual = np.einsum("ij,abj->abi", T[:3, :3], p) + T[:3, 3]
    np.testing.assert_allclose(transform_points(T, p), manual, atol=1e-14)
    # batched transforms, one point each
    Ts = random_T(rng, 8)
    q = rng.normal(size=(8, 3))
    manual_b = np.stack([Ts[i, :3, :3] @ q[i] + Ts[i, :3, 3] for i in range(8)])
    np.testing.assert_allclose(transform_points(Ts, q), manual_b, atol=1e-14)
    # broadcasting: (8, 1) transforms × (5,) points → (8, 5, 3)
    pts = rng.normal(size=(5, 3))
    out = transform_points(Ts[:, None], pts)
    assert out.shape == (8, 5, 3)
    np.testing.assert_allclose(out[3, 2], Ts[3, :3, :3] @ pts[2] + Ts[3, :3, 3], atol=1e-14)


def test_frame_chaining_semantics() -> None:
    rng = np.random.default_rng(2)
    T_AfromB, T_BfromC = random_T(rng, 2)
    p_C = rng.normal(size=(10, 3))
    p_A = transform_points(T_AfromB, transform_points(T_BfromC, p_C))
    np.testing.assert_allclose(transform_points(compose(T_AfromB, T_BfromC), p_C), p_A, atol=1e-13)
    np.testing.assert_allclose(
        transform_points(invert_T(compose(T_AfromB, T_BfromC)), p_A), p_C, atol=1e-13
    )


def hat6(xi: np.ndarray) -> np.ndarray:
    M = np.zeros((4, 4))
    M[:3, :3] = skew(xi[3:])
    M[:3, 3] = xi[:3]
    return M


@pytest.mark.parametrize("rot_scale", [0.0, 1e-9, 1e-3, 0.5, 2.0, 3.1])
def test_se3_exp_matches_matrix_exponential_and_log_inverts(rot_scale: float) -> None:
    rng = np.random.default_rng(3)
    for _ in range(10):
        rho = rng.normal(size=3)
        phi = rng.normal(size=3)
        phi *= rot_scale / np.linalg.norm(phi)
        xi = np.concatenate([rho, phi])
        T = se3_exp(xi)
        np.testing.assert_allclose(T, expm(hat6(xi)), atol=1e-12)
        np.testing.assert_allclose(se3_log(T), xi, atol=1e-12)


def test_se3_batched() -> None:
    rng = np.random.default_rng(4)
    xi = rng.normal(size=(3, 5, 6))
    T = se3_exp(xi)
    assert T.shape == (3, 5, 4, 4)
    np.testing.assert_allclose(T[1, 2], se3_exp(xi[1, 2]))
    np.testing.assert_allclose(se3_exp(se3_log(T)), T, atol=1e-13)


# --------------------------------------------------------------------------- TUM rows


def test_tum_known_pose() -> None:
    # sensor at (1, 2, 3), yawed +90° about world z: its x axis points along world +y
    s = np.sqrt(0.5)
    row = np.array([1.0, 2.0, 3.0, 0.0, 0.0, s, s])
    T = T_from_tum(row)
    np.testing.assert_allclose(transform_points(T, [1.0, 0.0, 0.0]), [1.0, 3.0, 3.0], atol=1e-15)
    np.testing.assert_allclose(tum_from_T(T), row, atol=1e-15)


def test_tum_quaternion_is_scipy_active_scalar_last_and_thesis_attitude() -> None:
    rng = np.random.default_rng(5)
    T = random_T(rng, 40)
    rows = tum_from_T(T)
    assert rows.shape == (40, 7)
    np.testing.assert_array_equal(rows[:, :3], T[:, :3, 3])
    assert np.all(rows[:, 6] >= 0.0)
    # scipy reads scalar-last quaternions as the active rotation R_WfromS
    np.testing.assert_allclose(
        Rotation.from_quat(rows[:, 3:]).as_matrix(), T[:, :3, :3], atol=1e-14
    )
    # reordered to [w, x, y, z] it is the thesis world-to-body attitude: C(q) = R_WfromS^T
    q = rows[:, [6, 3, 4, 5]]
    np.testing.assert_allclose(dcm_from_quat(q), np.swapaxes(T[:, :3, :3], -1, -2), atol=1e-14)
    np.testing.assert_allclose(rotmat_from_quat(q), T[:, :3, :3], atol=1e-14)


def test_tum_round_trips() -> None:
    rng = np.random.default_rng(6)
    T = random_T(rng, 30)
    np.testing.assert_allclose(T_from_tum(tum_from_T(T)), T, atol=1e-14)
    rows = np.concatenate([rng.normal(size=(30, 3)), rng.normal(size=(30, 4))], axis=-1)
    rows[:, 3:] /= np.linalg.norm(rows[:, 3:], axis=-1, keepdims=True)
    back = tum_from_T(T_from_tum(rows))
    sign = np.sign(rows[:, 6:7])  # tum_from_T writes qw >= 0
    np.testing.assert_allclose(back[:, :3], rows[:, :3], atol=1e-15)
    np.testing.assert_allclose(back[:, 3:], sign * rows[:, 3:], atol=1e-14)
    # un-normalized (rounded) quaternions are accepted
    np.testing.assert_allclose(
        T_from_tum(np.concatenate([rows[0, :3], 2.0 * rows[0, 3:]])),
        T_from_tum(rows[0]),
        atol=1e-15,
    )
    with pytest.raises(ValueError):
        T_from_tum(np.zeros(8))


# --------------------------------------------------------------------------- interpolation


def test_interpolate_poses() -> None:
    rng = np.random.default_rng(7)
    times = np.cumsum(rng.uniform(0.02, 0.05, 20))
    T = random_T(rng, 20)
    np.testing.assert_allclose(interpolate_poses(times, T, times), T, atol=1e-14)
    query = rng.uniform(times[0], times[-1], 50)
    out = interpolate_poses(times, T, query)
    assert out.shape == (50, 4, 4)
    ref_R = Slerp(times, Rotation.from_matrix(T[:, :3, :3]))(query).as_matrix()
    np.testing.assert_allclose(out[:, :3, :3], ref_R, atol=1e-12)
    ref_t = np.stack([np.interp(query, times, T[:, k, 3]) for k in range(3)], axis=-1)
    np.testing.assert_allclose(out[:, :3, 3], ref_t, atol=1e-14)
    np.testing.assert_array_equal(out[:, 3], np.broadcast_to([0, 0, 0, 1.0], (50, 4)))
    with pytest.raises(ValueError):
        interpolate_poses(times, T, [times[-1] + 1.0])
    nan = interpolate_poses(times, T, [times[0] - 1.0, times[3]], out_of_range="nan")
    assert np.all(np.isnan(nan[0]))
    np.testing.assert_allclose(nan[1], T[3], atol=1e-14)
