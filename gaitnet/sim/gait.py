"""Footstep-driven walking with full ground truth: shoes, legs, pelvis, SMPL pose, gait events.

:func:`generate_walk` plans the footsteps (:mod:`gaitnet.sim.gait_plan`), builds each shoe's
trajectory with heel and toe rockers and a C² swing (:mod:`gaitnet.sim.gait_feet`), a C²+
pelvis trajectory whose height follows designed stance-knee angles and keeps both ankles
within reach (:mod:`gaitnet.sim.gait_pelvis`), and places the knees by two-link IK
(:mod:`gaitnet.sim.gait_legs`). The returned :class:`Walk` evaluates everything at arbitrary
times.

Conventions:
- world: z up, floor z = 0, the walk starts at x ≈ 0 heading +x, left foot at +y;
- pelvis frame P: origin at the SMPL pelvis joint, x forward, y left, z up;
- shoe frame (:mod:`gaitnet.sim.scene`): origin at the sole centre, x toe, y left, z up; the
  ankle joint is the fixed point :meth:`Subject.ankle_in_shoe` and the SMPL foot joint the fixed
  point ``ankle + R_PfromSMPL (J_foot − J_ankle)`` of that frame;
- SMPL pose: ``root_orient = log(R_WfromP R_PfromSMPL)`` (an upright subject facing +x has
  ``R_root`` columns [0,1,0], [0,0,1], [1,0,0]), ``trans = p_pelvis − J_rest[pelvis]``, local
  axis-angles for SMPL joints 1, 2, 4, 5, 7, 8, 10, 11 (the foot joints' are zero), so that
  ``forward_kinematics(subject.skeleton(), ...)`` reproduces :meth:`Walk.joints`.

Step length from speed: ``step = ratio · H · (v / 1.3 m/s)^exponent`` with ratio 0.40 (the
often-quoted "step ≈ 0.41 H" at a normal 1.3 m/s) and exponent 0.5, so a 1.75 m subject at
1.2–1.4 m/s walks at about 105–115 steps/min with 1.35–1.45 m strides.

Knees (textbook values, docs/references.md, *Normal adult walking*): the pelvis height is
derived from the legs, not the other way round. The leg that carries the body has a designed
knee flexion — ``knee_extended_deg`` (3°) at heel strike and in mid-stance, a
``knee_loading_deg`` (17°) loading-response peak at 13 % of the cycle — and the pelvis height
is the smooth curve closest to the heights at which the legs have those angles
(:func:`gait_knee.stance_knee`); the swing knee, the trailing knee in pre-swing and every
knee angle then follow by IK. Standing, both knees are at ``knee_extended_deg``.
``REACH_FRACTION`` (knee ≥ about 1°) only guards the IK. For a 1.75 m subject at 1.3 m/s this
gives a knee of about 5–7° at heel strike, 18° in loading response, 5° in mid-stance, 38° at
toe off and 60° in swing, and a pelvis vertical excursion of 3–4.5 cm per step.

Heel off adapts to the legs: it moves earlier (down to ``min_heel_off_fraction`` of the cycle)
when the trailing leg would otherwise run out of reach of the desired pelvis height, as a real
heel rises when the leg is straight.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from gaitnet.motion.skeleton import LowerBodySkeleton
from gaitnet.sim.gait_config import GaitConfig
from gaitnet.sim.gait_feet import (
    FootTrajectory,
)
from gaitnet.sim.gait_fit import REACH_FRACTION, fit_feet_and_height
from gaitnet.sim.gait_legs import R_PfromSMPL, leg_chain, smpl_pose_from_chain
from gaitnet.sim.gait_pelvis import (
    PelvisParams,
    PelvisTrajectory,
    build_pelvis,
    motion_end_time,
    pelvis_grid,
)
from gaitnet.sim.gait_plan import FootStance, StepPlan, WalkPath, WalkVariation, plan_steps
from gaitnet.sim.gait_style import REFERENCE_SPEED_MPS, SpeedLaws, sample_sway, speed_laws
from gaitnet.sim.scene import SIDES, BodyState, LegSegment, ShoeState, Side
from gaitnet.sim.subject import Subject

__all__ = [
    "REACH_FRACTION",
    "FootEvents",
    "GaitConfig",
    "ShoeTrajectory",
    "StepEvents",
    "Walk",
    "generate_walk",
    "walk_laws",
]

DEG = np.pi / 180.0
_HEIGHT_FIT_S = 0.05  # smoothing scale of the pelvis height at up to REFERENCE_SPEED_MPS


class ShoeTrajectory(NamedTuple):
    """Shoe poses of one side at ``n`` times."""

    R_WfromShoe: np.ndarray  # (n, 3, 3)
    p_SoleCentre_W: np.ndarray  # (n, 3)


@dataclass(frozen=True, eq=False)
class FootEvents:
    """Gait events and foot-flat placements of one foot, one row per stance.

    The first stance (standing at the start) has no HS/FF (NaN) and the last no HO/TO.
    ``flat_*`` bound the foot-flat intervals (sole completely still);
    ``stride_lengths_m[i]`` is the distance between flat sole centres ``i`` and ``i + 1``.
    """

    side: Side
    hs_s: np.ndarray
    ff_s: np.ndarray
    ho_s: np.ndarray
    to_s: np.ndarray
    flat_start_s: np.ndarray
    flat_end_s: np.ndarray
    sole_centre_W: np.ndarray  # (n, 3)
    yaw_rad: np.ndarray
    stride_lengths_m: np.ndarray  # (n − 1,)


@dataclass(frozen=True, eq=False)
class StepEvents:
    """One row per step: the foot that lands, when, and its placement relative to the other.

    ``length_m``: distance between the two sole centres along the walking direction at the
    landing; ``width_m``: across it. The last step is the closing step (length ≈ 0).
    """

    side: tuple[Side, ...]
    hs_s: np.ndarray
    length_m: np.ndarray
    width_m: np.ndarray


class Walk:
    """A generated walk; every method takes times ``t`` (n,) [s] and is vectorised."""

    #: where a played motion came from (:class:`gaitnet.sim.clip_walk.ClipSource`); None: the
    #: gait generator
    source = None

    def __init__(
        self,
        subject: Subject,
        config: GaitConfig,
        plan: StepPlan,
        path: WalkPath,
        feet: tuple[FootTrajectory, FootTrajectory],
        pelvis: PelvisTrajectory,
        duration_s: float,
        laws: SpeedLaws,
    ) -> None:
        self.subject = subject
        self.config = config
        self.skeleton: LowerBodySkeleton = subject.skeleton()
        self.plan = plan
        self.path = path
        self._feet = feet
        self._pelvis = pelvis
        self.duration_s = float(duration_s)
        #: the speed- and subject-dependent values this walk was made with
        self.laws = laws
        self._ankle_S = subject.ankle_in_shoe()
        J = self.skeleton.rest_joints
        #: SMPL foot joints (ball of the foot) as fixed points of the shoe frames (left, right).
        self.foot_joints_in_shoe = self._ankle_S + (J[7:9] - J[5:7]) @ R_PfromSMPL.T
        self.events: dict[Side, FootEvents] = {
            side: _foot_events(side, plan.stances[i], self.duration_s)
            for i, side in enumerate(SIDES)
        }
        self.steps = _step_events(plan)

    # --- pelvis -------------------------------------------------------------------------
    def pelvis_kinematics(self, t: ArrayLike) -> tuple[np.ndarray, ...]:
        """``(R_WfromP, p_PinW, v_PinW, a_PinW, omega_PinP)``, exact spline derivatives."""
        return self._pelvis.kinematics(_times(t))

    def pelvis_angular_acceleration(self, t: ArrayLike) -> np.ndarray:
        """``dω_P/dt`` expressed in the pelvis frame (n, 3)."""
        return self._pelvis.angular_acceleration(_times(t))

    def pelvis_pose(self, t: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """``R_WfromP (n, 3, 3)`` and ``p_PinW (n, 3)``."""
        return self._pelvis.pose(_times(t))

    # --- shoes --------------------------------------------------------------------------
    def shoes(self, t: ArrayLike) -> dict[Side, ShoeTrajectory]:
        """Shoe poses per side."""
        t = _times(t)
        return {side: ShoeTrajectory(*self._feet[i].pose(t)) for i, side in enumerate(SIDES)}

    def shoe_points(self, t: ArrayLike, points_S: ArrayLike) -> np.ndarray:
        """World positions ``(n, 2, k, 3)`` of shoe-frame points ``(k, 3)`` (left, right)."""
        P = np.asarray(points_S, dtype=np.float64).reshape(-1, 3)
        out = []
        for traj in self.shoes(t).values():
            out.append(traj.p_SoleCentre_W[:, None, :] + np.einsum("nij,kj->nki", traj[0], P))
        return np.stack(out, axis=1)

    def sole_centres(self, t: ArrayLike) -> np.ndarray:
        """Sole centres (n, 2, 3)."""
        return self.shoe_points(t, np.zeros(3))[:, :, 0]

    def marker_points(self, t: ArrayLike) -> np.ndarray:
        """Instep markers on top of the shoes (n, 2, 3)."""
        return self.shoe_points(t, self.subject.marker_in_shoe())[:, :, 0]

    def ankles(self, t: ArrayLike) -> np.ndarray:
        """Ankle joints (n, 2, 3) (fixed points of the shoes)."""
        return self.shoe_points(t, self._ankle_S)[:, :, 0]

    # --- legs and SMPL pose -------------------------------------------------------------
    def _chain(self, t: np.ndarray) -> tuple[np.ndarray, ...]:
        R_P, p_P = self._pelvis.pose(t)
        shoes = self.shoes(t)
        R_S = np.stack([shoes[s].R_WfromShoe for s in SIDES], axis=1)
        p_S = np.stack([shoes[s].p_SoleCentre_W for s in SIDES], axis=1)
        ankle = p_S + np.einsum("nsij,j->nsi", R_S, self._ankle_S)
        joints, G_thigh, G_shank = leg_chain(self.skeleton, R_P, p_P, R_S, ankle)
        return joints, R_P, G_thigh, G_shank, R_S

    def joints(self, t: ArrayLike) -> np.ndarray:
        """World joint positions (n, 9, 3), SMPL joints [0, 1, 2, 4, 5, 7, 8, 10, 11]."""
        return self._chain(_times(t))[0]

    def smpl_pose(self, t: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``root_orient (n, 3)``, ``trans (n, 3)``, ``joint_aa (n, 8, 3)`` (SMPL convention)."""
        joints, R_P, G_thigh, G_shank, R_S = self._chain(_times(t))
        root, aa = smpl_pose_from_chain(R_P, G_thigh, G_shank, R_S)
        return root, joints[:, 0] - self.skeleton.rest_joints[0], aa

    def body_state(self, t: float) -> BodyState:
        """What the renderer draws at one instant: thighs, shanks and shoes."""
        joints = self.joints(np.array([float(t)]))[0]
        sj = self.subject
        legs = []
        for i, side in enumerate(SIDES):
            hip, knee, ankle = joints[1 + i], joints[3 + i], joints[5 + i]
            legs.append(
                LegSegment(
                    side, "thigh", hip, knee, sj.thigh_radius_top_m, sj.thigh_radius_bottom_m
                )
            )
            legs.append(
                LegSegment(
                    side, "shank", knee, ankle, sj.shank_radius_top_m, sj.shank_radius_bottom_m
                )
            )
        shoes = self.shoes(np.array([float(t)]))
        states = tuple(
            ShoeState(
                side,
                shoes[side].R_WfromShoe[0],
                shoes[side].p_SoleCentre_W[0],
                sj.shoe_length_m,
                sj.shoe_width_m,
                sj.shoe_height_m,
            )
            for side in SIDES
        )
        return BodyState(legs=tuple(legs), shoes=(states[0], states[1]))


def _times(t: ArrayLike) -> np.ndarray:
    return np.atleast_1d(np.asarray(t, dtype=np.float64))


def _foot_events(side: Side, stances: tuple[FootStance, ...], duration: float) -> FootEvents:
    def col(name: str) -> np.ndarray:
        return np.array([getattr(s, name) for s in stances], dtype=float)

    xy = np.array([s.xy for s in stances])
    flat_start = np.where(np.isnan(col("t_ff")), 0.0, col("t_ff"))
    flat_end = np.where(np.isnan(col("t_ho")), duration, col("t_ho"))
    return FootEvents(
        side=side,
        hs_s=col("t_hs"),
        ff_s=col("t_ff"),
        ho_s=col("t_ho"),
        to_s=col("t_to"),
        flat_start_s=flat_start,
        flat_end_s=flat_end,
        sole_centre_W=np.concatenate([xy, np.zeros((len(xy), 1))], axis=1),
        yaw_rad=col("yaw"),
        stride_lengths_m=np.linalg.norm(np.diff(xy, axis=0), axis=1),
    )


def _step_events(plan: StepPlan) -> StepEvents:
    """Step table: for each landing, the offset from the other foot's current placement."""
    idx = [1, 1]  # next stance index per foot
    current = [plan.stances[0][0], plan.stances[1][0]]
    lengths, widths = [], []
    for side in plan.step_side:
        st = plan.stances[side][idx[side]]
        idx[side] += 1
        other = current[1 - side]
        current[side] = st
        d = np.subtract(st.xy, other.xy)
        mean_yaw = 0.5 * (st.yaw + other.yaw)  # the feet's toe-out angles cancel
        heading = np.array([np.cos(mean_yaw), np.sin(mean_yaw)])
        lengths.append(float(d @ heading))
        widths.append(float(abs(d[0] * heading[1] - d[1] * heading[0])))
    return StepEvents(
        side=tuple(SIDES[s] for s in plan.step_side),
        hs_s=plan.step_hs[1:].copy(),
        length_m=np.array(lengths),
        width_m=np.array(widths),
    )


def walk_laws(subject: Subject, cfg: GaitConfig) -> SpeedLaws:
    """The speed- and subject-dependent values of a walk (:mod:`gaitnet.sim.gait_style`)."""
    return speed_laws(
        speed_mps=cfg.speed_mps,
        height_m=subject.height_m,
        style=subject.gait_style,
        variability=cfg.variability,
        stance_fraction=cfg.stance_fraction,
        step_ratio=cfg.step_length_height_ratio,
        step_exponent=cfg.step_length_speed_exponent,
        rotation_rad=cfg.pelvis_rotation_deg * DEG,
        obliquity_rad=cfg.pelvis_obliquity_deg * DEG,
        lateral_m=cfg.pelvis_lateral_m,
        stand_width_m=cfg.stand_width_m,
        shoe_width_m=subject.shoe_width_m,
    )


def generate_walk(
    subject: Subject,
    cfg: GaitConfig,
    rng: np.random.Generator,
    sway_rng: np.random.Generator | None = None,
    variation: WalkVariation | None = None,
) -> Walk:
    """Generate one walk (deterministic given the generators' states).

    ``rng`` draws the footsteps, ``sway_rng`` the postural sway while standing (None: drawn
    from ``rng`` after the footsteps). ``variation``: speed change within the walk, step
    asymmetry and a turn within a short arc (:class:`gaitnet.sim.gait_plan.WalkVariation`,
    used for the motion predictor's training clips; None: none, as the simulator).
    """
    laws = walk_laws(subject, cfg)
    pp = PelvisParams(
        lateral_m=laws.lateral_m,
        rotation_rad=laws.rotation_rad,
        obliquity_rad=laws.obliquity_rad,
        tilt_rad=cfg.pelvis_tilt_deg * DEG,
        # longer, faster steps vault higher: smooth the height more
        height_fit_s=_HEIGHT_FIT_S * max(1.0, cfg.speed_mps / REFERENCE_SPEED_MPS) ** 1.3,
    )
    settle = 2.0 * pp.height_hold_s  # the height is held still this long around standing
    t_go = cfg.stand_start_s + settle
    if variation is None:
        path = WalkPath(cfg.walk_length_m, cfg.turn_deg * DEG)
    else:
        path = WalkPath(
            cfg.walk_length_m,
            cfg.turn_deg * DEG,
            turn_arc_m=variation.turn_arc_m,
            turn_at=variation.turn_at,
        )
    plan = _plan(path, laws, cfg, rng, t_go + pp.progression_smooth_s, variation)
    sway = sample_sway(rng if sway_rng is None else sway_rng, cfg.sway_ap_rms_m, cfg.sway_ml_rms_m)
    t_stop = motion_end_time(plan, pp)
    duration = t_stop + settle + cfg.stand_end_s
    ankle_S = subject.ankle_in_shoe()
    grid = pelvis_grid(
        plan, path, pp, t_go=t_go, t_end=duration, ankle_x=float(ankle_S[0]), sway=sway
    )
    still = (cfg.stand_start_s, t_stop + settle)
    plan, feet, z_fit, bounds = fit_feet_and_height(plan, grid, subject, cfg, pp, still)
    pelvis = build_pelvis(grid, z_fit, bounds)
    return Walk(subject, cfg, plan, path, feet, pelvis, duration, laws)


def _plan(
    path: WalkPath,
    laws: SpeedLaws,
    cfg: GaitConfig,
    rng: np.random.Generator,
    t_first_heel_off: float,
    variation: WalkVariation | None = None,
) -> StepPlan:
    first = cfg.first_foot
    first_side = int(rng.integers(2)) if first == "random" else (0 if first == "left" else 1)
    return plan_steps(
        path,
        step_m=laws.step_m,
        speed_mps=cfg.speed_mps,
        step_width_m=cfg.step_width_m,
        stand_width_m=laws.stand_width_m,
        step_length_cv=cfg.step_length_cv,
        step_time_cv=cfg.step_time_cv,
        step_width_std_m=cfg.step_width_std_m,
        toe_out_rad=cfg.toe_out_deg * DEG,
        hs_pitch_rad=cfg.heel_strike_pitch_deg * DEG,
        to_pitch_rad=cfg.toe_off_pitch_deg * DEG,
        timing=(laws.stance_fraction, cfg.foot_flat_fraction, cfg.heel_off_fraction),
        t_first_heel_off=t_first_heel_off,
        first_side=first_side,
        rng=rng,
        variation=variation,
    )
