"""The sparse smoother of sec. 3.5 (gaitnet.vio.smoother) and the filter record it consumes."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.optimize import least_squares
from scipy.stats import chi2

sys.path.insert(0, str(Path(__file__).parent))

from smootherfactory import SynthConfig, make_problem  # noqa: E402

from gaitnet.geometry import invert_T, quat_boxminus, quat_from_rotvec, rotmat_from_quat  # noqa: E402
from gaitnet.vio.imu_propagation import propagate_to  # noqa: E402
from gaitnet.vio.records import (  # noqa: E402
    FilterRecorder,
    ImuInterval,
    VoRecord,
    preintegrate,
)
from gaitnet.vio.smoother import (  # noqa: E402
    Problem,
    SmootherOptions,
    elimination_order,
    smooth,
    solve_normal_equations,
)
from gaitnet.vio.state import FilterState, ImuState  # noqa: E402


@pytest.fixture(scope="module")
def small():
    return make_problem(SynthConfig(duration_s=0.5, step_s=0.2, stance_s=0.3), seed=3)


@pytest.fixture(scope="module")
def walk():
    return make_problem(SynthConfig(duration_s=6.0), seed=11)


def _increments(iv: ImuInterval) -> np.ndarray:
    return np.concatenate([iv.dp, iv.dv])


def test_interval_reproduces_the_core_propagation_from_any_start(small) -> None:
    """The preintegrated increment predicts propagate_to from another start state exactly
    (the mechanisation is linear in the start pose and velocity)."""
    rng = np.random.default_rng(0)
    before = small.record.imu_state(3)
    t_end = float(small.record.t_s[4])
    iv, after = preintegrate(before, small.imu, t_end, small.noise, gravity_mps2=9.81)
    other = ImuState(
        quat_from_rotvec(rng.normal(size=3)),
        rng.normal(size=3),
        rng.normal(size=3),
        before.b_g.copy(),
        before.b_a.copy(),
        before.t_s,
    )
    st = FilterState.new(other, np.eye(15))
    propagate_to(st, small.imu, t_end, small.noise, gravity_mps2=9.81)
    R0 = rotmat_from_quat(other.q)
    g = np.array([0.0, 0.0, 9.81])
    T = iv.dt_s
    np.testing.assert_allclose(rotmat_from_quat(st.imu.q), R0 @ iv.dR, atol=1e-12)
    np.testing.assert_allclose(st.imu.v_IinW, other.v_IinW + R0 @ iv.dv - g * T, atol=1e-12)
    np.testing.assert_allclose(
        st.imu.p_IinW,
        other.p_IinW + other.v_IinW * T + R0 @ iv.dp - 0.5 * g * T * T,
        atol=1e-12,
    )


def test_interval_bias_jacobian_equals_finite_differences(small) -> None:
    """J_bias from the probe covariance equals central differences of re-propagation."""
    before = small.record.imu_state(5)
    t_end = float(small.record.t_s[6])
    iv, _ = preintegrate(before, small.imu, t_end, small.noise, gravity_mps2=9.81)
    h = 1e-6
    J_fd = np.zeros((9, 6))
    for i in range(6):
        out = []
        for sgn in (1.0, -1.0):
            b = before.copy()
            if i < 3:
                b.b_g[i] += sgn * h
            else:
                b.b_a[i - 3] += sgn * h
            ivp, _ = preintegrate(b, small.imu, t_end, small.noise, gravity_mps2=9.81)
            out.append(ivp)
        dth = quat_boxminus(_quat(out[0].dR), _quat(iv.dR), chart="exp") - quat_boxminus(
            _quat(out[1].dR), _quat(iv.dR), chart="exp"
        )
        J_fd[0:3, i] = dth / (2 * h)
        J_fd[3:9, i] = (_increments(out[0]) - _increments(out[1])) / (2 * h)
    err = np.linalg.norm(J_fd - iv.J_bias) / np.linalg.norm(iv.J_bias)
    assert err < 1e-5
    assert np.all(np.linalg.eigvalsh(iv.Q) > 0.0)


def _quat(R: np.ndarray) -> np.ndarray:
    from gaitnet.geometry import quat_from_rotmat

    return quat_from_rotmat(R)


def test_without_measurements_the_smoother_keeps_the_filter_trajectory(small) -> None:
    """Prior + IMU only: the filter's dead reckoning is already optimal (zero dynamics
    residuals, prior residual zero), so the smoother returns it."""
    rec = small.record
    recorder = FilterRecorder(rec.T_CfromI, 9.81)
    state = FilterState.new(rec.x_prior.copy(), rec.P_prior)
    recorder.set_prior(state)
    recorder.add_frame(state, 0)
    for k in range(1, rec.n_frames):
        before = state.imu.copy()
        iv, _ = preintegrate(before, small.imu, float(rec.t_s[k]), small.noise, gravity_mps2=9.81)
        propagate_to(state, small.imu, float(rec.t_s[k]), small.noise, gravity_mps2=9.81)
        recorder.add_interval(iv)
        recorder.add_frame(state, k)
    imu_only = recorder.finish()
    problem = Problem(imu_only)
    e = problem.residual(problem.initial())
    assert np.max(np.abs(e)) < 1e-6
    result = smooth(imu_only)
    np.testing.assert_allclose(result.p_IinW, imu_only.p_IinW, atol=1e-9)
    np.testing.assert_allclose(quat_boxminus(result.q, imu_only.q), 0.0, atol=1e-9)


def test_jacobian_equals_finite_differences_of_the_residual(small) -> None:
    """The assembled sparse Jacobian equals central differences of the whitened nonlinear
    residual through the boxplus, at a perturbed state (every term kind present)."""
    problem = Problem(small.record)
    rng = np.random.default_rng(1)
    x0 = problem.initial()
    x = x0.boxplus(1e-2 * rng.normal(size=x0.dim))
    e, J = problem.linearise(x)
    assert sp.issparse(J)
    kinds = {b.kind: b.residual.size for b in problem.blocks(x, jacobian=False)}
    assert all(kinds[k] > 0 for k in ("prior", "imu", "vo", "tag", "foot"))
    h = 1e-6
    J_fd = np.zeros(J.shape)
    for i in range(x.dim):
        d = np.zeros(x.dim)
        d[i] = h
        J_fd[:, i] = (problem.residual(x.boxplus(d)) - problem.residual(x.boxplus(-d))) / (2 * h)
    Jd = J.toarray()  # small instance only
    col_err = np.linalg.norm(J_fd - Jd, axis=0) / np.maximum(np.linalg.norm(Jd, axis=0), 1e-3)
    assert col_err.max() < 1e-5


def test_step_equals_dense_least_squares_and_solution_equals_scipy(small) -> None:
    """The sparse normal-equation step equals a dense least-squares solve of the same
    linearisation; the converged estimate equals scipy's dense least_squares on the residual
    (its own finite-difference Jacobian) on a small instance."""
    rec = make_problem(SynthConfig(duration_s=0.4, step_s=0.15, stance_s=0.2), seed=5).record
    problem = Problem(rec)
    x0 = problem.initial()
    e, J = problem.linearise(x0)
    step = solve_normal_equations(J, e, elimination_order(rec, x0)).dx
    dense = np.linalg.lstsq(J.toarray(), -e, rcond=None)[0]
    np.testing.assert_allclose(step, dense, rtol=1e-6, atol=1e-9 * np.abs(dense).max())

    result = smooth(rec, SmootherOptions(max_iterations=10, step_tol=1e-10))
    assert result.converged
    start = x0.boxplus(step)  # scipy from the first GN step (the filter's start is stiff)
    sol = least_squares(
        lambda d: problem.residual(start.boxplus(d)),
        np.zeros(x0.dim),
        method="lm",
        xtol=1e-15,
        ftol=1e-15,
        gtol=1e-15,
        x_scale="jac",
    )
    xs = start.boxplus(sol.x)
    assert 0.5 * np.sum(sol.fun**2) == pytest.approx(result.cost[-1], rel=1e-6)
    np.testing.assert_allclose(result.p_IinW, xs.p_IinW, atol=1e-6)
    np.testing.assert_allclose(quat_boxminus(result.q, xs.q), 0.0, atol=1e-6)
    np.testing.assert_allclose(result.v_IinW, xs.v_IinW, atol=1e-5)
    for j, i in enumerate(xs.lm_ids):
        np.testing.assert_allclose(result.landmarks[i], xs.lm_xy[j], atol=1e-6)


def test_smoother_is_more_accurate_than_the_filter(walk) -> None:
    """Known truth: the smoother's poses, landmarks and same-foot strides are closer to the
    truth than the filter's; every landmark error is inside its marginal covariance's
    99.99 % ellipse; camera poses follow from T_CfromI."""
    rec = walk.record
    result = smooth(rec)
    assert result.iterations >= 1 and result.cost[-1] < result.cost[0]

    def pos_rmse(p: np.ndarray) -> float:
        return float(np.sqrt(np.mean(np.sum((p - walk.p) ** 2, axis=1))))

    def att_rmse(q: np.ndarray) -> float:
        return float(np.sqrt(np.mean(np.sum(quat_boxminus(q, walk.q) ** 2, axis=1))))

    assert pos_rmse(result.p_IinW) < pos_rmse(rec.p_IinW)
    assert att_rmse(result.q) < att_rmse(rec.q)
    ids = sorted(result.landmarks)

    def lm_rmse(est: dict[int, np.ndarray]) -> float:
        return float(np.sqrt(np.mean([np.sum((est[i] - walk.landmarks[i]) ** 2) for i in ids])))

    assert lm_rmse(result.landmarks) < lm_rmse(walk.filter_landmarks)

    def stride_rmse(est: dict[int, np.ndarray]) -> float:
        errs = [
            np.linalg.norm(est[b] - est[a]) - np.linalg.norm(walk.landmarks[b] - walk.landmarks[a])
            for a, b in zip(ids[:-2], ids[2:], strict=True)
        ]
        return float(np.sqrt(np.mean(np.square(errs))))

    cfg = SynthConfig()
    assert stride_rmse(result.landmarks) < stride_rmse(walk.filter_landmarks)
    assert stride_rmse(result.landmarks) < cfg.foot_std
    bound = chi2.ppf(0.9999, 2)
    for i in ids:
        d = result.landmarks[i] - walk.landmarks[i]
        assert d @ np.linalg.solve(result.landmark_cov[i], d) < bound
    T_WfromC = result.T_WfromC
    np.testing.assert_allclose(T_WfromC[7], result.T_WfromI[7] @ invert_T(rec.T_CfromI), atol=1e-12)


def test_iteration_options_act(walk) -> None:
    """``max_iterations`` caps the Gauss–Newton iterations (each lowers the cost on this
    walk: the cost evaluated at each end point); ``step_tol`` stops them once the largest step
    is below it."""
    capped = [
        smooth(
            walk.record, SmootherOptions(max_iterations=n, step_tol=1e-12, final_evaluation=True)
        )
        for n in (1, 3)
    ]
    assert [r.iterations for r in capped] == [1, 3] and not any(r.converged for r in capped)
    assert capped[1].cost[-1] < capped[0].cost[-1]
    loose = smooth(walk.record, SmootherOptions(max_iterations=5, step_tol=1e3))
    assert loose.iterations == 1 and loose.converged


def test_large_problem_stays_sparse(monkeypatch: pytest.MonkeyPatch) -> None:
    """No dense (n × n) matrix on a 10 s, 30 Hz problem: the Jacobian is CSR with O(n)
    entries, nothing is densified, and the LU of the normal matrix fills only its band."""
    rec = make_problem(SynthConfig(duration_s=10.0), seed=2).record

    def refuse(*args, **kwargs):
        raise AssertionError("a sparse matrix was densified")

    monkeypatch.setattr(sp.csr_matrix, "toarray", refuse)
    monkeypatch.setattr(sp.csc_matrix, "toarray", refuse)
    monkeypatch.setattr(sp.coo_matrix, "toarray", refuse)
    monkeypatch.setattr(sp.csr_matrix, "todense", refuse)
    monkeypatch.setattr(sp.csc_matrix, "todense", refuse)
    problem = Problem(rec)
    x = problem.initial()
    e, J = problem.linearise(x)
    n = x.dim
    assert isinstance(J, sp.csr_matrix) and n > 2500
    assert J.nnz < 60 * n
    normal = solve_normal_equations(J, e, elimination_order(rec, x))
    assert normal.lu.L.nnz + normal.lu.U.nnz < 400 * n  # band, not n²
    result = smooth(rec)
    assert np.all(np.isfinite(result.p_IinW))


def test_record_is_validated(small) -> None:
    rec = small.record
    bad = VoRecord(0, rec.n_frames, np.eye(3), np.zeros(3), np.eye(6))
    from dataclasses import replace

    with pytest.raises(ValueError, match="VO record"):
        replace(rec, vo=[*rec.vo, bad]).validate()
    with pytest.raises(ValueError, match="IMU intervals"):
        replace(rec, intervals=rec.intervals[:-1]).validate()
    recorder = FilterRecorder(rec.T_CfromI)
    with pytest.raises(ValueError, match="previous frame"):
        recorder.add_vo(np.eye(3), np.zeros(3), np.eye(6))
    with pytest.raises(ValueError, match="set_prior"):
        recorder.finish()
