"""Measurement models of the filter (VO, AprilTag, stance foot): conventions, and every
Jacobian against float64 central differences through the error-state boxplus."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from gaitnet.geometry import (
    invert_T,
    make_T,
    quat_boxminus,
    quat_from_rotmat,
    rotmat_from_quat,
    so3_exp,
    so3_log,
    transform_points,
)
from gaitnet.vio.covariance import augment_landmark, clone, update
from gaitnet.vio.foot_model import (
    foot_measurement,
    foot_predict,
    landmark_from_observation,
    landmark_xy,
)
from gaitnet.vio.measurement import Measurement, stack_jacobian
from gaitnet.vio.state import FilterState, ImuState, PoseClone
from gaitnet.vio.tag_model import (
    imu_pose_from_camera_pose,
    tag_corners_in_camera,
    tag_measurement,
    tag_pose_covariance,
)
from gaitnet.vio.vo_model import vo_measurement, vo_predict

SEEDS = [0, 1, 2, 3, 4]
EPS = 1e-6
K = np.array([[380.0, 0.0, 320.0], [0.0, 381.0, 240.0], [0.0, 0.0, 1.0]])


def random_T_CfromI(rng: np.random.Generator) -> np.ndarray:
    """A D455-like extrinsic: axes permuted and slightly misaligned, a few cm apart."""
    R_CI = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]]) @ so3_exp(
        0.05 * rng.normal(size=3)
    )
    return make_T(R_CI, 0.03 * rng.normal(size=3))


def camera_looking_down(rng: np.random.Generator, xy: np.ndarray) -> np.ndarray:
    """``T_WfromC`` about 1 m above the floor at ``xy``, looking down and forward."""
    R_down = np.array([[0.0, -1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
    R = so3_exp(np.array([0.0, 0.0, rng.uniform(-np.pi, np.pi)])) @ R_down
    R = R @ so3_exp(0.3 * rng.normal(size=3))
    return make_T(R, np.array([xy[0], xy[1], 1.0 + 0.1 * rng.normal()]))


def random_state(rng: np.random.Generator, T_CfromI: np.ndarray) -> FilterState:
    """Current pose, a clone 1/30 s earlier, two landmarks in view, random P."""
    T_WfromC = camera_looking_down(rng, rng.normal(size=2))
    q, p = imu_pose_from_camera_pose(T_WfromC, T_CfromI)
    imu = ImuState(
        q, p, rng.normal(size=3), 0.01 * rng.normal(size=3), 0.1 * rng.normal(size=3), 2.0
    )
    A = rng.normal(size=(15, 15))
    state = FilterState.new(imu, A @ A.T / 15 + 1e-3 * np.eye(15))
    state.clone = PoseClone(
        quat_from_rotmat(rotmat_from_quat(q) @ so3_exp(0.05 * rng.normal(size=3))),
        p - np.array([0.04, 0.0, 0.0]) + 0.01 * rng.normal(size=3),
        1.97,
    )
    state.P = np.eye(21) * 1e-3
    for lm_id in (3, 7):
        state.landmarks[lm_id] = T_WfromC[:2, 3] + 0.3 * rng.normal(size=2)
        state.P = np.eye(state.dim) * 1e-3
    return state


def fd_jacobian(
    state: FilterState,
    fun: Callable[[FilterState], object],
    minus: Callable[[object, object], np.ndarray],
) -> np.ndarray:
    """Central differences of ``fun`` through ``state ⊞ δx``, differences taken with ``minus``."""
    y0 = fun(state)
    cols = []
    for j in range(state.dim):
        e = np.zeros(state.dim)
        e[j] = EPS
        plus = minus(fun(state.boxplus(e)), y0)
        minus_ = minus(fun(state.boxplus(-e)), y0)
        cols.append((plus - minus_) / (2 * EPS))
    return np.stack(cols, axis=1)


def rel_err(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


def vec_minus(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.asarray(a) - np.asarray(b)


# ----------------------------------------------------------------------------- VO


def test_vo_prediction_is_the_relative_camera_motion() -> None:
    """(3.11), (3.12): p_Ck = R_vo p_Ck−1 + t_vo for any world point, from the camera poses."""
    rng = np.random.default_rng(20)
    T_CfromI = random_T_CfromI(rng)
    state = random_state(rng, T_CfromI)
    T_WfromIk = make_T(rotmat_from_quat(state.imu.q), state.imu.p_IinW)
    T_WfromIj = make_T(rotmat_from_quat(state.clone.q), state.clone.p_IinW)
    T_WfromCk = T_WfromIk @ invert_T(T_CfromI)
    T_WfromCj = T_WfromIj @ invert_T(T_CfromI)
    X = rng.normal(size=(5, 3))
    p_Ck = transform_points(invert_T(T_WfromCk), X)
    p_Cj = transform_points(invert_T(T_WfromCj), X)
    R_vo, t_vo = vo_predict(
        state.imu.q, state.imu.p_IinW, state.clone.q, state.clone.p_IinW, T_CfromI
    )
    np.testing.assert_allclose(p_Cj @ R_vo.T + t_vo, p_Ck, atol=1e-12)


@pytest.mark.parametrize("seed", SEEDS)
def test_vo_jacobian_equals_central_differences(seed: int) -> None:
    rng = np.random.default_rng(100 + seed)
    T_CfromI = random_T_CfromI(rng)
    state = random_state(rng, T_CfromI)
    # A measurement that is not the prediction, so the residual is not zero.
    R_pred, t_pred = vo_predict(
        state.imu.q, state.imu.p_IinW, state.clone.q, state.clone.p_IinW, T_CfromI
    )
    R_meas = so3_exp(0.02 * rng.normal(size=3)) @ R_pred
    t_meas = t_pred + 0.01 * rng.normal(size=3)
    m = vo_measurement(state, T_CfromI, R_meas, t_meas, np.eye(6))

    def fun(s: FilterState) -> tuple[np.ndarray, np.ndarray]:
        return vo_predict(s.imu.q, s.imu.p_IinW, s.clone.q, s.clone.p_IinW, T_CfromI)

    def minus(a: tuple, b: tuple) -> np.ndarray:
        return np.concatenate([so3_log(a[0] @ b[0].T), a[1] - b[1]])

    H = stack_jacobian(m, state)
    H_fd = fd_jacobian(state, fun, minus)
    assert rel_err(H[:3], H_fd[:3]) < 1e-5  # attitude rows
    assert rel_err(H[3:], H_fd[3:]) < 1e-5  # translation rows
    np.testing.assert_allclose(m.residual, minus((R_meas, t_meas), fun(state)), atol=1e-15)


def test_vo_update_pulls_the_relative_pose_to_the_measurement() -> None:
    rng = np.random.default_rng(21)
    T_CfromI = random_T_CfromI(rng)
    truth = random_state(rng, T_CfromI)
    R_vo, t_vo = vo_predict(
        truth.imu.q, truth.imu.p_IinW, truth.clone.q, truth.clone.p_IinW, T_CfromI
    )
    est = truth.copy()
    est.imu.q = quat_from_rotmat(rotmat_from_quat(est.imu.q) @ so3_exp(np.array([0.0, 0.0, 0.02])))
    est.imu.p_IinW = est.imu.p_IinW + np.array([0.02, -0.01, 0.0])
    m = vo_measurement(est, T_CfromI, R_vo, t_vo, np.diag([1e-8] * 3 + [1e-8] * 3))
    before = np.abs(m.residual).max()
    assert update(est, m).accepted
    after = vo_measurement(est, T_CfromI, R_vo, t_vo, np.eye(6)).residual
    assert np.abs(after).max() < 0.05 * before


def test_vo_measurement_needs_a_clone() -> None:
    rng = np.random.default_rng(22)
    T_CfromI = random_T_CfromI(rng)
    state = random_state(rng, T_CfromI)
    state.clone = None
    state.landmarks = {}
    state.P = np.eye(15)
    with pytest.raises(ValueError, match="clone"):
        vo_measurement(state, T_CfromI, np.eye(3), np.zeros(3), np.eye(6))
    clone(state)
    m = vo_measurement(state, T_CfromI, np.eye(3), np.zeros(3), np.eye(6))
    np.testing.assert_allclose(m.residual, 0.0, atol=1e-12)  # no motion since the clone


# ----------------------------------------------------------------------------- foot


@pytest.mark.parametrize("seed", SEEDS)
def test_foot_jacobian_equals_central_differences(seed: int) -> None:
    rng = np.random.default_rng(200 + seed)
    T_CfromI = random_T_CfromI(rng)
    state = random_state(rng, T_CfromI)
    lm_id = 3 if seed % 2 else 7  # either landmark, not only the newest (thesis-notes, 3.48)
    pred = foot_predict(state.imu.q, state.imu.p_IinW, state.landmarks[lm_id], T_CfromI)
    z = pred + 0.01 * rng.normal(size=3)
    m = foot_measurement(state, T_CfromI, lm_id, z, 1e-4 * np.eye(3))

    def fun(s: FilterState) -> np.ndarray:
        return foot_predict(s.imu.q, s.imu.p_IinW, s.landmarks[lm_id], T_CfromI)

    H = stack_jacobian(m, state)
    H_fd = fd_jacobian(state, fun, vec_minus)
    assert rel_err(H, H_fd) < 1e-5
    other = state.index(("lm", 10 - lm_id))
    np.testing.assert_array_equal(H[:, other], 0.0)
    np.testing.assert_allclose(m.residual, z - pred, atol=1e-15)


def test_foot_prediction_is_the_floor_point_in_the_camera_frame() -> None:
    rng = np.random.default_rng(23)
    T_CfromI = random_T_CfromI(rng)
    state = random_state(rng, T_CfromI)
    T_WfromC = make_T(rotmat_from_quat(state.imu.q), state.imu.p_IinW) @ invert_T(T_CfromI)
    xy = state.landmarks[3]
    expected = transform_points(invert_T(T_WfromC), np.array([[xy[0], xy[1], 0.0]]))[0]
    p_FinC = foot_predict(state.imu.q, state.imu.p_IinW, xy, T_CfromI)
    np.testing.assert_allclose(p_FinC, expected, atol=1e-12)
    assert p_FinC[2] > 0.3  # in front of a camera looking down
    np.testing.assert_allclose(
        landmark_xy(state.imu.q, state.imu.p_IinW, p_FinC, T_CfromI), xy, atol=1e-12
    )


@pytest.mark.parametrize("seed", SEEDS)
def test_landmark_augmentation_jacobians_equal_central_differences(seed: int) -> None:
    """(3.42) corrected (G_X) and (3.43) (G_y) against finite differences of (3.44)."""
    rng = np.random.default_rng(300 + seed)
    T_CfromI = random_T_CfromI(rng)
    state = random_state(rng, T_CfromI)
    p_FinC = foot_predict(
        state.imu.q, state.imu.p_IinW, rng.normal(size=2) + state.imu.p_IinW[:2], T_CfromI
    )
    R3 = np.diag([1e-4, 2e-4, 4e-4])
    aug = landmark_from_observation(state, T_CfromI, p_FinC, R3)
    np.testing.assert_allclose(
        aug.value, landmark_xy(state.imu.q, state.imu.p_IinW, p_FinC, T_CfromI)
    )

    def fun(s: FilterState) -> np.ndarray:
        return landmark_xy(s.imu.q, s.imu.p_IinW, p_FinC, T_CfromI)

    G = stack_jacobian(Measurement(aug.value, aug.G, aug.R, "g"), state)
    G_fd = fd_jacobian(state, fun, vec_minus)
    assert rel_err(G, G_fd) < 1e-5
    G_y = np.stack(
        [
            (
                landmark_xy(state.imu.q, state.imu.p_IinW, p_FinC + EPS * e, T_CfromI)
                - landmark_xy(state.imu.q, state.imu.p_IinW, p_FinC - EPS * e, T_CfromI)
            )
            / (2 * EPS)
            for e in np.eye(3)
        ],
        axis=1,
    )
    assert rel_err(aug.R, G_y @ R3 @ G_y.T) < 1e-5


def test_landmark_initialised_then_reobserved_stays_consistent() -> None:
    """Augment from a first observation; a second noise-free observation from another pose of
    the true trajectory gives a residual explained by the state error, and the update reduces
    the landmark error."""
    rng = np.random.default_rng(24)
    T_CfromI = random_T_CfromI(rng)
    truth = random_state(rng, T_CfromI)
    L_true = truth.imu.p_IinW[:2] + np.array([0.2, -0.1])
    est = truth.copy()
    est.landmarks = {}
    est.P = np.diag(
        np.r_[1e-4 * np.ones(3), 1e-4 * np.ones(3), np.ones(9) * 1e-2, 1e-3 * np.ones(6)]
    )
    est.imu.p_IinW = est.imu.p_IinW + np.array([0.01, 0.005, 0.0])  # filter's position error
    y1 = foot_predict(truth.imu.q, truth.imu.p_IinW, L_true, T_CfromI)
    augment_landmark(est, 5, landmark_from_observation(est, T_CfromI, y1, 1e-6 * np.eye(3)))
    # The landmark inherits the pose error; its cross-covariance with position is positive.
    np.testing.assert_allclose(est.landmarks[5] - L_true, [0.01, 0.005], atol=1e-9)
    sl = est.index(("lm", 5))
    assert np.all(np.diag(est.P[sl, 3:5]) > 0.9e-4)
    # An absolute position fix (a tag) now also corrects the landmark through the correlation.
    fix = Measurement(
        truth.imu.p_IinW - est.imu.p_IinW, {"pos": np.eye(3)}, 1e-10 * np.eye(3), "fix"
    )
    assert update(est, fix).accepted
    assert np.linalg.norm(est.landmarks[5] - L_true) < 1e-3
    y2 = foot_predict(truth.imu.q, truth.imu.p_IinW, L_true, T_CfromI)
    m = foot_measurement(est, T_CfromI, 5, y2, 1e-6 * np.eye(3))
    assert np.abs(m.residual).max() < 2e-3


# ----------------------------------------------------------------------------- tags


def board_corners(rng: np.random.Generator, centre_xy: np.ndarray) -> np.ndarray:
    """Corners of a 3×2 grid of 6 cm tags on the floor around ``centre_xy``."""
    pts = []
    for r in range(2):
        for c in range(3):
            x0, y0 = centre_xy[0] + 0.08 * c - 0.1, centre_xy[1] + 0.08 * r - 0.05
            pts += [[x0, y0, 0], [x0 + 0.06, y0, 0], [x0 + 0.06, y0 + 0.06, 0], [x0, y0 + 0.06, 0]]
    return np.array(pts, dtype=np.float64)


@pytest.mark.parametrize("seed", SEEDS)
def test_tag_corner_jacobian_equals_central_differences(seed: int) -> None:
    """(3.32) with the corrected position sign, and the pixel Jacobian H̄ of (3.30)."""
    rng = np.random.default_rng(400 + seed)
    T_CfromI = random_T_CfromI(rng)
    state = random_state(rng, T_CfromI)
    T_WfromC = make_T(rotmat_from_quat(state.imu.q), state.imu.p_IinW) @ invert_T(T_CfromI)
    corners = board_corners(rng, T_WfromC[:2, 3])
    p_C, J = tag_corners_in_camera(state.imu.q, state.imu.p_IinW, T_CfromI, corners)
    np.testing.assert_allclose(p_C, transform_points(invert_T(T_WfromC), corners), atol=1e-12)

    def fun(s: FilterState) -> np.ndarray:
        return tag_corners_in_camera(s.imu.q, s.imu.p_IinW, T_CfromI, corners)[0].ravel()

    J_fd = fd_jacobian(state, fun, vec_minus)
    J_full = np.zeros_like(J_fd)
    J_full[:, 0:6] = J.reshape(-1, 6)
    assert rel_err(J_full, J_fd) < 1e-5

    def pixels(s: FilterState) -> np.ndarray:
        pc = tag_corners_in_camera(s.imu.q, s.imu.p_IinW, T_CfromI, corners)[0]
        uv = pc[:, :2] / pc[:, 2:3] * np.diag(K)[:2] + K[:2, 2]
        return uv.ravel()

    Hbar_fd = fd_jacobian(state, pixels, vec_minus)[:, 0:6]
    sigma = 0.7
    cov = tag_pose_covariance(state.imu.q, state.imu.p_IinW, T_CfromI, corners, K, sigma)
    cov_fd = sigma**2 * np.linalg.inv(Hbar_fd.T @ Hbar_fd)
    assert rel_err(cov, cov_fd) < 1e-5
    assert np.all(np.linalg.eigvalsh(cov) > 0)


def test_tag_covariance_shrinks_with_more_corners_and_less_pixel_noise() -> None:
    rng = np.random.default_rng(25)
    T_CfromI = random_T_CfromI(rng)
    state = random_state(rng, T_CfromI)
    T_WfromC = make_T(rotmat_from_quat(state.imu.q), state.imu.p_IinW) @ invert_T(T_CfromI)
    corners = board_corners(rng, T_WfromC[:2, 3])
    args = (state.imu.q, state.imu.p_IinW, T_CfromI)
    full = tag_pose_covariance(*args, corners, K, 1.0)
    one_tag = tag_pose_covariance(*args, corners[:4], K, 1.0)
    assert np.trace(full[3:, 3:]) < np.trace(one_tag[3:, 3:])
    np.testing.assert_allclose(tag_pose_covariance(*args, corners, K, 0.5), full / 4, rtol=1e-10)
    with pytest.raises(ValueError):
        tag_pose_covariance(*args, corners[:2], K, 1.0)


@pytest.mark.parametrize("use_attitude", [False, True])
def test_tag_measurement_jacobian_and_end_sheet_noise(use_attitude: bool) -> None:
    rng = np.random.default_rng(26 + use_attitude)
    T_CfromI = random_T_CfromI(rng)
    state = random_state(rng, T_CfromI)
    T_WfromC_true = make_T(rotmat_from_quat(state.imu.q), state.imu.p_IinW) @ invert_T(T_CfromI)
    T_meas = make_T(so3_exp(0.01 * rng.normal(size=3)), 0.02 * rng.normal(size=3)) @ T_WfromC_true
    A = rng.normal(size=(6, 6))
    cov6 = A @ A.T * 1e-5 + 1e-6 * np.eye(6)
    m = tag_measurement(
        state, T_CfromI, T_meas, cov6, end_sheet_eps2=4e-4, use_attitude=use_attitude
    )
    q_tag, p_tag = imu_pose_from_camera_pose(T_meas, T_CfromI)

    def fun(s: FilterState) -> tuple[np.ndarray, np.ndarray]:
        return s.imu.q, s.imu.p_IinW

    def minus(a: tuple, b: tuple) -> np.ndarray:
        d = a[1] - b[1]
        return np.concatenate([quat_boxminus(a[0], b[0]), d]) if use_attitude else d

    H = stack_jacobian(m, state)
    assert rel_err(H, fd_jacobian(state, fun, minus)) < 1e-5
    np.testing.assert_allclose(m.residual, minus((q_tag, p_tag), fun(state)), atol=1e-14)
    R_pos = m.R[-3:, -3:]
    np.testing.assert_allclose(R_pos - cov6[3:, 3:], np.diag([4e-4, 4e-4, 0.0]), atol=1e-15)
    if use_attitude:
        np.testing.assert_array_equal(m.R[:3, :], cov6[:3, :])


def test_imu_pose_from_camera_pose_round_trips() -> None:
    rng = np.random.default_rng(27)
    T_CfromI = random_T_CfromI(rng)
    T_WfromC = camera_looking_down(rng, np.array([1.0, 2.0]))
    q, p = imu_pose_from_camera_pose(T_WfromC, T_CfromI)
    T_back = make_T(rotmat_from_quat(q), p) @ invert_T(T_CfromI)
    np.testing.assert_allclose(T_back, T_WfromC, atol=1e-12)


def test_partial_foot_noise_adds_half_the_hidden_width_across_the_foot() -> None:
    """Known answer: a foot seen 7 cm wide where the whole one is 11 cm adds (2 cm)² across
    it on the floor and nothing along it or up; a foot seen whole or wider adds nothing."""
    from gaitnet.vio.foot_model import partial_foot_noise

    up_C = np.array([0.0, -1.0, 0.0])  # camera y points down
    axis_C = np.array([0.0, 0.3, 1.0])  # forward, with a component off the floor
    R3 = partial_foot_noise(0.01, 0.07, 0.11, axis_C, up_C)
    along = np.array([0.0, 0.0, 1.0])
    across = np.cross(up_C, along)
    assert along @ R3 @ along == pytest.approx(1e-4)
    assert up_C @ R3 @ up_C == pytest.approx(1e-4)
    assert across @ R3 @ across == pytest.approx(1e-4 + 0.02**2)
    np.testing.assert_allclose(R3, R3.T)
    whole = partial_foot_noise(0.01, 0.12, 0.11, axis_C, up_C)
    np.testing.assert_allclose(whole, np.eye(3) * 1e-4)


def test_foot_noise_takes_the_whole_width_from_the_widths_seen_so_far() -> None:
    """The whole width is the 90th percentile of the widths seen, from the 10th on; before,
    and with ``partial`` off, the noise is ``std_m²`` per axis."""
    from gaitnet.vio.foot_model import FootNoise, partial_foot_noise

    up_C, axis_C = np.array([0.0, -1.0, 0.0]), np.array([0.0, 0.0, 1.0])
    noise, off = FootNoise(0.01, partial=True), FootNoise(0.01, partial=False)
    widths = [0.10, 0.11, 0.12, 0.11, 0.10, 0.11, 0.12, 0.11, 0.10, 0.06, 0.07]
    got = [noise.of(w, axis_C, up_C) for w in widths]
    for R3 in got[: FootNoise.MIN_VIEWS - 1] + [off.of(0.05, axis_C, up_C)]:
        np.testing.assert_array_equal(R3, np.eye(3) * 1e-4)
    for k in (FootNoise.MIN_VIEWS - 1, FootNoise.MIN_VIEWS):
        full = np.percentile(widths[: k + 1], 90)
        want = partial_foot_noise(0.01, widths[k], full, axis_C, up_C)
        np.testing.assert_allclose(got[k], want)
        assert want[0, 0] > 1e-4 + 0.02**2  # the hidden width counts
