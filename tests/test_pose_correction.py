"""Pose correction (thesis eq. 4.7, 4.8; gaitnet.pipeline): Jacobians by central differences,
kinematics against gaitnet.motion, known answers, every parameter acting, bad input, and the
camera-to-pelvis extrinsic from standing frames."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from gaitnet.errors import InputError
from gaitnet.geometry import (
    so3_exp,
    so3_log,
    so3_right_jacobian,
    so3_right_jacobian_inv,
)
from gaitnet.motion import builtin_skeleton, forward_kinematics
from gaitnet.motion.heading import normalise_heading
from gaitnet.pipeline.pelvis_extrinsic import (
    complete_standing_feet,
    estimate_T_PfromC,
    pelvis_from_camera,
    standing_T_WfromP,
)
from gaitnet.pipeline.pose_correction import (
    _problem,
    correct_pose,
    correct_poses,
    skeleton_with_lengths,
    step_cost_and_gradient,
)
from gaitnet.pipeline.pose_residuals import (
    ChainGeometry,
    ChainState,
    chain_points,
    evaluate,
    exp_and_right_jacobian,
    log_and_right_jacobian_inv,
    retract,
)
from gaitnet.pipeline.pose_tracking import denormalise_root, track_poses
from gaitnet.pipeline.pose_types import (
    FrameMeasurements,
    PoseCorrectionParams,
    PoseState,
    R_PfromSMPL,
)

SKEL = builtin_skeleton(1.75)
# A walking-like pose facing +x: left hip flexed, right hip extended, knees bent.
JOINTS = np.array(
    [[-0.4, 0.05, 0.03], [0.2, -0.05, -0.04], [0.6, 0.0, 0.0], [0.2, 0.0, 0.0], [0.1, 0.0, 0.0]]
    + [[-0.1, 0.0, 0.0]]
)
ROOT = so3_log(R_PfromSMPL @ so3_exp([0.05, -0.03, 0.02]))
TRUE = PoseState(np.concatenate([ROOT, JOINTS.ravel()]), np.array([1.0, 0.5, 0.0]))


def model_points(pose: PoseState, params: PoseCorrectionParams) -> dict[str, np.ndarray]:
    """Pelvis pose and foot points of ``pose`` as the correction's model sees them."""
    geo = ChainGeometry.build(SKEL, params)
    s = ChainState(
        R0=so3_exp(pose.root_orient)[None],
        t=pose.trans[None],
        a=pose.joint_aa[None],
        l=geo.lengths[None].copy(),
    )
    pts = chain_points(geo, s)
    return {
        "R_WfromP": so3_exp(pose.root_orient) @ R_PfromSMPL.T,
        "p_PinW": pts["p0"][0],
        "foot": pts["foot"][0],
        "ankle": pts["ankle"][0],
    }


def exact_measurements(pose: PoseState, params: PoseCorrectionParams, **kw) -> FrameMeasurements:
    m = model_points(pose, params)
    return FrameMeasurements(m["R_WfromP"], m["p_PinW"], m["foot"], **kw)


def perturbed(pose: PoseState, rng: np.random.Generator, scale: float = 0.1) -> PoseState:
    return PoseState(pose.pose + rng.normal(0, scale, 21), pose.trans + rng.normal(0, 0.03, 3))


# --- rotations ------------------------------------------------------------------------------


@pytest.mark.parametrize("angle", [0.0, 1e-9, 1e-5, 1e-3, 0.3, 1.5, 2.0, 3.0])
def test_fused_exp_and_log_match_geometry(angle: float) -> None:
    rng = np.random.default_rng(1)
    axis = rng.normal(size=(4, 3))
    phi = axis / np.linalg.norm(axis, axis=1, keepdims=True) * angle
    R, Jr = exp_and_right_jacobian(phi)
    np.testing.assert_allclose(R, so3_exp(phi), atol=1e-12)
    np.testing.assert_allclose(Jr, so3_right_jacobian(phi), atol=1e-10)
    phi_back, Jinv = log_and_right_jacobian_inv(R)
    np.testing.assert_allclose(phi_back, so3_log(R), atol=1e-9)
    np.testing.assert_allclose(Jinv, so3_right_jacobian_inv(phi), atol=1e-8)


# --- kinematics and Jacobians -----------------------------------------------------------------


@pytest.mark.parametrize("fixed", [True, False])
def test_chain_matches_forward_kinematics(fixed: bool) -> None:
    rng = np.random.default_rng(2)
    geo = ChainGeometry.build(SKEL, PoseCorrectionParams(marker_offset=False))
    lengths = geo.lengths + (0 if fixed else rng.normal(0, 0.03, 4))
    pose = perturbed(TRUE, rng, 0.3)
    s = ChainState(
        so3_exp(pose.root_orient)[None], pose.trans[None], pose.joint_aa[None], lengths[None]
    )
    pts = chain_points(geo, s)
    fk = forward_kinematics(
        skeleton_with_lengths(SKEL, lengths), pose.root_orient, pose.trans, pose.smpl_joint_aa()
    )
    for name, rows in (("p0", [0]), ("hip", [1, 2]), ("knee", [3, 4]), ("ankle", [5, 6])):
        np.testing.assert_allclose(pts[name][0], fk[rows].squeeze(), atol=1e-12)


def test_marker_offset_is_fixed_in_the_ankle_frame() -> None:
    # With the skeleton's own ankle → foot-joint offset as the marker, the model's foot point
    # is the SMPL foot joint of forward kinematics (the built-in skeleton is mirror-symmetric).
    offset = SKEL.offsets[7]
    par = PoseCorrectionParams(marker_offset_m=tuple(offset))
    pose = perturbed(TRUE, np.random.default_rng(3), 0.3)
    fk = forward_kinematics(SKEL, pose.root_orient, pose.trans, pose.smpl_joint_aa())
    np.testing.assert_allclose(model_points(pose, par)["foot"], fk[7:9], atol=1e-12)


def _random_problem(par: PoseCorrectionParams, seed: int):
    rng = np.random.default_rng(seed)
    meas = FrameMeasurements(
        R_WfromP=so3_exp(rng.normal(0, 0.2, 3)),
        p_PinW=TRUE.trans + SKEL.rest_joints[0] + rng.normal(0, 0.05, 3),
        foot_W=model_points(TRUE, par)["foot"] + rng.normal(0, 0.08, (2, 3)),
        contact=[0.2, 1.0],
    )
    pb, s = _problem([perturbed(TRUE, rng)], [meas], SKEL, par)
    # Move away from the prior so every term has a nonzero residual.
    s = ChainState(
        s.R0 @ so3_exp(rng.normal(0, 0.2, 3)),
        s.t + rng.normal(0, 0.05, 3),
        s.a + rng.normal(0, 0.2, s.a.shape),
        s.l + rng.normal(0, 0.02, 4),
    )
    return pb, s


ALL_ON = dict(knee_hinge=True, rom_limits=True, robust_foot=False, marker_offset=True)
NARROW_ROM = tuple(tuple((-0.5, 0.5) for _ in range(3)) for _ in range(6))  # degrees: active


@pytest.mark.parametrize("fixed", [True, False])
@pytest.mark.parametrize("seed", [0, 1])
def test_residual_jacobian_central_differences(fixed: bool, seed: int) -> None:
    par = PoseCorrectionParams(fixed_lengths=fixed, rom_deg=NARROW_ROM, **ALL_ON)
    pb, s = _random_problem(par, seed)
    r, J, _ = evaluate(pb, s)
    n = J.shape[2]
    assert n == (24 if fixed else 28) and r.shape[1] == 36 + 4 + 18 + 4 + (0 if fixed else 4)
    h = 1e-6
    for k in range(n):
        d = np.zeros((1, n))
        d[0, k] = h
        numeric = (
            evaluate(pb, retract(s, d), False)[0] - evaluate(pb, retract(s, -d), False)[0]
        ) / (2 * h)
        np.testing.assert_allclose(
            J[0, :, k],
            numeric[0],
            atol=1e-6,
            err_msg=f"column {k}",
        )


@pytest.mark.parametrize("fixed", [True, False])
def test_robust_gradient_central_differences(fixed: bool) -> None:
    # With the Cauchy loss the re-weighted residuals give the exact gradient 2 Jᵀr of the cost.
    par = PoseCorrectionParams(fixed_lengths=fixed, robust_foot=True, cauchy_scale_m=0.03)
    pb, s = _random_problem(par, 5)
    r, J, cost = evaluate(pb, s)
    grad = 2 * J[0].T @ r[0]
    h = 1e-6
    for k in range(J.shape[2]):
        d = np.zeros((1, J.shape[2]))
        d[0, k] = h
        numeric = (
            evaluate(pb, retract(s, d), False)[2] - evaluate(pb, retract(s, -d), False)[2]
        ) / (2 * h)
        assert grad[k] == pytest.approx(numeric[0], rel=1e-5, abs=1e-3 * max(1.0, cost[0]) ** 0.5)


@pytest.mark.parametrize("fixed", [True, False])
def test_lbfgs_gradient_over_the_step_central_differences(fixed: bool) -> None:
    """The L-BFGS solver's gradient over the step from the start, at a step that turns the root
    by 0.5 rad (where the root's right Jacobian matters), against central differences."""
    par = PoseCorrectionParams(fixed_lengths=fixed, robust_foot=True, cauchy_scale_m=0.03)
    pb, s = _random_problem(par, 7)
    n = pb.n_params
    step = np.random.default_rng(3).normal(0, 0.05, (1, n))
    step[0, :3] = [0.3, -0.3, 0.2]
    cost, grad = step_cost_and_gradient(pb, s, step)
    h = 1e-6
    for k in range(n):
        d = np.zeros((1, n))
        d[0, k] = h
        numeric = (
            step_cost_and_gradient(pb, s, step + d)[0] - step_cost_and_gradient(pb, s, step - d)[0]
        ) / (2 * h)
        assert grad[0, k] == pytest.approx(
            numeric[0], rel=1e-5, abs=1e-3 * max(1.0, cost[0]) ** 0.5
        )


def test_lbfgs_reaches_the_levenberg_marquardt_minimum() -> None:
    """Both solvers minimise the same objective: given iterations enough, L-BFGS ends where
    Levenberg–Marquardt does."""
    prior, m = _scenario()
    tight = PoseCorrectionParams(max_iterations=200, cost_tolerance=1e-14, step_tolerance=1e-12)
    lm, info_lm = correct_pose(prior, m, SKEL, tight)
    lbfgs, info_bfgs = correct_pose(
        prior, m, SKEL, PoseCorrectionParams(solver="lbfgs", lbfgs_max_iterations=2000)
    )
    assert info_bfgs.cost_after[0] == pytest.approx(info_lm.cost_after[0], rel=1e-6)
    assert info_bfgs.cost_after[0] < 0.5 * info_bfgs.cost_before[0]
    np.testing.assert_allclose(lbfgs.pose, lm.pose, atol=1e-4)
    np.testing.assert_allclose(lbfgs.trans, lm.trans, atol=1e-5)


# --- known answers --------------------------------------------------------------------------


def test_pose_satisfying_every_measurement_stays_put() -> None:
    par = PoseCorrectionParams()  # no contact given: TRUE's feet are not flat
    out, info = correct_pose(TRUE, exact_measurements(TRUE, par), SKEL, par)
    np.testing.assert_allclose(out.pose, TRUE.pose, atol=1e-9)
    np.testing.assert_allclose(out.trans, TRUE.trans, atol=1e-12)
    assert info.cost_before[0] == pytest.approx(0, abs=1e-18)


def test_root_offset_is_removed_by_the_weighted_mean() -> None:
    # Pelvis position only, no feet: the translation is the weighted mean of prior and measurement
    # (weights 1/σ²), by hand: (t̄/0.1² + t̃/0.02²) / (1/0.1² + 1/0.02²). Tight tolerance.
    par = PoseCorrectionParams(cost_tolerance=1e-14)
    prior = PoseState(TRUE.pose, TRUE.trans + [0.05, -0.02, 0.03])
    m = FrameMeasurements(p_PinW=SKEL.rest_joints[0] + TRUE.trans)
    out, _ = correct_pose(prior, m, SKEL, par)
    expected = (prior.trans / 0.1**2 + TRUE.trans / 0.02**2) / (1 / 0.1**2 + 1 / 0.02**2)
    np.testing.assert_allclose(out.trans, expected, atol=1e-9)
    np.testing.assert_allclose(out.pose, prior.pose, atol=1e-9)
    # Everything measured (pelvis and both feet, σ 2 cm against the prior's 10 cm): ≥ 95 % goes.
    out, _ = correct_pose(prior, exact_measurements(TRUE, par), SKEL, par)
    assert np.linalg.norm(out.trans - TRUE.trans) < 0.05 * np.linalg.norm(prior.trans - TRUE.trans)


def test_root_rotation_is_the_weighted_geodesic_mean() -> None:
    # Prior and measurement differ by a rotation about one axis: the result lies on it, at the
    # weighted mean angle (1/σ² weights), by hand 0.1 · (1/0.02²) / (1/0.1² + 1/0.02²).
    par = PoseCorrectionParams(cost_tolerance=1e-14)
    axis = np.array([0.0, 0.0, 1.0])
    R_meas = so3_exp(TRUE.root_orient) @ so3_exp(0.1 * axis)
    m = FrameMeasurements(R_WfromP=R_meas @ R_PfromSMPL.T)
    out, _ = correct_pose(TRUE, m, SKEL, par)
    rel = so3_log(so3_exp(TRUE.root_orient).T @ so3_exp(out.root_orient))
    np.testing.assert_allclose(rel, 0.1 * axis / (1 + 0.02**2 / 0.1**2), atol=1e-9)


def test_foot_measurement_pulls_the_ankle_chain_of_its_leg_only() -> None:
    par = PoseCorrectionParams(sigma_foot_m=0.001, robust_foot=False)
    m0 = model_points(TRUE, par)
    foot = m0["foot"].copy()
    foot[0] += [0.04, 0.0, 0.02]
    m = FrameMeasurements(m0["R_WfromP"], m0["p_PinW"], np.array([foot[0], [np.nan] * 3]))
    out, info = correct_pose(TRUE, m, SKEL, par)
    assert np.linalg.norm(info.foot_points[0, 0] - foot[0]) < 0.002  # reached
    moved = np.abs(out.joint_aa - TRUE.joint_aa).max(axis=1)
    assert moved[0] > 0.01 and moved[2] > 1e-3  # left hip and knee rotate
    np.testing.assert_allclose(out.joint_aa[[1, 3, 5]], TRUE.joint_aa[[1, 3, 5]], atol=1e-9)


def test_with_one_foot_visible_the_other_leg_follows_the_prior() -> None:
    par = PoseCorrectionParams()
    rng = np.random.default_rng(7)
    prior = perturbed(TRUE, rng, 0.05)
    prior = PoseState(np.where(np.isin(np.arange(21), [13, 14]), 0.0, prior.pose), prior.trans)
    m_all = exact_measurements(TRUE, par)
    foot = m_all.foot_W.copy()
    foot[1] = np.nan
    out, _ = correct_pose(prior, FrameMeasurements(m_all.R_WfromP, m_all.p_PinW, foot), SKEL, par)
    np.testing.assert_allclose(out.joint_aa[[1, 3, 5]], prior.joint_aa[[1, 3, 5]], atol=1e-9)
    assert np.abs(out.joint_aa[[0, 2, 4]] - prior.joint_aa[[0, 2, 4]]).max() > 1e-3


def test_bone_lengths_fixed_or_free() -> None:
    far = exact_measurements(TRUE, PoseCorrectionParams())
    foot = far.foot_W + [0.0, 0.0, -0.15]  # below reach of a straight leg
    m = FrameMeasurements(far.R_WfromP, far.p_PinW, foot)
    for fixed in (True, False):
        par = PoseCorrectionParams(fixed_lengths=fixed, robust_foot=False)
        _, info = correct_pose(TRUE, m, SKEL, par)
        j = info.joints[0]
        thigh = np.linalg.norm(j[3:5] - j[1:3], axis=1)
        shank = np.linalg.norm(j[5:7] - j[3:5], axis=1)
        np.testing.assert_allclose(np.r_[thigh, shank], info.bone_lengths[0], atol=1e-12)
        skel_l = np.r_[SKEL.thigh_lengths, SKEL.shank_lengths]
        if fixed:
            np.testing.assert_allclose(info.bone_lengths[0], skel_l, atol=1e-12)
        else:
            assert np.all(info.bone_lengths[0] > skel_l + 1e-3)  # stretched towards the feet


def test_cauchy_loss_down_weights_an_outlier_foot_point() -> None:
    m0 = exact_measurements(TRUE, PoseCorrectionParams())
    foot = m0.foot_W + [[0.3, 0.0, 0.0], [0.0, 0.0, 0.0]]  # left foot point 30 cm off
    m = FrameMeasurements(m0.R_WfromP, m0.p_PinW, foot)
    shift = {}
    for robust in (False, True):
        # Prior σ 0.05 rad: reaching 30 cm costs more than the Cauchy term of staying put.
        par = PoseCorrectionParams(robust_foot=robust, sigma_prior_joint_rad=0.05)
        _, info = correct_pose(TRUE, m, SKEL, par)
        shift[robust] = np.linalg.norm(info.foot_points[0, 0] - m0.foot_W[0])
    # The Cauchy pull at 30 cm is 1/37 of the quadratic one (c = 5 cm), not zero: the leg stops
    # well short of the outlier, the quadratic loss follows it.
    assert shift[False] > 0.2
    assert shift[True] < 0.5 * shift[False]


def test_cauchy_weights_are_the_square_root_of_rho_prime() -> None:
    # Each foot residual is scaled by 1 / sqrt(1 + d²/c²) (IRLS), the cost is w² c² log(1 + d²/c²).
    m0 = exact_measurements(TRUE, PoseCorrectionParams())
    d = np.array([0.3, 0.01])
    foot = m0.foot_W + np.c_[d, [0, 0], [0, 0]]
    m = FrameMeasurements(m0.R_WfromP, m0.p_PinW, foot)
    plain = PoseCorrectionParams(robust_foot=False, knee_hinge=False, rom_limits=False)
    robust = dataclasses.replace(plain, robust_foot=True)
    (pb0, s0), (pb1, s1) = (_problem([TRUE], [m], SKEL, p) for p in (plain, robust))
    r0, _, c0 = evaluate(pb0, s0)
    r1, _, c1 = evaluate(pb1, s1)
    scale = 1 / np.sqrt(1 + d**2 / 0.05**2)
    np.testing.assert_allclose(r1[0, 30:36], r0[0, 30:36] * np.repeat(scale, 3), atol=1e-12)
    w = 1 / 0.02
    np.testing.assert_allclose(c1, np.sum(w**2 * 0.05**2 * np.log1p(d**2 / 0.05**2)), rtol=1e-12)
    np.testing.assert_allclose(c0, np.sum(w**2 * d**2), rtol=1e-12)


def test_contact_weighting_pulls_a_stance_foot_harder() -> None:
    m0 = exact_measurements(TRUE, PoseCorrectionParams())
    foot = m0.foot_W + [[0.05, 0.0, 0.0], [0.05, 0.0, 0.0]]
    dist = {}
    for contact in ([0.0, 0.0], [1.0, 1.0]):
        m = FrameMeasurements(m0.R_WfromP, m0.p_PinW, foot, contact)
        _, info = correct_pose(TRUE, m, SKEL, PoseCorrectionParams(contact_weighting=True))
        dist[contact[0]] = np.linalg.norm(info.foot_points[0] - foot, axis=1)
    assert np.all(dist[1.0] < 0.8 * dist[0.0])


def test_flat_foot_contact_levels_a_stance_foot() -> None:
    # The prior's right ankle is pitched 20° and rolled 10°; the right foot is in stance (contact
    # 1) and measured: with the term its sole comes level (forward and left axes horizontal).
    pose = TRUE.pose.copy()
    pose[18:21] = np.radians([20.0, 0.0, 10.0])
    prior = PoseState(pose, TRUE.trans)
    m0 = exact_measurements(prior, PoseCorrectionParams())
    tilt = {}
    for on in (False, True):
        par = PoseCorrectionParams(flat_foot_contact=on)
        out, _ = correct_pose(
            prior, FrameMeasurements(m0.R_WfromP, m0.p_PinW, m0.foot_W, [0, 1]), SKEL, par
        )
        geo = ChainGeometry.build(SKEL, par)
        st = ChainState(
            so3_exp(out.root_orient)[None], out.trans[None], out.joint_aa[None], geo.lengths[None]
        )
        G = chain_points(geo, st)["G_ank"][0]
        tilt[on] = np.abs(G[:, 2, 0::2])  # world-up parts of left / forward axes, per side
    assert tilt[False][1].max() > 0.1
    assert tilt[True][1].max() < 0.2 * tilt[False][1].max()
    # The left foot (no contact) keeps its tilt but for the shared root's small turn.
    np.testing.assert_allclose(tilt[True][0], tilt[False][0], atol=0.05)


def test_batch_equals_frame_by_frame_and_no_measurement_keeps_the_prior() -> None:
    rng = np.random.default_rng(9)
    par = PoseCorrectionParams()
    priors = [perturbed(TRUE, rng) for _ in range(3)]
    meas = [
        exact_measurements(TRUE, par),
        FrameMeasurements(),
        exact_measurements(TRUE, par, contact=[1, 1]),
    ]
    batch, _ = correct_poses(priors, meas, SKEL, par)
    for p, m, b in zip(priors, meas, batch, strict=True):
        one, _ = correct_pose(p, m, SKEL, par)
        np.testing.assert_allclose(b.pose, one.pose, atol=1e-10)
        np.testing.assert_allclose(b.trans, one.trans, atol=1e-12)
    # No measurements: only the hinge and ROM terms act; without the hinge (the prior's knees
    # have y, z rotations) and inside the ROM the prior comes back unchanged.
    free, _ = correct_pose(
        priors[1], FrameMeasurements(), SKEL, PoseCorrectionParams(knee_hinge=False)
    )
    np.testing.assert_allclose(free.pose, priors[1].pose, atol=1e-12)
    assert np.all(np.isfinite(batch[1].pose))


# --- every parameter acts --------------------------------------------------------------------


def _scenario() -> tuple[PoseState, FrameMeasurements]:
    """A prior violating the hinge and ROM, measurements partly off, one outlier-ish foot."""
    pose = TRUE.pose.copy()
    pose[9:11] = [-0.4, 0.2]  # left knee hyperextended (ROM) with y rotation (hinge)
    prior = PoseState(pose, TRUE.trans + [0.02, 0.0, 0.0])
    m0 = exact_measurements(TRUE, PoseCorrectionParams())
    foot = m0.foot_W + [[0.12, 0.0, 0.0], [0.0, 0.03, 0.0]]
    R = m0.R_WfromP @ so3_exp([0.0, 0.0, 0.05])
    return prior, FrameMeasurements(R, m0.p_PinW + 0.01, foot, [0.5, 1.0])


CHANGES = {
    "sigma_prior_joint_rad": 0.03,
    "sigma_prior_root_rad": 0.03,
    "sigma_prior_trans_m": 0.01,
    "sigma_root_rot_rad": 0.1,
    "sigma_root_pos_m": 0.1,
    "sigma_foot_m": 0.05,
    "sigma_bone_m": 0.001,
    "fixed_lengths": False,
    "knee_hinge": False,
    "sigma_hinge_rad": 0.1,
    "rom_limits": False,
    "sigma_rom_rad": 0.1,
    "rom_deg": tuple(tuple((-60.0, 60.0) for _ in range(3)) for _ in range(6)),
    "robust_foot": False,
    "cauchy_scale_m": 0.2,
    "contact_weighting": True,
    "contact_gain": 10.0,
    "marker_offset": False,
    "marker_offset_m": (0.0, 0.0, 0.12),
    "flat_foot_contact": False,
    "sigma_flat_rad": 0.5,
    "max_iterations": 1,
    "step_tolerance": 1.0,
    "cost_tolerance": 0.5,
    "solver": "lbfgs",
    "lbfgs_max_iterations": 1,
}
# Keys that only act together with another switch.
NEEDS = {
    "sigma_bone_m": {"fixed_lengths": False},
    "contact_gain": {"contact_weighting": True},
    "lbfgs_max_iterations": {"solver": "lbfgs"},
}


def test_every_parameter_is_tested() -> None:
    assert set(CHANGES) == {f.name for f in dataclasses.fields(PoseCorrectionParams)}


@pytest.mark.parametrize("key", sorted(CHANGES))
def test_each_parameter_acts(key: str) -> None:
    prior, m = _scenario()
    base = PoseCorrectionParams(**NEEDS.get(key, {}))
    changed = dataclasses.replace(base, **{key: CHANGES[key]})
    a, info_a = correct_pose(prior, m, SKEL, base)
    b, info_b = correct_pose(prior, m, SKEL, changed)
    diff = max(np.abs(a.pose - b.pose).max(), np.abs(a.trans - b.trans).max())
    assert diff > 1e-6 or info_a.iterations[0] != info_b.iterations[0], key


def test_hinge_and_rom_act_as_described() -> None:
    prior, m = _scenario()
    off, _ = correct_pose(prior, m, SKEL, PoseCorrectionParams(knee_hinge=False, rom_limits=False))
    on, _ = correct_pose(prior, m, SKEL, PoseCorrectionParams())
    assert abs(off.joint_aa[2, 1]) > 0.1 and abs(on.joint_aa[2, 1]) < 0.01  # hinge: no y
    low = np.radians(-10.0)  # the knee's extension limit
    assert low - on.joint_aa[2, 0] < 0.2 * (low - off.joint_aa[2, 0])  # ROM: ≥ 80 % undone


def test_thesis_preset_switches_every_extension_off() -> None:
    par = PoseCorrectionParams.thesis()
    assert not any(
        [par.fixed_lengths, par.knee_hinge, par.rom_limits, par.robust_foot]
        + [par.contact_weighting, par.marker_offset, par.flat_foot_contact]
    )
    assert PoseCorrectionParams.thesis(knee_hinge=True).knee_hinge


# --- bad input ------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "make",
    [
        lambda: PoseState(np.zeros(20), np.zeros(3)),
        lambda: PoseState(np.full(21, np.nan), np.zeros(3)),
        lambda: FrameMeasurements(R_WfromP=np.eye(3) * 2),
        lambda: FrameMeasurements(p_PinW=[0, 0, np.inf]),
        lambda: FrameMeasurements(foot_W=[[0, 0, np.nan], [0, 0, 0]]),
        lambda: FrameMeasurements(contact=[0.5, 1.5]),
        lambda: PoseCorrectionParams(sigma_foot_m=0.0),
        lambda: PoseCorrectionParams(cauchy_scale_m=-1.0),
        lambda: PoseCorrectionParams(contact_gain=float("nan")),
        lambda: PoseCorrectionParams(marker_offset_m=(0.0, 1.0)),  # type: ignore[arg-type]
        lambda: PoseCorrectionParams(rom_deg=((10.0, -10.0),) * 3),  # type: ignore[arg-type]
        lambda: PoseCorrectionParams(max_iterations=0),
        lambda: correct_poses([], [], SKEL),
        lambda: correct_poses([TRUE], [FrameMeasurements(), FrameMeasurements()], SKEL),
    ],
)
def test_bad_input_raises_one_line_input_error(make) -> None:
    with pytest.raises(InputError) as exc:
        make()
    assert "\n" not in str(exc.value)


# --- camera-to-pelvis extrinsic -------------------------------------------------------------


def _mount() -> np.ndarray:
    """Camera 17 cm in front of and 5 cm above the pelvis, looking forward and 40° down."""
    R_PfromC_level = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    T = np.eye(4)
    T[:3, :3] = so3_exp([0.0, np.radians(40), 0.0]) @ R_PfromC_level
    T[:3, 3] = [0.17, 0.0, 0.05]
    return T


STANDING_YAW = 0.7


def _standing_body(par: PoseCorrectionParams) -> tuple[np.ndarray, np.ndarray]:
    """A straight-legged body standing at (2, −1) facing yaw :data:`STANDING_YAW`: its pelvis
    pose ``T_WfromP`` (4, 4) and its foot points (2, 3) as the correction's model sees them."""
    R_WfromP = so3_exp([0.0, 0.0, STANDING_YAW])
    standing = PoseState(
        np.r_[so3_log(R_WfromP @ R_PfromSMPL), np.zeros(18)], np.array([2.0, -1.0, 0.0])
    )
    pts = model_points(standing, par)
    T_WfromP = np.eye(4)
    T_WfromP[:3, :3], T_WfromP[:3, 3] = R_WfromP, pts["p_PinW"]
    return T_WfromP, pts["foot"]


@pytest.mark.parametrize("yaw_from", ["camera", "feet"])
def test_extrinsic_from_standing_frames_known_answer(yaw_from: str) -> None:
    par = PoseCorrectionParams()
    T_WfromP, feet = _standing_body(par)
    cams = np.stack([T_WfromP @ _mount()] * 5)
    T_est = standing_T_WfromP(SKEL, feet, cams[0], params=par, yaw_from=yaw_from)  # type: ignore[arg-type]
    np.testing.assert_allclose(T_est, T_WfromP, atol=1e-10)
    ext = estimate_T_PfromC(cams, T_est)
    np.testing.assert_allclose(ext.T_PfromC, _mount(), atol=1e-10)
    assert ext.spread_pos_m < 1e-12 and ext.n_frames == 5
    np.testing.assert_allclose(
        pelvis_from_camera(cams, ext.T_PfromC), np.stack([T_WfromP] * 5), atol=1e-10
    )


def test_extrinsic_averages_noisy_frames() -> None:
    rng = np.random.default_rng(4)
    T_WfromP = np.eye(4)
    T_WfromP[:3, 3] = [0.0, 0.0, 0.95]
    cams = []
    for _ in range(200):
        T = T_WfromP @ _mount()
        T[:3, :3] = T[:3, :3] @ so3_exp(rng.normal(0, 0.01, 3))
        T[:3, 3] += rng.normal(0, 0.005, 3)
        cams.append(T)
    ext = estimate_T_PfromC(np.stack(cams), T_WfromP)
    err = so3_log(ext.T_PfromC[:3, :3].T @ _mount()[:3, :3])
    assert (
        np.linalg.norm(err) < 0.003
        and np.linalg.norm(ext.T_PfromC[:3, 3] - _mount()[:3, 3]) < 0.002
    )
    assert 0.01 < ext.spread_rot_rad < 0.025 and 0.005 < ext.spread_pos_m < 0.012


def test_extrinsic_bad_input() -> None:
    with pytest.raises(InputError):
        estimate_T_PfromC(np.zeros((0, 4, 4)), np.eye(4))
    with pytest.raises(InputError):
        standing_T_WfromP(SKEL, np.full((2, 3), np.nan), np.eye(4))
    with pytest.raises(InputError):
        standing_T_WfromP(SKEL, np.zeros((2, 3)), None, yaw_from="camera")
    with pytest.raises(InputError):
        standing_T_WfromP(SKEL, np.zeros((2, 3)), np.eye(4), yaw_from="up")  # type: ignore[arg-type]


def test_unseen_standing_feet_are_placed_from_the_skeleton_and_the_camera() -> None:
    par = PoseCorrectionParams()
    T_WfromP, feet = _standing_body(par)
    cam = T_WfromP @ _mount()  # the mount has no yaw: the camera heads along the pelvis's x
    same, note = complete_standing_feet(feet, SKEL, cam, 0.05, 0.1, par)
    np.testing.assert_array_equal(same, feet)
    assert note is None
    for lost in (0, 1):  # one foot lost: placed where the skeleton's other foot is
        partial = feet.copy()
        partial[lost] = np.nan
        placed, note = complete_standing_feet(partial, SKEL, cam, 0.05, 0.1, par)
        np.testing.assert_allclose(placed, feet, atol=1e-12)
        assert note is not None and ("left", "right")[lost] in note
    # neither seen: the midpoint lies behind_camera_m behind the camera, on its heading
    heading = np.array([np.cos(STANDING_YAW), np.sin(STANDING_YAW), 0.0])
    for behind in (0.1, 0.25):
        placed, note = complete_standing_feet(np.full((2, 3), np.nan), SKEL, cam, 0.05, behind, par)
        middle = placed.mean(axis=0)
        np.testing.assert_allclose(middle[:2], cam[:2, 3] - behind * heading[:2], atol=1e-12)
        np.testing.assert_allclose(placed[:, 2], 0.05)
        np.testing.assert_allclose(placed[0] - placed[1], feet[0] - feet[1], atol=1e-12)
        assert note is not None and f"{behind:.2f} m" in note
        # the standing pelvis over them is the true one moved as the feet's midpoint moved
        T_est = standing_T_WfromP(SKEL, placed, cam, params=par)
        shift = T_est[:3, 3] - T_WfromP[:3, 3]
        np.testing.assert_allclose(shift, middle - feet.mean(axis=0), atol=1e-12)
    with pytest.raises(InputError):
        complete_standing_feet(np.zeros((3, 3)), SKEL, cam, 0.05, 0.1, par)


# --- predict-correct loop -------------------------------------------------------------------


def test_track_poses_resamples_the_window_to_the_predictors_rate() -> None:
    """A body whose joints turn at a constant rate, frames 1, 2 and 3.5 predictor steps apart,
    and a predictor that carries the window's last step on: with the frame times, the window
    is the motion sampled one predictor step apart and every prior is the truth at the frame's
    time (so is every corrected pose); one step apart, the same as frame by frame. (No
    hinge or range-of-motion terms: the made-up motion turns every joint about every axis.)"""
    par = PoseCorrectionParams(knee_hinge=False, rom_limits=False)
    dt = 1 / 30
    rate = np.zeros(21)
    rate[3:] = 0.4 * np.sin(np.arange(18))  # rad/s on every joint axis
    v = np.array([1.1, 0.2, 0.0])

    def truth(t: float) -> PoseState:
        return PoseState(TRUE.pose + rate * t, TRUE.trans + v * t)

    windows: list[np.ndarray] = []

    def carry_on(window: np.ndarray) -> np.ndarray:
        windows.append(window)
        step = window[-1] - window[-2]
        return np.stack([window[-1] + k * step for k in range(1, 5)])

    start = [truth(-k * dt) for k in (3, 2, 1)]
    for spacing in (1.0, 2.0, 3.5):
        t_s = spacing * dt * np.arange(6)
        frames = [exact_measurements(truth(t), par) for t in t_s]
        windows.clear()
        out, priors = track_poses(carry_on, start, frames, SKEL, par, t_s, dt)
        for w in windows:
            step = np.broadcast_to(rate[3:] * dt, (len(w) - 1, 18))
            np.testing.assert_allclose(np.diff(w[:, 3:], axis=0), step, atol=1e-9)
        for o, prior, t in zip(out, priors, t_s, strict=True):
            np.testing.assert_allclose(prior.pose[3:], truth(t).pose[3:], atol=1e-9)
            np.testing.assert_allclose(prior.trans, truth(t).trans, atol=1e-12)
            np.testing.assert_allclose(o.pose, truth(t).pose, atol=1e-7)
    # frames exactly one step apart: the same as frame by frame without times
    t_s = dt * np.arange(6)
    frames = [exact_measurements(truth(t), par) for t in t_s]
    timed, _ = track_poses(carry_on, start, frames, SKEL, par, t_s, dt)
    by_frame, _ = track_poses(carry_on, start, frames, SKEL, par)
    for a, b in zip(timed, by_frame, strict=True):
        np.testing.assert_allclose(a.pose, b.pose, atol=1e-9)
        np.testing.assert_allclose(a.trans, b.trans, atol=1e-12)
    with pytest.raises(InputError, match="frame times"):
        track_poses(carry_on, start, frames, SKEL, par, t_s[::-1], dt)
    with pytest.raises(InputError, match="frame times"):
        track_poses(carry_on, start, iter(frames), SKEL, par, t_s[:3], dt)


def test_denormalise_root_undoes_heading_normalisation() -> None:
    rng = np.random.default_rng(11)
    root = np.stack([so3_log(so3_exp([0, 0, y]) @ R_PfromSMPL) for y in rng.uniform(-3, 3, 5)])
    trans = rng.normal(size=(5, 3))
    root_n, _, yaw = normalise_heading(root, trans, 4)
    np.testing.assert_allclose(
        so3_exp(denormalise_root(root_n[4], yaw)), so3_exp(root[4]), atol=1e-12
    )


def test_track_poses_known_answers() -> None:
    # A constant-pose predictor (returns the last normalised pose) and exact measurements of a
    # body walking at constant velocity: every prior and every corrected pose is the truth.
    par = PoseCorrectionParams()
    v = np.array([0.04, 0.01, 0.0])
    truth = [PoseState(TRUE.pose, TRUE.trans + k * v) for k in range(8)]
    seen = []

    def last(window: np.ndarray) -> np.ndarray:
        seen.append(window.shape)
        return window[-1]

    out, priors = track_poses(
        last, truth[:3], [exact_measurements(p, par) for p in truth[3:]], SKEL, par
    )
    assert seen == [(3, 21)] * 5
    for o, p, t in zip(out, priors, truth[3:], strict=True):
        np.testing.assert_allclose(so3_exp(p.root_orient), so3_exp(t.root_orient), atol=1e-9)
        np.testing.assert_allclose(p.trans, t.trans, atol=1e-12)  # constant-velocity prior
        np.testing.assert_allclose(o.pose, t.pose, atol=1e-8)
        np.testing.assert_allclose(o.trans, t.trans, atol=1e-9)
    with pytest.raises(InputError):
        track_poses(last, truth[:1], [], SKEL, par)
    with pytest.raises(InputError):
        track_poses(lambda w: np.zeros(5), truth[:3], [FrameMeasurements()], SKEL, par)
