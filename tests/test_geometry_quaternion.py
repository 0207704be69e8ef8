"""Quaternion conventions, conversions, error-state model and interpolation.

scipy's ``Rotation`` is the independent reference: its ``as_quat`` is scalar-last
``[x, y, z, w]`` and ``as_matrix`` is the active (body-to-world) ``R``.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

from gaitnet.geometry import (
    axis_angle_from_quat,
    dcm_from_quat,
    f_quat,
    quat_boxminus,
    quat_boxplus,
    quat_conjugate,
    quat_from_axis_angle,
    quat_from_dcm,
    quat_from_rotmat,
    quat_from_rotvec,
    quat_identity,
    quat_interpolate,
    quat_inverse,
    quat_make_continuous,
    quat_multiply,
    quat_normalize,
    quat_positive,
    quat_slerp,
    quat_wxyz_from_xyzw,
    quat_xyzw_from_wxyz,
    rotate_body_to_world,
    rotate_world_to_body,
    rotmat_from_quat,
    rotvec_from_quat,
    skew,
)


def random_quats(rng: np.random.Generator, n: int) -> np.ndarray:
    q = rng.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def scipy_rot(q_wxyz: np.ndarray) -> Rotation:
    """scipy Rotation from our [w, x, y, z] (reordered by hand, not with our helper)."""
    return Rotation.from_quat(np.asarray(q_wxyz)[..., [1, 2, 3, 0]])


def same_rotation(p: np.ndarray, q: np.ndarray, atol: float = 1e-12) -> bool:
    """True where p == ±q (quaternion double cover)."""
    return bool(np.all(np.minimum(np.abs(p - q).max(-1), np.abs(p + q).max(-1)) <= atol))


# --------------------------------------------------------------------------- matrices


def test_rotmat_from_quat_matches_scipy_active_matrix() -> None:
    q = random_quats(np.random.default_rng(0), 200)
    np.testing.assert_allclose(rotmat_from_quat(q), scipy_rot(q).as_matrix(), atol=1e-14)


def test_dcm_is_transpose_of_rotmat_and_maps_world_to_body() -> None:
    rng = np.random.default_rng(1)
    q = random_quats(rng, 50)
    R = scipy_rot(q).as_matrix()
    np.testing.assert_allclose(dcm_from_quat(q), np.swapaxes(R, -1, -2), atol=1e-14)
    v_W = rng.normal(size=(50, 3))
    # v_B = C v_W undoes v_W = R v_B
    np.testing.assert_allclose(rotate_world_to_body(q, v_W), scipy_rot(q).inv().apply(v_W))
    np.testing.assert_allclose(rotate_body_to_world(q, v_W), scipy_rot(q).apply(v_W))


def test_known_rotation_about_z() -> None:
    # +90° about z: R maps the body x axis to world y; C maps world x to body -y.
    q = quat_from_axis_angle([0.0, 0.0, 1.0], np.pi / 2)
    np.testing.assert_allclose(q, [np.sqrt(0.5), 0.0, 0.0, np.sqrt(0.5)], atol=1e-15)
    np.testing.assert_allclose(rotmat_from_quat(q) @ [1.0, 0, 0], [0.0, 1.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(dcm_from_quat(q) @ [1.0, 0, 0], [0.0, -1.0, 0.0], atol=1e-15)


def test_rotmat_normalizes_input_quaternion() -> None:
    q = random_quats(np.random.default_rng(2), 10)
    np.testing.assert_allclose(rotmat_from_quat(3.7 * q), rotmat_from_quat(q), atol=1e-14)


def test_quat_from_rotmat_inverts_rotmat_with_nonnegative_w() -> None:
    q = random_quats(np.random.default_rng(3), 500)
    q_back = quat_from_rotmat(rotmat_from_quat(q))
    assert np.all(q_back[:, 0] >= 0.0)
    np.testing.assert_allclose(q_back, quat_positive(q), atol=1e-14)
    # scipy's canonical quaternion also has w >= 0
    ref = scipy_rot(q).as_quat(canonical=True)[:, [3, 0, 1, 2]]
    np.testing.assert_allclose(q_back, ref, atol=1e-14)


@pytest.mark.parametrize("axis", [[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, -2, 0.5], [-1, 1, 1]])
@pytest.mark.parametrize("angle", [np.pi, np.pi - 1e-9, np.pi - 1e-5, 1e-9, 0.0, 1.0])
def test_quat_from_rotmat_is_accurate_at_hard_angles(axis: list[float], angle: float) -> None:
    R = Rotation.from_rotvec(np.asarray(axis) / np.linalg.norm(axis) * angle).as_matrix()
    q = quat_from_rotmat(R)
    assert q[0] >= 0.0
    assert abs(np.linalg.norm(q) - 1.0) < 1e-15
    np.testing.assert_allclose(rotmat_from_quat(q), R, atol=2e-15)


def test_quat_from_dcm_inverts_dcm() -> None:
    q = quat_positive(random_quats(np.random.default_rng(4), 20))
    np.testing.assert_allclose(quat_from_dcm(dcm_from_quat(q)), q, atol=1e-14)


def test_batched_shapes() -> None:
    rng = np.random.default_rng(5)
    q = random_quats(rng, 24).reshape(2, 3, 4, 4)
    R = rotmat_from_quat(q)
    assert R.shape == (2, 3, 4, 3, 3)
    assert quat_from_rotmat(R).shape == (2, 3, 4, 4)
    assert quat_multiply(q, q[0, 0, 0]).shape == (2, 3, 4, 4)
    assert rotvec_from_quat(q).shape == (2, 3, 4, 3)
    np.testing.assert_allclose(R[1, 2, 3], rotmat_from_quat(q[1, 2, 3]))


def test_bad_shapes_raise() -> None:
    with pytest.raises(ValueError):
        rotmat_from_quat(np.zeros(3))
    with pytest.raises(ValueError):
        quat_from_rotmat(np.eye(4))
    with pytest.raises(ValueError):
        quat_normalize(np.zeros(4))
    # missing data (NaN) propagates instead of raising, batch entries stay independent
    q = np.array([[np.nan, 0, 0, 0], [0.0, 0, 0, 2]])
    R = rotmat_from_quat(q)
    assert np.all(np.isnan(R[0]))
    np.testing.assert_allclose(R[1], np.diag([-1.0, -1.0, 1.0]))


# --------------------------------------------------------------------------- algebra


def test_hamilton_product_basis_elements() -> None:
    one, i, j, k = np.eye(4)
    np.testing.assert_array_equal(quat_multiply(i, j), k)
    np.testing.assert_array_equal(quat_multiply(j, k), i)
    np.testing.assert_array_equal(quat_multiply(k, i), j)
    np.testing.assert_array_equal(quat_multiply(i, i), -one)
    np.testing.assert_array_equal(quat_multiply(j, i), -k)


def test_composition_identities() -> None:
    rng = np.random.default_rng(6)
    p, q = random_quats(rng, 100), random_quats(rng, 100)
    pq = quat_multiply(p, q)
    # C(p ⊗ q) = C(q) C(p)   and   R(p ⊗ q) = R(p) R(q)
    np.testing.assert_allclose(dcm_from_quat(pq), dcm_from_quat(q) @ dcm_from_quat(p), atol=1e-14)
    np.testing.assert_allclose(
        rotmat_from_quat(pq), rotmat_from_quat(p) @ rotmat_from_quat(q), atol=1e-14
    )
    # scipy: (r1 * r2).as_matrix() == r1.as_matrix() @ r2.as_matrix()
    ref = (scipy_rot(p) * scipy_rot(q)).as_quat()[:, [3, 0, 1, 2]]
    assert same_rotation(pq, ref, atol=1e-14)


def test_conjugate_inverse_and_double_cover() -> None:
    rng = np.random.default_rng(7)
    q = random_quats(rng, 50)
    np.testing.assert_allclose(
        quat_multiply(q, quat_conjugate(q)), quat_identity((50,)), atol=1e-15
    )
    np.testing.assert_allclose(
        quat_multiply(quat_conjugate(q), q), quat_identity((50,)), atol=1e-15
    )
    np.testing.assert_allclose(rotmat_from_quat(-q), rotmat_from_quat(q), atol=0.0)
    np.testing.assert_allclose(
        rotmat_from_quat(quat_conjugate(q)), np.swapaxes(rotmat_from_quat(q), -1, -2), atol=1e-15
    )
    s = 2.5 * q
    np.testing.assert_allclose(quat_multiply(s, quat_inverse(s)), quat_identity((50,)), atol=1e-14)
    np.testing.assert_allclose(np.linalg.norm(quat_normalize(s), axis=-1), 1.0)


def test_quat_positive_and_reordering() -> None:
    q = random_quats(np.random.default_rng(8), 30)
    pos = quat_positive(q)
    assert np.all(pos[:, 0] >= 0)
    assert same_rotation(pos, q, atol=0.0)
    xyzw = quat_xyzw_from_wxyz(q)
    np.testing.assert_array_equal(xyzw, q[:, [1, 2, 3, 0]])
    np.testing.assert_array_equal(quat_wxyz_from_xyzw(xyzw), q)


def test_quat_make_continuous() -> None:
    rng = np.random.default_rng(9)
    # a smooth trajectory with random sign flips
    q = quat_from_rotvec(np.linspace(0, 1, 40)[:, None] * np.array([0.5, 2.0, -1.0]))
    signs = rng.choice([-1.0, 1.0], size=40)
    flipped = q * signs[:, None]
    assert np.any(np.sum(flipped[1:] * flipped[:-1], axis=-1) < 0)  # test is not vacuous
    cont = quat_make_continuous(flipped)
    assert np.all(np.sum(cont[1:] * cont[:-1], axis=-1) > 0)
    assert same_rotation(cont, q, atol=0.0)
    np.testing.assert_array_equal(cont[0], flipped[0])


# --------------------------------------------------------------------------- axis-angle


def test_rotvec_conversions_match_scipy() -> None:
    rng = np.random.default_rng(10)
    axes = rng.normal(size=(300, 3))
    axes /= np.linalg.norm(axes, axis=-1, keepdims=True)
    angles = np.concatenate([rng.uniform(0, np.pi, 280), [1e-12, 1e-9, 1e-6, np.pi - 1e-9] * 5])
    phi = axes * angles[:, None]
    q = quat_from_rotvec(phi)
    ref_q = Rotation.from_rotvec(phi).as_quat()[:, [3, 0, 1, 2]]
    assert same_rotation(q, ref_q, atol=1e-15)
    back = rotvec_from_quat(q)
    np.testing.assert_allclose(back, phi, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(back, Rotation.from_rotvec(phi).as_rotvec(), atol=2e-15)
    # the sign of q does not matter
    np.testing.assert_allclose(rotvec_from_quat(-q), back, atol=1e-15)


def test_rotvec_at_zero_is_exact() -> None:
    np.testing.assert_array_equal(quat_from_rotvec(np.zeros(3)), [1.0, 0, 0, 0])
    np.testing.assert_array_equal(rotvec_from_quat([1.0, 0, 0, 0]), np.zeros(3))
    phi = np.array([1e-13, -2e-13, 3e-13])
    np.testing.assert_allclose(rotvec_from_quat(quat_from_rotvec(phi)), phi, rtol=1e-14)


def test_axis_angle_round_trip() -> None:
    rng = np.random.default_rng(11)
    axis = rng.normal(size=(40, 3))
    angle = rng.uniform(0.0, np.pi, 40)
    q = quat_from_axis_angle(axis * 3.0, angle)  # axis need not be unit
    ref = Rotation.from_rotvec(axis / np.linalg.norm(axis, axis=-1, keepdims=True) * angle[:, None])
    np.testing.assert_allclose(rotmat_from_quat(q), ref.as_matrix(), atol=1e-14)
    a_back, ang_back = axis_angle_from_quat(q)
    np.testing.assert_allclose(ang_back, angle, atol=1e-14)
    np.testing.assert_allclose(a_back, axis / np.linalg.norm(axis, axis=-1, keepdims=True))
    a0, ang0 = axis_angle_from_quat(quat_identity())
    np.testing.assert_array_equal(a0, [1.0, 0.0, 0.0])
    assert ang0 == 0.0
    # negative angle is the same as the flipped axis
    q_neg = quat_from_axis_angle([0, 0, 1.0], -0.4)
    assert same_rotation(q_neg, quat_from_axis_angle([0, 0, -1.0], 0.4), atol=1e-15)
    # one axis, many angles
    assert quat_from_axis_angle([1.0, 0, 0], np.linspace(0, 1, 7)).shape == (7, 4)
    with pytest.raises(ValueError):
        quat_from_axis_angle(np.zeros(3), 1.0)


# --------------------------------------------------------------------------- error state


def test_small_error_model_is_second_order_accurate() -> None:
    """C(q̂ ⊗ [1; e]) = (I - 2[e×]) C(q̂) + O(|e|²) (thesis eq. (3.1))."""
    rng = np.random.default_rng(12)
    q_hat = random_quats(rng, 20)
    direction = rng.normal(size=(20, 3))
    direction /= np.linalg.norm(direction, axis=-1, keepdims=True)
    for form in ("first", "exact"):
        errs = []
        for scale in (1e-2, 1e-3, 1e-4):
            e = scale * direction
            dq = f_quat(e, first_order=form == "first")
            q = quat_multiply(q_hat, dq)
            approx = (np.eye(3) - 2.0 * skew(e)) @ dcm_from_quat(q_hat)
            errs.append(np.abs(dcm_from_quat(q) - approx).max())
        # quadratic: 10x smaller error vector → ~100x smaller residual
        assert errs[0] < 1e-3
        assert 60.0 < errs[0] / errs[1] < 160.0, errs
        assert 60.0 < errs[1] / errs[2] < 160.0, errs
    # and the error is on the body side: R(q) ≈ R(q̂)(I + 2[e×]), not (I + 2[e×]) R(q̂)
    e = 1e-4 * direction
    q = quat_multiply(q_hat, f_quat(e))
    wrong_side = (np.eye(3) + 2.0 * skew(e)) @ rotmat_from_quat(q_hat)
    right_side = rotmat_from_quat(q_hat) @ (np.eye(3) + 2.0 * skew(e))
    assert np.abs(rotmat_from_quat(q) - right_side).max() < 1e-7
    assert np.abs(rotmat_from_quat(q) - wrong_side).max() > 1e-5


def test_f_quat_forms() -> None:
    e = np.array([0.1, -0.2, 0.3])
    np.testing.assert_allclose(f_quat(e), [np.sqrt(1 - 0.14), 0.1, -0.2, 0.3])
    np.testing.assert_array_equal(f_quat(e, first_order=True), [1.0, 0.1, -0.2, 0.3])
    big = np.array([[2.0, 0.0, 0.0], [0.6, 0.6, 0.6]])  # |e| > 1: normalized fallback
    out = f_quat(big)
    np.testing.assert_allclose(np.linalg.norm(out, axis=-1), 1.0)
    np.testing.assert_allclose(out[0], np.array([1.0, 2.0, 0, 0]) / np.sqrt(5.0))
    assert np.all(np.isfinite(out))


@pytest.mark.parametrize("chart", ["fquat", "exp"])
def test_boxplus_boxminus_round_trip(chart: str) -> None:
    rng = np.random.default_rng(13)
    q_hat = random_quats(rng, 100)
    dtheta = rng.normal(size=(100, 3))
    dtheta *= rng.uniform(0.0, 1.5, size=(100, 1)) / np.linalg.norm(dtheta, axis=-1, keepdims=True)
    q = quat_boxplus(q_hat, dtheta, chart=chart)
    np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1.0)
    np.testing.assert_allclose(quat_boxminus(q, q_hat, chart=chart), dtheta, atol=1e-13)
    np.testing.assert_allclose(quat_boxminus(-q, q_hat, chart=chart), dtheta, atol=1e-13)
    # boxminus then boxplus reaches q from any q_hat
    q_other = random_quats(rng, 100)
    d = quat_boxminus(q_other, q_hat, chart=chart)
    assert same_rotation(quat_boxplus(q_hat, d, chart=chart), q_other, atol=1e-12)


def test_boxplus_definitions() -> None:
    rng = np.random.default_rng(14)
    q_hat = random_quats(rng, 30)
    d = 0.3 * rng.normal(size=(30, 3))
    # fquat chart is literally thesis eq. (3.1) with q̄_e = dθ/2
    np.testing.assert_allclose(
        quat_boxplus(q_hat, d, chart="fquat"), quat_multiply(q_hat, f_quat(d / 2)), atol=1e-15
    )
    # exp chart: R(q) = R(q̂) Exp(dθ) (scipy composition, right = body side)
    ref = (scipy_rot(q_hat) * Rotation.from_rotvec(d)).as_matrix()
    np.testing.assert_allclose(
        rotmat_from_quat(quat_boxplus(q_hat, d, chart="exp")), ref, atol=1e-14
    )
    with pytest.raises(ValueError):
        quat_boxplus(q_hat, d, chart="nope")  # type: ignore[arg-type]
    with pytest.raises(ValueError):
        quat_boxminus(q_hat, q_hat, chart="nope")  # type: ignore[arg-type]


def test_boxplus_charts_agree_to_third_order() -> None:
    rng = np.random.default_rng(15)
    q_hat = random_quats(rng, 10)
    direction = rng.normal(size=(10, 3))
    direction /= np.linalg.norm(direction, axis=-1, keepdims=True)
    diffs = []
    for scale in (1e-1, 1e-2):
        d = scale * direction
        q = quat_boxplus(q_hat, d, chart="fquat")
        diffs.append(np.abs(quat_boxminus(q, q_hat, chart="exp") - d).max())
        # first order: C(q) ≈ (I - [dθ×]) C(q̂)
        approx = (np.eye(3) - skew(d)) @ dcm_from_quat(q_hat)
        assert np.abs(dcm_from_quat(q) - approx).max() < 2 * scale**2
    assert 500.0 < diffs[0] / diffs[1] < 2000.0, diffs


# --------------------------------------------------------------------------- interpolation


def test_slerp_endpoints_midpoint_and_constant_speed() -> None:
    q0 = quat_from_axis_angle([0, 0, 1.0], 0.2)
    q1 = quat_from_axis_angle([0, 0, 1.0], 1.4)
    np.testing.assert_allclose(quat_slerp(q0, q1, 0.0), q0, atol=1e-15)
    np.testing.assert_allclose(quat_slerp(q0, q1, 1.0), q1, atol=1e-15)
    t = np.linspace(0.0, 1.0, 11)
    q_t = quat_slerp(q0, q1, t)
    assert q_t.shape == (11, 4)
    _, ang = axis_angle_from_quat(q_t)
    np.testing.assert_allclose(ang, 0.2 + 1.2 * t, atol=1e-14)
    # shortest arc: flipping q1's sign changes nothing
    np.testing.assert_allclose(quat_slerp(q0, -q1, t), q_t, atol=1e-15)


def test_slerp_matches_scipy() -> None:
    rng = np.random.default_rng(16)
    q0, q1 = random_quats(rng, 50), random_quats(rng, 50)
    t = rng.uniform(0, 1, 50)
    ours = quat_slerp(q0, q1, t)
    ref = [
        Slerp([0.0, 1.0], scipy_rot(np.stack([a, b])))(ti).as_quat()[[3, 0, 1, 2]]
        for a, b, ti in zip(q0, q1, t, strict=True)
    ]
    assert same_rotation(ours, np.array(ref), atol=1e-13)


def test_quat_interpolate_at_timestamps() -> None:
    rng = np.random.default_rng(17)
    times = np.cumsum(rng.uniform(0.01, 0.1, 30))
    quats = random_quats(rng, 30)
    query = rng.uniform(times[0], times[-1], 100)
    ours = quat_interpolate(times, quats, query)
    ref = Slerp(times, scipy_rot(quats))(query).as_quat()[:, [3, 0, 1, 2]]
    assert same_rotation(ours, ref, atol=1e-12)
    # exactly at samples (including the last) returns the samples
    assert same_rotation(quat_interpolate(times, quats, times), quats, atol=1e-14)
    assert quat_interpolate(times, quats, query.reshape(10, 10)).shape == (10, 10, 4)


def test_quat_interpolate_out_of_range_and_bad_times() -> None:
    times = np.array([0.0, 1.0, 2.0])
    quats = quat_from_axis_angle([0, 1.0, 0], [0.0, 0.5, 1.0])
    with pytest.raises(ValueError, match="outside"):
        quat_interpolate(times, quats, [-0.1, 1.0])
    clamped = quat_interpolate(times, quats, [-5.0, 7.0], out_of_range="clamp")
    np.testing.assert_allclose(clamped, quats[[0, 2]], atol=1e-15)
    nan = quat_interpolate(times, quats, [-5.0, 1.5], out_of_range="nan")
    assert np.all(np.isnan(nan[0]))
    np.testing.assert_allclose(nan[1], quat_from_axis_angle([0, 1.0, 0], 0.75), atol=1e-15)
    with pytest.raises(ValueError, match="increasing"):
        quat_interpolate(np.array([0.0, 1.0, 1.0]), quats, [0.5])
    with pytest.raises(ValueError):
        quat_interpolate(times[:2], quats, [0.5])
    # a single sample can be "interpolated" at its own time only
    np.testing.assert_allclose(quat_interpolate([3.0], quats[1:2], [3.0]), quats[1:2])
    with pytest.raises(ValueError):
        quat_interpolate([3.0], quats[1:2], [3.5])


def test_single_quaternion_and_matrix_fast_paths_match_the_batched_formulas() -> None:
    """One quaternion / one matrix take a Python-float path; it must give the batched result,
    refuse a zero quaternion the same way and pass NaN on."""
    rng = np.random.default_rng(23)
    quats = [*rng.normal(size=(300, 4)), np.array([1.0, 0, 0, 0]), np.array([0.0, 1, 0, 0])]
    quats += [np.array([1e-9, 0.6, 0.0, 0.8]), np.array([-0.5, 0.5, -0.5, 0.5]) * 3.0]
    for q in quats:  # the same operations in the same order: the same bits
        R = rotmat_from_quat(q)
        np.testing.assert_array_equal(R, rotmat_from_quat(q[None])[0])
        np.testing.assert_array_equal(quat_from_rotmat(R), quat_from_rotmat(R[None])[0])
    # pivot ties: a 120° turn about (1, 1, 1) permutes the axes (all four pivots equal), ±0.0
    for R in (np.array([[0.0, 0, 1], [1, 0, 0], [0, 1, 0]]), np.diag([1.0, -1.0, -1.0]) * -0.0):
        np.testing.assert_array_equal(quat_from_rotmat(R), quat_from_rotmat(R[None])[0])
    with pytest.raises(ValueError, match="zero quaternion"):
        rotmat_from_quat(np.zeros(4))
    with np.errstate(invalid="ignore"):
        assert np.isnan(rotmat_from_quat(np.array([np.nan, 0.0, 0.0, 1.0]))).all()
        assert np.isnan(quat_from_rotmat(np.full((3, 3), np.nan))).all()
