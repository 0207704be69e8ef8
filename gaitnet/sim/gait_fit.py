"""The feet and the pelvis height of a walk, fitted to each other (used by :mod:`gait`).

Two rounds: the desired pelvis height follows the designed stance-knee flexion
(:func:`gaitnet.sim.gait_pelvis.stance_knee`); with the hips where it puts them each toe off gets
the heel-up pitch of the designed ankle angle (:func:`gaitnet.sim.gait_ankle.design_toe_off`),
each heel off moves earlier where the leg could not reach (:func:`gait_feet.adapt_heel_off`),
each swing's pitch is steered toward the designed ankle course
(:func:`gaitnet.sim.gait_ankle.swing_pitch_target`), and the height is fitted again to the new
feet, the last time constrained to the legs' reach.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from gaitnet.sim.gait_ankle import AnkleGeometry, design_toe_off, swing_pitch_target
from gaitnet.sim.gait_config import MAX_TO_PITCH_DEG, GaitConfig
from gaitnet.sim.gait_feet import (
    FootTrajectory,
    PitchTarget,
    adapt_heel_off,
    build_foot_trajectory,
)
from gaitnet.sim.gait_knee import StanceKnee, stance_knee
from gaitnet.sim.gait_legs import R_PfromSMPL
from gaitnet.sim.gait_pelvis import (
    PelvisGrid,
    PelvisParams,
    design_heights,
    fit_height,
    reach_bounds,
)
from gaitnet.sim.gait_plan import StepPlan
from gaitnet.sim.subject import Subject

__all__ = ["REACH_FRACTION", "fit_feet_and_height"]

DEG = np.pi / 180.0
REACH_FRACTION = 0.99995  # hip–ankle distance ≤ this × (thigh + shank): knee ≥ about 1°
_HEEL_RISE_MARGIN_M = 0.003  # the heel rises while the leg is still this far from the limit
_TERMINAL_SWING_KNEE_DEG = 15.0  # designed knee when the landing leg starts to count
_TRAILING_KNEE_DEG = 6.0  # ... and when the stance leg stops counting


def fit_feet_and_height(
    plan: StepPlan,
    grid: PelvisGrid,
    subject: Subject,
    cfg: GaitConfig,
    pp: PelvisParams,
    still: tuple[float, float],
) -> tuple[StepPlan, tuple[FootTrajectory, FootTrajectory], np.ndarray, np.ndarray]:
    """Heel-off times and the pelvis height, fitted to each other (two rounds).

    The desired height follows the designed stance-knee flexion (:func:`stance_knee`); each
    heel off moves earlier where that leg, once it no longer carries the body, could not reach
    the desired height; the height is fitted again to the new feet, the last time constrained
    to the reach bounds. Returns the final plan, feet, fitted height and per-leg reach bounds.
    """
    ankle_S = subject.ankle_in_shoe()
    skel = subject.skeleton()
    J = skel.rest_joints
    hips_in_P = (R_PfromSMPL @ (J[1:3] - J[0]).T).T
    thigh, shank = np.asarray(skel.thigh_lengths), np.asarray(skel.shank_lengths)
    reach = REACH_FRACTION * subject.leg_length_m
    design = StanceKnee(
        cfg.knee_extended_deg * DEG,
        cfg.knee_loading_deg * DEG,
        _TERMINAL_SWING_KNEE_DEG * DEG,
        _TRAILING_KNEE_DEG * DEG,
    )
    knee, weight = stance_knee(plan, grid.t, design)
    earliest = (cfg.heel_off_fraction - cfg.min_heel_off_fraction) / (
        cfg.heel_off_fraction - cfg.foot_flat_fraction
    )

    def fit(feet: tuple[FootTrajectory, FootTrajectory], final: bool) -> tuple[np.ndarray, ...]:
        ankles = _ankles(feet, grid.t, ankle_S)
        bounds = reach_bounds(grid, ankles, hips_in_P, reach)
        targets = design_heights(grid, ankles, hips_in_P, knee, thigh, shank)
        upper = np.min(bounds, axis=1)
        z, desired = fit_height(grid, targets, weight, upper, pp, still, constrained=final)
        return z, desired, bounds

    planned = plan.stances
    feet = _build_feet(plan, subject, cfg)
    _, desired, _ = fit(feet, final=False)
    geos = _ankle_geometry(subject)
    forward = grid.rotation()[:, :, 0]
    for final in (False, True):
        hips = grid.hips(desired, hips_in_P)
        designed = tuple(
            design_toe_off(
                planned[i],
                grid.t,
                hips[:, i],
                forward,
                geos[i],
                cfg.toe_off_ankle_deg * DEG,
                cfg.toe_off_pitch_deg * DEG,
                MAX_TO_PITCH_DEG * DEG,
            )
            for i in (0, 1)
        )
        left, right = (
            adapt_heel_off(
                designed[i],
                grid.t,
                hips[:, i],
                reach - _HEEL_RISE_MARGIN_M,
                subject.shoe_length_m,
                ankle_S,
                MAX_TO_PITCH_DEG * DEG,
                plan.t_first_move,
                earliest,
                checked=np.isnan(knee[:, i]),
            )
            for i in (0, 1)
        )
        plan = replace(plan, stances=(left, right))
        targets = tuple(
            _pitch_target(grid.t, hips[:, i], forward, geos[i], cfg, DEG) for i in (0, 1)
        )
        feet = _build_feet(plan, subject, cfg, targets)
        z_fit, desired, bounds = fit(feet, final)
    return plan, feet, z_fit, bounds


def _ankle_geometry(subject: Subject) -> tuple[AnkleGeometry, AnkleGeometry]:
    """Per leg: what :mod:`gaitnet.sim.gait_ankle` needs to design the ankle angles."""
    skel = subject.skeleton()
    J = skel.rest_joints
    ankle_S = subject.ankle_in_shoe()
    out = []
    for i in (0, 1):
        a, b = J[3 + i] - J[5 + i], J[7 + i] - J[5 + i]
        rest = float(np.arccos(a @ b / np.linalg.norm(a) / np.linalg.norm(b)))
        ball_S = ankle_S + R_PfromSMPL @ (J[7 + i] - J[5 + i])
        out.append(
            AnkleGeometry(
                float(skel.thigh_lengths[i]),
                float(skel.shank_lengths[i]),
                subject.shoe_length_m,
                ankle_S,
                ball_S,
                rest,
            )
        )
    return out[0], out[1]


def _pitch_target(
    t_grid: np.ndarray,
    hips: np.ndarray,
    forward: np.ndarray,
    geo: AnkleGeometry,
    cfg: GaitConfig,
    deg: float,
) -> PitchTarget:
    """The swing-pitch target of one leg with its hip and the pelvis axis on the grid."""

    def target(u: np.ndarray, t: np.ndarray, R: np.ndarray, p: np.ndarray) -> np.ndarray:
        h = np.stack([np.interp(t, t_grid, hips[:, k]) for k in range(3)], axis=-1)
        f = np.stack([np.interp(t, t_grid, forward[:, k]) for k in range(3)], axis=-1)
        return swing_pitch_target(
            u, R, p, h, f, geo, cfg.swing_ankle_deg * deg, cfg.push_off_ankle_deg * deg
        )

    return target


def _build_feet(
    plan: StepPlan,
    subject: Subject,
    cfg: GaitConfig,
    targets: tuple[PitchTarget, PitchTarget] | None = None,
) -> tuple[FootTrajectory, FootTrajectory]:
    left, right = (
        build_foot_trajectory(
            plan.stances[i],
            plan.stances[1 - i],
            subject.shoe_length_m,
            subject.shoe_width_m,
            cfg.toe_clearance_m,
            None if targets is None else targets[i],
        )
        for i in (0, 1)
    )
    return left, right


def _ankles(
    feet: tuple[FootTrajectory, FootTrajectory], t: np.ndarray, ankle_S: np.ndarray
) -> np.ndarray:
    """Both ankle joints (n, 2, 3) at times ``t``."""
    out = []
    for f in feet:
        R, p = f.pose(t)
        out.append(p + R @ ankle_S)
    return np.stack(out, axis=1)
