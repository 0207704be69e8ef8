"""Pose correction of the thesis (sec. 4.2.4, eq. 4.7, 4.8) by Levenberg-Marquardt.

Each frame starts from the motion predictor's pose ``x̄`` and is pulled towards the measured
pelvis orientation and position and the measured foot points, with bone-length terms; beyond
the thesis, a knee hinge, range-of-motion limits, fixed thigh/shank lengths, a Cauchy loss
on the foot terms, contact weighting of the foot terms and an ankle-to-marker offset are
switches of :class:`~gaitnet.pipeline.pose_types.PoseCorrectionParams`. The objective is a
sum of squared residuals (:mod:`gaitnet.pipeline.pose_residuals`, analytic Jacobians), solved
by a small batched Levenberg-Marquardt in numpy instead of the thesis's L-BFGS (0.3 s per
frame): about a millisecond per frame. ``solver: lbfgs`` runs scipy's L-BFGS-B on the same
objective and gradient instead (docs/pose-correction.md has the objective, the parameters and
the measured speed and accuracy of both).
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from gaitnet.errors import InputError
from gaitnet.motion.skeleton import LowerBodySkeleton, from_rest_joints
from gaitnet.pipeline.pose_residuals import (
    ChainGeometry,
    ChainState,
    Problem,
    chain_points,
    evaluate,
    exp_and_right_jacobian,
    log_and_right_jacobian_inv,
    retract,
)
from gaitnet.pipeline.pose_types import (
    FrameMeasurements,
    PoseCorrectionParams,
    PoseState,
    R_PfromSMPL,
)

FloatArray = NDArray[np.float64]
log = logging.getLogger(__name__)

__all__ = [
    "CorrectionInfo",
    "correct_pose",
    "correct_poses",
    "skeleton_with_lengths",
]


@dataclass(frozen=True, eq=False)
class CorrectionInfo:
    """What the solver did for a batch of B frames.

    ``cost_before`` / ``cost_after`` (B,): the objective at the prior and at the result;
    ``iterations`` (B,): accepted and rejected steps taken; ``bone_lengths`` (B, 4): thigh L, R,
    shank L, R [m] (the skeleton's when they are fixed); ``joints`` (B, 7, 3): pelvis, L_hip,
    R_hip, L_knee, R_knee, L_ankle, R_ankle; ``foot_points`` (B, 2, 3): the model's foot points
    (ankle plus the marker offset) in the world.
    """

    cost_before: FloatArray
    cost_after: FloatArray
    iterations: NDArray[np.int64]
    bone_lengths: FloatArray
    joints: FloatArray
    foot_points: FloatArray


_LAST_GEOMETRY: list[tuple[LowerBodySkeleton, PoseCorrectionParams, ChainGeometry]] = []


def _geometry(skel: LowerBodySkeleton, params: PoseCorrectionParams) -> ChainGeometry:
    """The chain constants, kept for the skeleton and parameters (by identity) last used."""
    if _LAST_GEOMETRY and _LAST_GEOMETRY[0][0] is skel and _LAST_GEOMETRY[0][1] is params:
        return _LAST_GEOMETRY[0][2]
    geo = ChainGeometry.build(skel, params)
    _LAST_GEOMETRY[:] = [(skel, params, geo)]
    return geo


def _problem(
    priors: Sequence[PoseState],
    meas: Sequence[FrameMeasurements],
    skel: LowerBodySkeleton,
    params: PoseCorrectionParams,
) -> tuple[Problem, ChainState]:
    if len(priors) != len(meas) or not priors:
        raise InputError(
            f"pose correction: {len(priors)} priors and {len(meas)} measurements; need equal, > 0"
        )
    for i, (p, m) in enumerate(zip(priors, meas, strict=True)):
        if not isinstance(p, PoseState) or not isinstance(m, FrameMeasurements):
            raise InputError(f"pose correction frame {i}: expected PoseState and FrameMeasurements")
    B = len(priors)
    geo = _geometry(skel, params)
    pose = np.stack([p.pose for p in priors])
    R_prior, _ = exp_and_right_jacobian(pose[:, :3])
    measured_rot = np.array([m.R_WfromP is not None for m in meas])
    R_meas = np.tile(np.eye(3), (B, 1, 1))
    for i, m in enumerate(meas):
        if m.R_WfromP is not None:
            R_meas[i] = m.R_WfromP @ R_PfromSMPL
    measured_pos = np.array([m.p_PinW is not None for m in meas])
    p_meas = np.stack([m.p_PinW if m.p_PinW is not None else np.zeros(3) for m in meas])
    visible = np.stack([m.visible for m in meas])
    foot = np.nan_to_num(np.stack([m.foot_W for m in meas]))
    gain = params.contact_gain if params.contact_weighting else 0.0
    contact = np.stack([m.contact for m in meas])
    rom = np.radians(np.asarray(params.rom_deg, dtype=np.float64)).reshape(18, 2)
    pb = Problem(
        geo=geo,
        params=params,
        R_prior=R_prior,
        t_prior=np.stack([p.trans for p in priors]),
        a_prior=pose[:, 3:].reshape(B, 6, 3),
        R_meas=R_meas,
        w_root_rot=measured_rot / params.sigma_root_rot_rad,
        p_meas=p_meas,
        w_root_pos=measured_pos / params.sigma_root_pos_m,
        foot=foot,
        w_foot=visible * (1.0 + gain * contact) / params.sigma_foot_m,
        rom_lo=rom[:, 0],
        rom_hi=rom[:, 1],
        w_flat=contact / params.sigma_flat_rad,
        R_prior_meas_T=np.stack([R_prior, R_meas], axis=1).swapaxes(-1, -2).copy(),
    )
    state = ChainState(
        R0=R_prior.copy(),
        t=pb.t_prior.copy(),
        a=pb.a_prior.copy(),
        l=np.tile(geo.lengths, (B, 1)),
    )
    return pb, state


def _levenberg_marquardt(
    pb: Problem, s: ChainState
) -> tuple[ChainState, FloatArray, FloatArray, NDArray[np.int64]]:
    """Batched LM: damping ``λ diag(JᵀJ)`` per frame, a step is kept only if the cost drops."""
    par = pb.params
    r, J, cost = evaluate(pb, s)
    cost0 = cost.copy()
    B, n = J.shape[0], J.shape[2]
    lam = np.full(B, 1e-4)
    active = np.ones(B, dtype=bool)
    iterations = np.zeros(B, dtype=np.int64)
    eye = np.eye(n)
    for _ in range(par.max_iterations):
        Jt = J.swapaxes(1, 2)
        H = Jt @ J
        g = (Jt @ r[..., None])[..., 0]
        diag = np.einsum("bii->bi", H)
        A = H + (lam[:, None] * diag + 1e-9)[:, :, None] * eye
        step = -np.linalg.solve(A, g[..., None])[..., 0]
        step[~active] = 0.0
        # The linear model's predicted decrease −2gᵀΔ − ΔᵀHΔ: below the tolerance, stop
        # without evaluating the step.
        predicted = -2.0 * np.einsum("bi,bi->b", g, step) - np.einsum("bi,bij,bj->b", step, H, step)
        active &= predicted > par.cost_tolerance * cost
        if not active.any():
            break
        step[~active] = 0.0
        trial = retract(s, step)
        r_t, J_t, cost_t = evaluate(pb, trial)
        better = (cost_t < cost) & active
        iterations += active
        if better.all():
            s, r, J = trial, r_t, J_t
        elif better.any():
            for name in ("R0", "t", "a", "l"):
                getattr(s, name)[better] = getattr(trial, name)[better]
            r[better], J[better] = r_t[better], J_t[better]
        small = np.abs(step).max(axis=1) < par.step_tolerance
        tiny_gain = better & (cost - cost_t <= par.cost_tolerance * cost)
        cost = np.where(better, cost_t, cost)
        lam = np.where(better, np.maximum(lam / 3.0, 1e-9), lam * 4.0)
        active &= ~(small | tiny_gain | (lam > 1e8))
        if not active.any():
            break
    return s, cost0, cost, iterations


def step_cost_and_gradient(
    pb: Problem, s0: ChainState, step: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Each frame's cost at ``retract(s0, step)`` and its gradient over ``step`` (B, n): the
    exact gradient ``2 Jᵀ r`` of :func:`~gaitnet.pipeline.pose_residuals.evaluate`, carried to
    the root's step through its right Jacobian (``exp(δ + h) ≈ exp(δ) exp(J_r(δ) h)``)."""
    r, J, cost = evaluate(pb, retract(s0, step))
    grad = 2.0 * np.einsum("bmi,bm->bi", J, r)
    _, Jr = exp_and_right_jacobian(step[:, 0:3])
    grad[:, 0:3] = np.einsum("bij,bi->bj", Jr, grad[:, 0:3])
    return cost, grad


def _lbfgs(
    pb: Problem, s0: ChainState
) -> tuple[ChainState, FloatArray, FloatArray, NDArray[np.int64]]:
    """scipy's L-BFGS-B (the thesis's solver, sec. 4.2.4) on the same objective, over the step
    from the start (:func:`step_cost_and_gradient`), every frame at once (independent frames:
    their costs add up), at most ``lbfgs_max_iterations`` iterations (the thesis: 25)."""
    from scipy.optimize import minimize

    B, n = s0.t.shape[0], pb.n_params
    cost0 = evaluate(pb, s0, jac=False)[2]

    def total(x: FloatArray) -> tuple[float, FloatArray]:
        cost, grad = step_cost_and_gradient(pb, s0, x.reshape(B, n))
        return float(cost.sum()), grad.ravel()

    result = minimize(
        total,
        np.zeros(B * n),
        jac=True,
        method="L-BFGS-B",
        options={"maxiter": pb.params.lbfgs_max_iterations, "ftol": 1e-12, "gtol": 1e-9},
    )
    s = retract(s0, result.x.reshape(B, n))
    cost = evaluate(pb, s, jac=False)[2]
    return s, cost0, cost, np.full(B, int(result.nit), dtype=np.int64)


def correct_poses(
    priors: Sequence[PoseState],
    measurements: Sequence[FrameMeasurements],
    skeleton: LowerBodySkeleton,
    params: PoseCorrectionParams | None = None,
) -> tuple[list[PoseState], CorrectionInfo]:
    """Correct a batch of independent frames (eq. 4.7, 4.8): one solve, vectorised over frames.

    Frame ``i`` starts from ``priors[i]`` (the predictor's pose; its ``trans`` a prior for the
    root position, weak by default) and is pulled towards ``measurements[i]``. Frames do not
    interact (with ``solver: lbfgs`` they share one L-BFGS-B solve over their summed cost, so
    its stopping test and iteration cap are the batch's); :func:`correct_pose` is the one-frame
    form used in the predict-correct loop.
    """
    params = params or PoseCorrectionParams()
    pb, s0 = _problem(priors, measurements, skeleton, params)
    solve = _lbfgs if params.solver == "lbfgs" else _levenberg_marquardt
    s, cost0, cost, iterations = solve(pb, s0)
    root, _ = log_and_right_jacobian_inv(s.R0)
    poses = [
        PoseState(pose=np.concatenate([root[i], s.a[i].ravel()]), trans=s.t[i])
        for i in range(len(priors))
    ]
    pts = chain_points(pb.geo, s)
    joints = np.stack(
        [pts["p0"], pts["hip"][:, 0], pts["hip"][:, 1], pts["knee"][:, 0], pts["knee"][:, 1]]
        + [pts["ankle"][:, 0], pts["ankle"][:, 1]],
        axis=1,
    )
    info = CorrectionInfo(
        cost_before=cost0,
        cost_after=cost,
        iterations=iterations,
        bone_lengths=s.l.copy(),
        joints=joints,
        foot_points=pts["foot"],
    )
    return poses, info


def correct_pose(
    prior: PoseState,
    measurements: FrameMeasurements,
    skeleton: LowerBodySkeleton,
    params: PoseCorrectionParams | None = None,
) -> tuple[PoseState, CorrectionInfo]:
    """Correct one frame (eq. 4.7, 4.8); :func:`correct_poses` with a batch of one."""
    poses, info = correct_poses([prior], [measurements], skeleton, params)
    return poses[0], info


def skeleton_with_lengths(skel: LowerBodySkeleton, lengths: FloatArray) -> LowerBodySkeleton:
    """``skel`` with thigh L, R and shank L, R set to ``lengths`` (4,) [m], directions kept.

    Forward kinematics of the corrected pose with this skeleton reproduces the solver's joints
    when the bone lengths were free; the foot joints move with their ankles.
    """
    lengths = np.asarray(lengths, dtype=np.float64)
    J = skel.rest_joints.copy()
    off = skel.offsets
    for side in (0, 1):
        knee = J[1 + side] + off[3 + side] * lengths[side] / np.linalg.norm(off[3 + side])
        ankle = knee + off[5 + side] * lengths[2 + side] / np.linalg.norm(off[5 + side])
        J[7 + side] = ankle + off[7 + side]
        J[3 + side], J[5 + side] = knee, ankle
    return from_rest_joints(J)
