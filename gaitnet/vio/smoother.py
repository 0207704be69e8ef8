"""Smoother over a whole session as sparse nonlinear least squares (thesis sec. 3.5, (2.19)).

The thesis smooths the filter's estimates by minimising a sum of quadratic terms in the error
states of all frames, the biases and the stance-foot landmarks (sec. 3.5, the ch. 2 version is
(2.19)). With the corrections of the thesis-notes (``quad(a, B) = ½ aᵀ B⁻¹ a``; the tag term on
the position block with ``ε2`` at the end sheet; the foot term on ``U_k``; ``U_init`` with the
conjugate; linearisation that accounts for the filter's update jumps) the cost is

    ``J(x) = ½ Σ_terms ‖W_i e_i(x)‖²``   (terms: :mod:`gaitnet.vio.smoother_terms`,
    :mod:`gaitnet.vio.smoother_measurements`),

solved here by Gauss–Newton: the first iteration linearises around the filter's estimates
(the thesis's single linear solve of (3.49)–(3.50), with the dynamics residual equal to the
filter's update jumps), later ones around the updated estimates until the step is negligible.
Each step solves the sparse normal equations ``(J S)ᵀ(J S) y = −(J S)ᵀ e``, ``δx = S y`` (``S``
the column scaling ``1/‖J_:j‖``) with a sparse LU (``scipy.sparse.linalg.splu``); no dense
``(9N + 6 + 2M)²`` matrix is ever formed. Marginal covariances of the landmarks and the biases
come from the same factorisation (one solve per landmark dimension); per-frame pose covariances
are not computed (they would need selected inversion).

Input: a :class:`~gaitnet.vio.records.FilterRecord`. Output: :class:`SmootherResult`.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from gaitnet.geometry import invert_T, rotmat_from_quat
from gaitnet.vio.errors import FilterDivergedError
from gaitnet.vio.foot_model import foot_measurement
from gaitnet.vio.records import FilterRecord
from gaitnet.vio.smoother_measurements import MeasurementTerm, group_terms
from gaitnet.vio.smoother_terms import (
    DynamicsData,
    PriorData,
    SmootherVariables,
    TermBlock,
    dynamics_data,
    dynamics_term,
    prior_data,
    prior_term,
    stack_blocks,
)
from gaitnet.vio.tag_model import tag_measurement
from gaitnet.vio.vo_model import vo_measurement

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class SmootherOptions:
    """``max_iterations`` Gauss–Newton iterations (1 = the thesis's single linear solve; on
    the 60 s synthetic session of benchmarks/bench_smoother.py the second iteration ends
    0.05 mm from the converged estimate, the first 9 cm from it);
    ``step_tol`` stop when the largest step component (rad, m, m/s) falls below it;
    ``noise_floor`` a variance added to every dynamics and prior covariance (keeps noise-free
    configurations solvable; 1e-14 is far below any real IMU's per-frame noise);
    ``landmark_covariance`` compute the landmarks' and biases' marginal covariances;
    ``final_evaluation`` evaluate the residual once more at the solution for the reported
    ``chi2`` (else they come from the last linear model, exact to second order in the last
    step)."""

    max_iterations: int = 2
    step_tol: float = 1e-6
    noise_floor: float = 1e-14
    landmark_covariance: bool = True
    final_evaluation: bool = False


@dataclass
class SmootherResult:
    """Smoothed estimates (thesis (3.50)): per frame ``t_s``, ``session_index``, ``q`` (N, 4)
    (``R(q) = R_WfromI``), ``p_IinW``, ``v_IinW`` (N, 3); the session biases ``b_g``, ``b_a``;
    ``landmarks`` {id: (x, y)} on the floor ``z = 0``; ``landmark_cov`` {id: (2, 2)} and
    ``bias_cov`` (6, 6) marginal covariances (empty / ``None`` when not computed);
    ``T_CfromI`` the extrinsic. Diagnostics: ``cost`` per iteration (``½ Σ ‖W e‖²``, first the
    filter's), ``chi2`` per term kind at the solution with ``n_residuals`` per kind,
    ``iterations``, ``converged``, ``timings_s`` per phase."""

    t_s: np.ndarray
    session_index: np.ndarray
    q: np.ndarray
    p_IinW: np.ndarray
    v_IinW: np.ndarray
    b_g: np.ndarray
    b_a: np.ndarray
    landmarks: dict[int, np.ndarray]
    T_CfromI: np.ndarray
    landmark_cov: dict[int, np.ndarray] = field(default_factory=dict)
    bias_cov: np.ndarray | None = None
    cost: list[float] = field(default_factory=list)
    chi2: dict[str, float] = field(default_factory=dict)
    n_residuals: dict[str, int] = field(default_factory=dict)
    iterations: int = 0
    converged: bool = False
    timings_s: dict[str, float] = field(default_factory=dict)

    @property
    def T_WfromI(self) -> np.ndarray:
        """IMU poses (N, 4, 4)."""
        n = self.q.shape[0]
        T = np.broadcast_to(np.eye(4), (n, 4, 4)).copy()
        T[:, :3, :3] = rotmat_from_quat(self.q)
        T[:, :3, 3] = self.p_IinW
        return T

    @property
    def T_WfromC(self) -> np.ndarray:
        """Colour-camera poses (N, 4, 4): ``T_WfromC = T_WfromI T_CfromI⁻¹``."""
        return self.T_WfromI @ invert_T(self.T_CfromI)


class Problem:
    """The smoothing problem of one record: the fixed data of every term and the evaluation of
    the whitened residual and its sparse Jacobian at given variables."""

    def __init__(
        self,
        record: FilterRecord,
        terms: list[MeasurementTerm] | None = None,
        options: SmootherOptions | None = None,
    ) -> None:
        record.validate()
        self.record = record
        self.options = options or SmootherOptions()
        self.prior: PriorData = prior_data(record, self.options.noise_floor)
        self.dynamics: DynamicsData = dynamics_data(record, self.options.noise_floor)
        self.terms = measurement_terms_from_record(record) if terms is None else terms
        self.groups = group_terms(self.terms)

    def initial(self) -> SmootherVariables:
        return SmootherVariables.from_record(self.record)

    def blocks(self, x: SmootherVariables, jacobian: bool = True) -> list[TermBlock]:
        """Every term kind's whitened residuals (and Jacobian triplets), in :data:`KINDS` order."""
        out = [prior_term(x, self.prior, jacobian), dynamics_term(x, self.dynamics, jacobian)]
        out += [g.evaluate(x, jacobian) for g in self.groups]
        return out

    def residual(self, x: SmootherVariables) -> np.ndarray:
        """The whitened nonlinear residual ``W e(x)`` (all terms stacked)."""
        return np.concatenate([b.residual for b in self.blocks(x, jacobian=False)])

    def linearise(self, x: SmootherVariables) -> tuple[np.ndarray, sp.csr_matrix]:
        """``(W e(x), ∂(W e(x ⊞ δ))/∂δ at 0)``, the Jacobian as ``scipy.sparse`` CSR."""
        return stack_blocks(self.blocks(x, jacobian=True), x.dim)


def measurement_terms_from_record(record: FilterRecord) -> list[MeasurementTerm]:
    """The record's VO, tag (except the initialising detection, which is in the prior) and
    foot observations as :class:`MeasurementTerm` closures over the filter's measurement
    functions (thesis (3.21), (3.33), (3.47))."""
    T_CfromI = record.T_CfromI
    terms: list[MeasurementTerm] = []
    for m in record.vo:
        terms.append(
            MeasurementTerm(
                "vo",
                m.frame,
                m.frame_prev,
                None,
                lambda s, m=m: vo_measurement(s, T_CfromI, m.R, m.t, m.cov6),
                so3_rows=(0, 3),
            )
        )
    for t in record.tags:
        if t.is_first:
            continue
        terms.append(
            MeasurementTerm(
                "tag_pose" if t.use_attitude else "tag",
                t.frame,
                None,
                None,
                lambda s, t=t: tag_measurement(
                    s,
                    T_CfromI,
                    t.T_WfromC,
                    t.cov6,
                    end_sheet_eps2=t.end_sheet_eps2,
                    use_attitude=t.use_attitude,
                ),
            )
        )
    for f in record.feet:
        terms.append(
            MeasurementTerm(
                "foot",
                f.frame,
                None,
                f.landmark_id,
                lambda s, f=f: foot_measurement(s, T_CfromI, f.landmark_id, f.p_FinC, f.R3),
            )
        )
    return terms


def elimination_order(record: FilterRecord, x: SmootherVariables) -> np.ndarray:
    """A fill-reducing ordering of the error-state columns: frames in time order, each
    landmark next to the median frame of its observations, the session biases last.

    Every term couples frames at most a stance apart (VO: consecutive frames; foot: the frames
    that see one landmark), so in this order the normal matrix is banded (half-bandwidth about
    9 × frames per stance) with a 6-wide border, and an LU without reordering fills only the
    band. (SuperLU's own orderings treat the dense bias columns badly: on a 60 s session they
    fill 80× more and take seconds.)"""
    n = x.n_frames
    frames_of: dict[int, list[int]] = {}
    for f in record.feet:
        frames_of.setdefault(f.landmark_id, []).append(f.frame)
    key = np.concatenate(
        [
            np.repeat(np.arange(n, dtype=np.float64), 9),
            np.repeat([float(np.median(frames_of[i])) + 0.5 for i in x.lm_ids], 2),
        ]
    )
    order = np.argsort(key, kind="stable")
    frame_lm_cols = np.concatenate(
        [np.arange(9 * n), x.bias_col + 6 + np.arange(2 * len(x.lm_ids))]
    )
    return np.concatenate([frame_lm_cols[order], x.bias_col + np.arange(6)]).astype(np.int64)


@dataclass
class NormalSolve:
    """One Gauss–Newton solve: the step ``dx``, and what a covariance solve needs: the LU
    factor of the permuted, scaled normal matrix, the permutation and the column scaling."""

    dx: np.ndarray
    lu: spla.SuperLU
    perm: np.ndarray
    scale: np.ndarray

    def solve(self, B: np.ndarray) -> np.ndarray:
        """``(JᵀJ)⁻¹ B`` for a dense ``B`` (n, m)."""
        s = self.scale[:, None]
        X = np.empty_like(B)
        X[self.perm] = self.lu.solve(np.ascontiguousarray((s * B)[self.perm]))
        return s * X


def solve_normal_equations(J: sp.csr_matrix, e: np.ndarray, perm: np.ndarray) -> NormalSolve:
    """The Gauss–Newton step ``δ = argmin ‖e + J δ‖²`` from the sparse normal equations,
    scaled (``S = diag(1/‖J_:j‖)``) and permuted by ``perm`` (:func:`elimination_order`):
    ``(J S)ᵀ(J S) y = −(J S)ᵀ e``, ``δ = S y``, factorised by SuperLU without further
    reordering or pivoting (the matrix is symmetric positive definite)."""
    col_norm = np.sqrt(np.asarray(J.multiply(J).sum(axis=0)).ravel())
    if np.any(col_norm == 0.0):
        j = int(np.argmin(col_norm))
        raise FilterDivergedError(f"smoother: error-state column {j} is not constrained")
    s = 1.0 / col_norm
    Js = J @ sp.diags(s)
    A = (Js.T @ Js).tocsr()[perm][:, perm].tocsc()
    rhs = -(Js.T @ e)
    lu = spla.splu(A, permc_spec="NATURAL", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
    y = np.empty_like(rhs)
    y[perm] = lu.solve(rhs[perm])
    return NormalSolve(s * y, lu, perm, s)


def smooth(
    record: FilterRecord,
    options: SmootherOptions | None = None,
    terms: list[MeasurementTerm] | None = None,
) -> SmootherResult:
    """Smooth a filter run (module docstring; thesis sec. 3.5 corrected).

    Gauss–Newton from the filter's estimates: linearise (residual and sparse Jacobian), solve
    the sparse normal equations, apply ``x ⊞ δx``; stop after ``max_iterations`` or when the
    largest step component is below ``step_tol``. If a linearisation finds the cost above the
    previous one, the previous step is halved (up to 4 times) instead. ``terms`` overrides the
    measurement terms built from the record (tests, other models). Raises
    :class:`FilterDivergedError` for a non-finite residual or an unconstrained variable.
    """
    opts = options or SmootherOptions()
    timings = {"setup": 0.0, "linearise": 0.0, "solve": 0.0, "covariance": 0.0}
    t0 = time.perf_counter()
    problem = Problem(record, terms, opts)
    x = problem.initial()
    timings["setup"] = time.perf_counter() - t0

    costs: list[float] = []
    converged = False
    normal: NormalSolve | None = None
    perm = elimination_order(record, x)
    iterations = 0
    halvings = 0
    prev: tuple[SmootherVariables, np.ndarray, float] | None = None  # (x, δx, cost) before
    blocks: list[TermBlock] = []
    J = sp.csr_matrix((0, x.dim))
    while iterations < opts.max_iterations:
        t0 = time.perf_counter()
        blocks = problem.blocks(x, jacobian=True)
        e, J = stack_blocks(blocks, x.dim)
        timings["linearise"] += time.perf_counter() - t0
        cost = 0.5 * float(e @ e)
        if not np.isfinite(cost):
            raise FilterDivergedError("smoother: non-finite residual")
        if prev is not None and cost > prev[2] * (1.0 + 1e-9) and halvings < 4:
            halvings += 1
            x = prev[0].boxplus(prev[1] * 0.5**halvings)
            continue
        halvings = 0
        costs.append(cost)
        iterations += 1
        t0 = time.perf_counter()
        normal = solve_normal_equations(J, e, perm)
        dx = normal.dx
        timings["solve"] += time.perf_counter() - t0
        prev = (x, dx, cost)
        x = x.boxplus(dx)
        if float(np.max(np.abs(dx), initial=0.0)) < opts.step_tol:
            converged = True
            break
    # Final diagnostics: exactly (one more residual evaluation) or from the linear model.
    t0 = time.perf_counter()
    if opts.final_evaluation or prev is None:
        blocks = problem.blocks(x, jacobian=False)
        chi2 = {b.kind: float(b.residual @ b.residual) for b in blocks}
    else:
        e_pred = np.concatenate([b.residual for b in blocks]) + J @ prev[1]
        chi2, row = {}, 0
        for b in blocks:
            m = b.residual.shape[0]
            chi2[b.kind] = float(e_pred[row : row + m] @ e_pred[row : row + m])
            row += m
    costs.append(0.5 * sum(chi2.values()))
    timings["linearise"] += time.perf_counter() - t0

    result = SmootherResult(
        t_s=record.t_s.copy(),
        session_index=record.session_index.copy(),
        q=x.q,
        p_IinW=x.p_IinW,
        v_IinW=x.v_IinW,
        b_g=x.b_g,
        b_a=x.b_a,
        landmarks={i: x.lm_xy[j].copy() for j, i in enumerate(x.lm_ids)},
        T_CfromI=record.T_CfromI.copy(),
        cost=costs,
        chi2=chi2,
        n_residuals={b.kind: int(b.residual.shape[0]) for b in blocks},
        iterations=iterations,
        converged=converged,
        timings_s=timings,
    )
    if opts.landmark_covariance and normal is not None:
        t0 = time.perf_counter()
        _marginals(result, x, normal)
        timings["covariance"] = time.perf_counter() - t0
    logger.info(
        "smoother: %d frames, %d landmarks, cost %.4g -> %.4g in %d iterations (%s)",
        x.n_frames,
        len(x.lm_ids),
        costs[0],
        costs[-1],
        iterations,
        "converged" if converged else "iteration limit",
    )
    return result


def _marginals(result: SmootherResult, x: SmootherVariables, normal: NormalSolve) -> None:
    """Marginal covariances of the biases and landmarks: their columns of ``(JᵀJ)⁻¹`` from the
    last factorisation (one sparse solve per wanted dimension; dense only n × (6 + 2M))."""
    idx = np.concatenate(
        [x.bias_col + np.arange(6), x.bias_col + 6 + np.arange(2 * len(x.lm_ids))]
    ).astype(np.int64)
    E = np.zeros((x.dim, idx.size))
    E[idx, np.arange(idx.size)] = 1.0
    C = normal.solve(E)[idx, :]
    C = 0.5 * (C + C.T)
    result.bias_cov = C[0:6, 0:6]
    for j, lm_id in enumerate(x.lm_ids):
        s = 6 + 2 * j
        result.landmark_cov[lm_id] = C[s : s + 2, s : s + 2]
