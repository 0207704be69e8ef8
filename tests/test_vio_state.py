"""The filter state container and its covariance helper (gaitnet.vio.state / covariance)."""

from __future__ import annotations

import numpy as np
import pytest

from gaitnet.geometry import quat_boxminus, quat_from_rotvec
from gaitnet.vio.covariance import (
    augment_landmark,
    check_healthy,
    chi2_gate,
    clone,
    inflate_to_pass,
    marginalise_landmark,
    propagate,
    update,
)
from gaitnet.vio.errors import FilterDivergedError
from gaitnet.vio.measurement import (
    Augmentation,
    Measurement,
    stack_jacobian,
    stack_measurements,
)
from gaitnet.vio.state import FilterState, ImuState


def random_spd(rng: np.random.Generator, n: int, scale: float = 1.0) -> np.ndarray:
    A = rng.normal(size=(n, n))
    return scale * (A @ A.T / n + 0.1 * np.eye(n))


def random_state(rng: np.random.Generator, n_lm: int = 0, with_clone: bool = False) -> FilterState:
    imu = ImuState(
        q=quat_from_rotvec(rng.normal(size=3)),
        p_IinW=rng.normal(size=3),
        v_IinW=rng.normal(size=3),
        b_g=0.01 * rng.normal(size=3),
        b_a=0.1 * rng.normal(size=3),
        t_s=1.5,
    )
    state = FilterState.new(imu, random_spd(rng, 15))
    if with_clone:
        clone(state)
        state.imu.q = quat_from_rotvec(rng.normal(size=3))
        state.imu.p_IinW = rng.normal(size=3)
        state.P = random_spd(rng, state.dim)
    for k in range(n_lm):
        G = {"pos": rng.normal(size=(2, 3))}
        augment_landmark(state, 10 + k, Augmentation(rng.normal(size=2), G, 0.1 * np.eye(2), "lm"))
    state.P = random_spd(rng, state.dim)
    return state


def test_layout_and_index() -> None:
    state = random_state(np.random.default_rng(0), n_lm=2, with_clone=True)
    assert state.dim == 15 + 6 + 4
    assert state.index("vel") == slice(6, 9)
    assert state.index("clone_pos") == slice(18, 21)
    assert state.index(("lm", 10)) == slice(21, 23)
    assert state.index(("lm", 11)) == slice(23, 25)
    with pytest.raises(KeyError):
        state.index(("lm", 99))
    bare = random_state(np.random.default_rng(1))
    with pytest.raises(KeyError):
        bare.index("clone_att")


def test_boxplus_applies_attitude_on_the_right_and_the_rest_additively() -> None:
    rng = np.random.default_rng(2)
    state = random_state(rng, n_lm=1, with_clone=True)
    dx = 0.01 * rng.normal(size=state.dim)
    new = state.boxplus(dx)
    np.testing.assert_allclose(quat_boxminus(new.imu.q, state.imu.q), dx[0:3], atol=1e-14)
    np.testing.assert_allclose(new.imu.p_IinW - state.imu.p_IinW, dx[3:6], atol=1e-14)
    np.testing.assert_allclose(new.imu.b_a - state.imu.b_a, dx[12:15], atol=1e-14)
    np.testing.assert_allclose(quat_boxminus(new.clone.q, state.clone.q), dx[15:18], atol=1e-14)
    np.testing.assert_allclose(new.landmarks[10] - state.landmarks[10], dx[21:23], atol=1e-14)
    # R_WfromI ≈ R̂ (I + [dθ×]): a body-frame error.
    np.testing.assert_allclose(
        new.imu.R_WfromI, state.imu.R_WfromI @ (np.eye(3) + _skew(dx[0:3])), atol=1e-3
    )


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])


def test_update_equals_textbook_kalman_on_a_linear_problem() -> None:
    rng = np.random.default_rng(3)
    state = random_state(rng, n_lm=1, with_clone=True)
    n = state.dim
    H_pos = rng.normal(size=(4, 3))
    H_lm = rng.normal(size=(4, 2))
    H_vel = rng.normal(size=(4, 3))
    R = random_spd(rng, 4, 0.05)
    r = rng.normal(size=4)
    m = Measurement(r, {"pos": H_pos, ("lm", 10): H_lm, "vel": H_vel}, R, "toy")
    H = stack_jacobian(m, state)
    P = state.P.copy()
    K = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)
    dx = K @ r
    P_textbook = (np.eye(n) - K @ H) @ P
    before = state.copy()
    res = update(state, m)
    assert res.accepted and res.dof == 4
    np.testing.assert_allclose(res.chi2, r @ np.linalg.solve(H @ P @ H.T + R, r), rtol=1e-10)
    np.testing.assert_allclose(state.P, P_textbook, atol=1e-10)
    np.testing.assert_allclose(state.imu.p_IinW - before.imu.p_IinW, dx[3:6], atol=1e-12)
    np.testing.assert_allclose(state.imu.v_IinW - before.imu.v_IinW, dx[6:9], atol=1e-12)
    np.testing.assert_allclose(state.landmarks[10] - before.landmarks[10], dx[21:23], atol=1e-12)
    np.testing.assert_allclose(quat_boxminus(state.imu.q, before.imu.q), dx[0:3], atol=1e-12)
    np.testing.assert_allclose(quat_boxminus(state.clone.q, before.clone.q), dx[15:18], atol=1e-12)


def test_joseph_update_keeps_P_symmetric_psd_over_many_sharp_updates() -> None:
    rng = np.random.default_rng(4)
    state = random_state(rng, n_lm=2, with_clone=True)
    state.P *= 1e4  # large prior against very precise measurements: the classic failure case
    for _ in range(200):
        var = ["att", "pos", "vel", "clone_pos", ("lm", 11)][rng.integers(5)]
        w = 2 if isinstance(var, tuple) else 3
        m = Measurement(
            1e-3 * rng.normal(size=3), {var: rng.normal(size=(3, w))}, 1e-12 * np.eye(3), "sharp"
        )
        assert update(state, m).accepted
        np.testing.assert_array_equal(state.P, state.P.T)
        assert np.linalg.eigvalsh(state.P)[0] > -1e-9 * np.abs(state.P).max()
    check_healthy(state)


def test_chi2_gate_rejects_an_outlier_and_leaves_the_state_alone() -> None:
    rng = np.random.default_rng(5)
    state = random_state(rng)
    m = Measurement(np.array([100.0, 0, 0]), {"pos": np.eye(3)}, 0.01 * np.eye(3), "out")
    before = state.copy()
    res = update(state, m, gate_chi2=chi2_gate(3, 0.99))
    assert not res.accepted and "chi2" in res.reason and res.chi2 > chi2_gate(3, 0.99)
    np.testing.assert_array_equal(state.P, before.P)
    np.testing.assert_array_equal(state.imu.p_IinW, before.imu.p_IinW)
    inlier = Measurement(np.array([0.01, 0, 0]), {"pos": np.eye(3)}, 0.01 * np.eye(3), "in")
    assert update(state, inlier, gate_chi2=chi2_gate(3, 0.99)).accepted
    nan = Measurement(np.array([np.nan, 0, 0]), {"pos": np.eye(3)}, 0.01 * np.eye(3), "nan")
    res = update(state, nan)
    assert not res.accepted and "non-finite" in res.reason


def test_propagate_transforms_imu_rows_and_keeps_the_rest() -> None:
    rng = np.random.default_rng(6)
    state = random_state(rng, n_lm=1, with_clone=True)
    Phi = np.eye(15) + 0.1 * rng.normal(size=(15, 15))
    Q = random_spd(rng, 15, 0.01)
    F = np.eye(state.dim)
    F[:15, :15] = Phi
    Qf = np.zeros((state.dim, state.dim))
    Qf[:15, :15] = Q
    expected = F @ state.P @ F.T + Qf
    propagate(state, Phi, Q)
    np.testing.assert_allclose(state.P, expected, atol=1e-12)


def test_clone_copies_the_pose_with_full_correlation() -> None:
    rng = np.random.default_rng(7)
    state = random_state(rng, n_lm=1)
    lm_block = state.P[15:17, 15:17].copy()
    lm_cross_pos = state.P[15:17, 3:6].copy()
    clone(state)
    assert state.dim == 15 + 6 + 2
    P = state.P
    np.testing.assert_array_equal(P[15:21, 15:21], P[0:6, 0:6])
    np.testing.assert_array_equal(P[15:21, :15], P[0:6, :15])
    np.testing.assert_array_equal(P[21:23, 21:23], lm_block)  # landmark moved down, intact
    np.testing.assert_array_equal(P[21:23, 18:21], lm_cross_pos)
    np.testing.assert_array_equal(state.clone.q, state.imu.q)
    # Clone again after the pose moved: the clone rows follow the new pose rows.
    propagate(state, np.eye(15) + 0.05 * rng.normal(size=(15, 15)), random_spd(rng, 15, 0.1))
    clone(state)
    assert state.dim == 23
    np.testing.assert_array_equal(state.P[15:21, :15], state.P[0:6, :15])
    np.testing.assert_array_equal(state.P[15:21, 15:21], state.P[0:6, 0:6])
    check_healthy(state)


def test_relative_measurement_through_the_clone_constrains_only_the_relative_motion() -> None:
    rng = np.random.default_rng(8)
    state = random_state(rng)
    clone(state)
    Phi = np.eye(15)
    Phi[3:6, 6:9] = 0.1 * np.eye(3)  # p += v dt
    propagate(state, Phi, np.diag(np.r_[np.zeros(3), 1e-2 * np.ones(3), np.zeros(9)]))
    var_abs = np.diag(state.P)[3:6].copy()
    m = Measurement(
        np.zeros(3), {"pos": np.eye(3), "clone_pos": -np.eye(3)}, 1e-8 * np.eye(3), "rel"
    )
    assert update(state, m).accepted
    D = np.zeros((3, state.dim))
    D[:, 3:6] = np.eye(3)
    D[:, 18:21] = -np.eye(3)
    var_rel = np.diag(D @ state.P @ D.T)
    assert np.all(var_rel < 2e-8)
    assert np.all(np.diag(state.P)[3:6] > 0.3 * var_abs)  # absolute position still uncertain


def test_augment_matches_the_joint_gaussian_and_marginalise_round_trips() -> None:
    rng = np.random.default_rng(9)
    state = random_state(rng, n_lm=1, with_clone=True)
    P0 = state.P.copy()
    n = state.dim
    G = {"att": rng.normal(size=(2, 3)), "clone_pos": rng.normal(size=(2, 3))}
    R = random_spd(rng, 2, 0.01)
    aug = Augmentation(np.array([1.0, 2.0]), G, R, "new")
    augment_landmark(state, 42, aug)
    Gfull = np.zeros((2, n))
    Gfull[:, 0:3] = G["att"]
    Gfull[:, 18:21] = G["clone_pos"]
    np.testing.assert_allclose(state.P[:n, :n], P0)
    np.testing.assert_allclose(state.P[n:, :n], Gfull @ P0, atol=1e-12)
    np.testing.assert_allclose(state.P[n:, n:], Gfull @ P0 @ Gfull.T + R, atol=1e-12)
    assert state.index(("lm", 42)) == slice(n, n + 2)
    with pytest.raises(ValueError):
        augment_landmark(state, 42, aug)
    marginalise_landmark(state, 42)
    np.testing.assert_array_equal(state.P, P0)
    assert list(state.landmarks) == [10]
    # Marginalising an older landmark keeps the newer one's block and its cross terms.
    augment_landmark(state, 43, aug)
    block43 = state.P[n:, n:].copy()
    cross43 = state.P[n:, :21].copy()
    marginalise_landmark(state, 10)
    assert list(state.landmarks) == [43]
    sl = state.index(("lm", 43))
    np.testing.assert_array_equal(state.P[sl, sl], block43)
    np.testing.assert_array_equal(state.P[sl, :21], cross43)
    check_healthy(state)


def test_stack_measurements_is_block_diagonal() -> None:
    rng = np.random.default_rng(10)
    state = random_state(rng)
    a = Measurement(rng.normal(size=3), {"pos": rng.normal(size=(3, 3))}, np.eye(3), "a")
    b = Measurement(rng.normal(size=2), {"vel": rng.normal(size=(2, 3))}, 2 * np.eye(2), "b")
    ab = stack_measurements([a, b], "ab")
    H = stack_jacobian(ab, state)
    np.testing.assert_array_equal(H[:3], stack_jacobian(a, state))
    np.testing.assert_array_equal(H[3:], stack_jacobian(b, state))
    np.testing.assert_array_equal(ab.R[3:, 3:], 2 * np.eye(2))
    assert ab.R[0, 3] == 0.0
    with pytest.raises(ValueError):
        stack_jacobian(Measurement(np.zeros(3), {"pos": np.eye(2)}, np.eye(3), "bad"), state)


def test_check_healthy_names_what_failed() -> None:
    rng = np.random.default_rng(11)
    state = random_state(rng, n_lm=1, with_clone=True)
    check_healthy(state)
    s = state.copy()
    s.imu.v_IinW[1] = np.nan
    with pytest.raises(FilterDivergedError, match="velocity"):
        check_healthy(s)
    s = state.copy()
    s.P[22, 5] = s.P[5, 22] = np.inf
    with pytest.raises(FilterDivergedError, match="non-finite covariance"):
        check_healthy(s)
    s = state.copy()
    s.P[7, 7] = -1.0
    with pytest.raises(FilterDivergedError, match="vel"):
        check_healthy(s)
    s = state.copy()
    w, V = np.linalg.eigh(s.P)
    w[0] = -0.5 * w[-1]
    s.P = (V * w) @ V.T
    s.P = 0.5 * (s.P + s.P.T)
    with pytest.raises(FilterDivergedError, match="positive semi-definite"):
        check_healthy(s)
    s = state.copy()
    s.P[0, 1] += 1.0
    with pytest.raises(FilterDivergedError, match="symmetric"):
        check_healthy(s)


@pytest.mark.parametrize("dof", [1, 2, 3, 6, 9])
@pytest.mark.parametrize("probability", [0.9, 0.99, 0.999])
def test_chi2_gate_equals_the_chi2_quantile(dof: int, probability: float) -> None:
    from scipy.stats import chi2

    assert chi2_gate(dof, probability) == pytest.approx(chi2.ppf(probability, dof), rel=1e-10)


def test_inflate_to_pass_known_answer_and_only_the_navigation_block() -> None:
    # P_pp = σ² I (uncorrelated), R = ρ² I: rᵀS⁻¹r = |r|² / (f σ² + ρ²), so the target χ² is
    # reached at f = (|r|² / target − ρ²) / σ²
    rng = np.random.default_rng(3)
    state = random_state(rng, n_lm=1, with_clone=True)
    sigma2, rho2 = 1e-4, 1e-4
    state.P[3:6, :] = 0.0
    state.P[:, 3:6] = 0.0
    state.P[3:6, 3:6] = sigma2 * np.eye(3)
    r = np.array([0.3, -0.1, 0.2])
    m = Measurement(r, {"pos": np.eye(3)}, rho2 * np.eye(3), "sheet")
    target = 0.5 * chi2_gate(3, 0.99999)
    before = state.P.copy()
    f = inflate_to_pass(state, m, target)
    assert f == pytest.approx((r @ r / target - rho2) / sigma2, rel=1e-3)
    np.testing.assert_allclose(state.P[:9, :9], f * before[:9, :9], rtol=1e-12)
    np.testing.assert_array_equal(state.P[9:, :], before[9:, :])  # biases, clone, landmark
    np.testing.assert_array_equal(state.P[:9, 9:], before[:9, 9:])
    assert np.linalg.eigvalsh(state.P).min() > 0
    assert update(state, m, gate_chi2=chi2_gate(3, 0.99999)).accepted
    # a measurement that already passes changes nothing
    again = state.P.copy()
    small = Measurement(np.array([1e-4, 0, 0]), {"pos": np.eye(3)}, rho2 * np.eye(3), "in")
    assert inflate_to_pass(state, small, target) == 1.0
    np.testing.assert_array_equal(state.P, again)


def test_inflate_to_pass_leaves_P_alone_when_no_factor_reaches_the_target() -> None:
    rng = np.random.default_rng(4)
    state = random_state(rng)
    state.P[3:6, :] = 0.0
    state.P[:, 3:6] = 0.0
    state.P[3:6, 3:6] = 1e-12 * np.eye(3)  # a position the filter is sure of
    m = Measurement(np.array([5.0, 0, 0]), {"pos": np.eye(3)}, 1e-8 * np.eye(3), "far")
    before = state.P.copy()
    assert inflate_to_pass(state, m, 1.0, max_factor=10.0) == np.inf
    np.testing.assert_array_equal(state.P, before)
