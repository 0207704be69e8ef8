"""A motion-capture clip as the simulated subject's motion (``gaitnet simulate --motion``).

:func:`build_clip_walk` turns ``motion.*`` (:class:`gaitnet.sim.config.MotionConfig`) into a
:class:`ClipWalk`, which the rest of the simulator uses exactly as a generated
:class:`gaitnet.sim.gait.Walk`: the rig on its pelvis with the strap dynamics, the sensors, the
scene with tag sheets at both ends of the walked path and clutter off it, and every
ground-truth file. Order of work:

1. the clip's segment and skeleton (:mod:`gaitnet.sim.clip_source`);
2. the subject: drawn as for a generated walk (``subject`` stream: shoes, clothes, radii) at
   the skeleton's height, with the skeleton's thigh, shank, hip and pelvis lengths;
3. the shoes mounted level on the clip's planted feet (:func:`gaitnet.sim.clip_pose.
   shoe_mounting`) and the floor under the stance feet: a plane through the lowest of the
   four sole ends (heel and toe of both shoes) of every frame (at any instant of walking one
   foot stands), turned level at ``z = 0`` by one rigid motion of the whole clip
   (:func:`floor_transform`: a capture volume's vertical can be off by about a degree, which
   over metres lifts the feet by centimetres); what a clip slides or sinks around that plane
   stays as recorded and is the ground truth;
4. the segment must walk: each foot rests on the floor at least twice
   (:mod:`gaitnet.sim.clip_events`), and a stride moves at least 0.2 m;
5. standing, lead-in, clip, lead-out, standing (:mod:`gaitnet.sim.clip_lead`);
6. placed as a generated walk is: the standing feet's midpoint at the origin, the heading +x;
7. the pelvis as a quintic spline through the samples (the same channels as a generated
   pelvis, :class:`gaitnet.sim.gait_pelvis.PelvisTrajectory`, so velocity, acceleration and
   angular rate for the IMU are its exact derivatives), the legs by forward kinematics of the
   slerped joint rotations at any time; the gait events are measured on the shoes as rendered.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike
from scipy.interpolate import make_interp_spline

from gaitnet.errors import InputError
from gaitnet.geometry import make_T, so3_exp, so3_log
from gaitnet.motion.skeleton import LowerBodySkeleton
from gaitnet.sim.clip_events import foot_contacts, foot_events, step_events
from gaitnet.sim.clip_lead import (
    SessionMotion,
    StandingSpec,
    build_session_motion,
    median_pelvis_tilt,
)
from gaitnet.sim.clip_pose import (
    BodyChain,
    PoseSamples,
    ShoeGeometry,
    body_chain,
    poses_chain,
    shoe_mounting,
)
from gaitnet.sim.clip_source import ClipSegment, read_clip_segment
from gaitnet.sim.config import SimConfig
from gaitnet.sim.gait import GaitConfig, ShoeTrajectory, Walk
from gaitnet.sim.gait_legs import R_PfromSMPL
from gaitnet.sim.gait_pelvis import PelvisTrajectory
from gaitnet.sim.scene import SIDES, Side
from gaitnet.sim.subject import Subject, sample_subject

__all__ = ["MIN_STRIDE_M", "ClipSource", "ClipWalk", "build_clip_walk", "floor_transform"]

MIN_STRIDE_M = 0.2  # a segment whose strides are all shorter than this is not walking
_LONGEST_STRIDE_S = 2.5  # a foot resting once in a longer segment is not walking
_MAX_TILT_DEG = 80.0  # the pelvis channels are Z-Y-X Euler angles: no gimbal lock near 90°
STAND_WIDTH_M = 0.165  # natural standing width (sole centres), as the generator's
_SHOE_CLEARANCE_M = 0.03
_FLOOR_WINDOW_S = 1.0
_FLOOR_SLOPE_PRIOR_M = 0.5  # a slope counts as much as a floor point this far away


@dataclass(frozen=True, eq=False)
class ClipSource:
    """Where a :class:`ClipWalk` came from, written to ``groundtruth/motion.json`` and, per
    frame, ``groundtruth/motion_frames.csv`` (docs/groundtruth.md)."""

    segment: ClipSegment
    sha256: str
    start_s: float
    end_s: float
    floor_tilt_deg: float
    pelvis_tilt_deg: float
    T_session_from_clip: np.ndarray
    motion: SessionMotion
    lead_in_s: float
    lead_out_s: float
    lowpass_hz: float

    def to_json(self) -> str:
        seg = self.segment
        return json.dumps(
            {
                "source": "clip",
                "clip": str(seg.path),
                "clip_sha256": self.sha256,
                "clip_fps": seg.fps,
                "clip_duration_s": seg.clip_duration_s,
                "segment_s": [self.start_s, self.end_s],
                "lowpass_hz": self.lowpass_hz,
                "lead_in_s": self.lead_in_s,
                "lead_out_s": self.lead_out_s,
                "skeleton_source": seg.skeleton_source,
                "height_m": seg.height_m,
                "floor_tilt_deg": self.floor_tilt_deg,
                "pelvis_tilt_deg": self.pelvis_tilt_deg,
                "T_session_from_clip": np.round(self.T_session_from_clip, 12).tolist(),
                "synthetic_s": float(np.sum(self.motion.synthetic) / seg.fps),
            },
            indent=2,
        )

    def frame_rows(self, times: np.ndarray) -> np.ndarray:
        """Per time: clip time, blend weight, playback rate, synthetic (0/1) — the nearest
        sample's (the samples are the clip's frames, 60–120 Hz)."""
        m = self.motion
        k = np.clip(np.round(np.asarray(times) * self.segment.fps).astype(int), 0, len(m.poses) - 1)
        return np.column_stack(
            [m.clip_time_s[k], m.blend_weight[k], m.time_rate[k], m.synthetic[k].astype(float)]
        )


def _euler_channels(R: np.ndarray, name: str) -> np.ndarray:
    """Unwrapped Z-Y-X Euler angles ``(yaw, tilt, obliquity)`` (n, 3) of ``R_WfromP``."""
    tilt = -np.arcsin(np.clip(R[:, 2, 0], -1.0, 1.0))
    if np.any(np.abs(tilt) > np.deg2rad(_MAX_TILT_DEG)):
        raise InputError(
            f"{name}: the pelvis tilts more than {_MAX_TILT_DEG:g}° from upright; not a walk"
        )
    yaw = np.unwrap(np.arctan2(R[:, 1, 0], R[:, 0, 0]))
    obl = np.unwrap(np.arctan2(R[:, 2, 1], R[:, 2, 2]))
    return np.column_stack([yaw, tilt, obl])


class ClipWalk(Walk):
    """A played clip with a :class:`~gaitnet.sim.gait.Walk`'s interface (module docstring).

    ``plan``, ``path`` and ``laws`` (the generator's footstep plan and speed laws) are None;
    ``events`` and ``steps`` are measured on the shoes; ``source`` says where the motion came
    from."""

    def __init__(
        self,
        subject: Subject,
        config: GaitConfig,
        skeleton: LowerBodySkeleton,
        poses: PoseSamples,
        shoe: ShoeGeometry,
        source: ClipSource | None = None,
        name: str = "motion.clip",
    ) -> None:
        self.subject = subject
        self.config = config
        self.skeleton = skeleton
        self.plan = None  # type: ignore[assignment]
        self.path = None  # type: ignore[assignment]
        self.laws = None  # type: ignore[assignment]
        self.source = source
        self._poses = poses
        self.duration_s = float(poses.t[-1])
        self._shoe = shoe
        self._ankle_S = shoe.ankle_in_shoe
        J = skeleton.rest_joints
        foot_in_ankle = (J[7:9] - J[5:7]) @ R_PfromSMPL.T
        self.foot_joints_in_shoe = self._ankle_S + np.einsum(
            "sji,sj->si", shoe.ankle_from_shoe, foot_in_ankle
        )
        chain = poses_chain(poses, skeleton, shoe)
        channels = np.column_stack([chain.p_P, _euler_channels(chain.R_WfromP, name)])
        self._pelvis = PelvisTrajectory(make_interp_spline(poses.t, channels, k=5), self.duration_s)
        self.events, self.steps = self._measure_events(chain)

    def _measure_events(self, chain: BodyChain):
        pts = chain.shoe_points(self._ankle_S, self._shoe.sole_points())
        t = self._poses.t
        events = {}
        for i, side in enumerate(SIDES):
            contacts = foot_contacts(t, pts[:, i, 0], pts[:, i, 1])
            toe_dir = chain.R_WfromShoe[:, i, :, 0]
            events[side] = foot_events(
                side, t, contacts, pts[:, i, 2], toe_dir, pts[:, i, 0], pts[:, i, 1]
            )
        return events, step_events(events)

    def _pose(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        R_P, p_P = self._pelvis.pose(t)
        _, _, aa = self._poses.at(t)
        return so3_log(R_P @ R_PfromSMPL), p_P - self.skeleton.rest_joints[0], aa

    def _body(self, t: ArrayLike) -> BodyChain:
        pose = self._pose(np.atleast_1d(np.asarray(t, float)))
        return body_chain(self.skeleton, *pose, self._shoe.ankle_from_shoe)

    def smpl_pose(self, t: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return self._pose(np.atleast_1d(np.asarray(t, float)))

    def joints(self, t: ArrayLike) -> np.ndarray:
        return self._body(t).joints

    def shoes(self, t: ArrayLike) -> dict[Side, ShoeTrajectory]:
        ch = self._body(t)
        soles = ch.joints[:, 5:7] - np.einsum("nsij,j->nsi", ch.R_WfromShoe, self._ankle_S)
        return {
            side: ShoeTrajectory(ch.R_WfromShoe[:, i], soles[:, i]) for i, side in enumerate(SIDES)
        }


def _sha256(path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _fit_subject(subject: Subject, skel: LowerBodySkeleton, height_m: float) -> Subject:
    """``subject`` with the skeleton's segment lengths (its shoes, clothes and radii kept)."""
    J = skel.rest_joints
    hips = J[1:3]
    return replace(
        subject,
        height_m=float(height_m),
        thigh_m=float(np.mean(skel.thigh_lengths)),
        shank_m=float(np.mean(skel.shank_lengths)),
        hip_width_m=float(np.linalg.norm(hips[0] - hips[1])),
        pelvis_above_hip_m=float(J[0, 1] - hips[:, 1].mean()),
        pelvis_behind_hip_m=float(hips[:, 2].mean() - J[0, 2]),
    )


def _level_plane(points: np.ndarray) -> np.ndarray:
    """The rigid motion (4, 4) turning the plane through ``points`` (m, 3) level at ``z = 0``
    about its point under the first one; its slopes are held near 0 where the points span
    too little (e.g. across a straight walk)."""
    A = np.column_stack([np.ones(len(points)), points[:, :2] - points[0, :2]])
    prior = np.diag([0.0, _FLOOR_SLOPE_PRIOR_M, _FLOOR_SLOPE_PRIOR_M])  # slopes pulled to 0
    coef, *_ = np.linalg.lstsq(
        np.vstack([A, prior]), np.concatenate([points[:, 2], np.zeros(3)]), rcond=None
    )
    normal = np.array([-coef[1], -coef[2], 1.0])
    normal /= np.linalg.norm(normal)
    axis = np.cross(normal, [0.0, 0.0, 1.0])
    angle = np.arctan2(np.linalg.norm(axis), normal[2])
    R = so3_exp(axis / max(np.linalg.norm(axis), 1e-12) * angle)
    origin = np.array([*points[0, :2], coef[0]])
    return make_T(R, -R @ origin + np.array([origin[0], origin[1], 0.0]))


def _flat_floor_points(chain: BodyChain, t: np.ndarray, shoe: ShoeGeometry) -> np.ndarray:
    """One floor point per foot-flat interval (both sole ends down, :mod:`gaitnet.sim.
    clip_events`): the mean of the sole ends' positions over it."""
    ends = chain.shoe_points(shoe.ankle_in_shoe, shoe.sole_points()[:2])
    points = []
    for s in range(2):
        contacts = foot_contacts(t, ends[:, s, 0], ends[:, s, 1])
        for a, b in contacts.stances:
            flat = contacts.flat(a, b)
            if flat is not None:
                points.append(ends[flat[0] : flat[1] + 1, s].reshape(-1, 3).mean(axis=0))
    return np.array(points).reshape(-1, 3)


def floor_transform(poses: PoseSamples, skel: LowerBodySkeleton, shoe: ShoeGeometry) -> np.ndarray:
    """The rigid motion ``T`` (4, 4) that lays the floor under the clip's stance feet on
    ``z = 0`` (module docstring, step 3). First guess: per window of
    :data:`_FLOOR_WINDOW_S` (about a stride) the median height of the lowest sole end and its
    mean position give one floor point. Then, twice, the feet's contacts are found on the
    levelled clip and the plane is refitted through the foot-flat soles (one point per
    foot flat: the mean of both sole ends over it), which the lowest end alone puts 1–2 cm
    too low (a rigid shoe's toe dips under the floor where a real foot bends, and a flat
    sole is never exactly level)."""
    chain = poses_chain(poses, skel, shoe)
    ends = chain.shoe_points(shoe.ankle_in_shoe, shoe.sole_points()[:2]).reshape(len(poses), 4, 3)
    low = ends[np.arange(len(poses)), np.argmin(ends[..., 2], axis=1)]
    window = np.floor((poses.t - poses.t[0]) / _FLOOR_WINDOW_S).astype(int)
    guess = np.array(
        [
            [*low[window == k, :2].mean(axis=0), np.median(low[window == k, 2])]
            for k in np.unique(window)
        ]
    )
    T = _level_plane(guess)
    J0 = skel.rest_joints[0]
    for _ in range(2):
        levelled = poses_chain(_transformed(poses, T[:3, :3], T[:3, 3], J0), skel, shoe)
        points = _flat_floor_points(levelled, poses.t, shoe)
        if len(points) < 2:
            break
        T = _level_plane(points) @ T
    return T


def _check_walking(poses: PoseSamples, skel: LowerBodySkeleton, shoe: ShoeGeometry, name: str):
    chain = poses_chain(poses, skel, shoe)
    pts = chain.shoe_points(shoe.ankle_in_shoe, shoe.sole_points())
    longest = 0.0
    for i, side in enumerate(SIDES):
        c = foot_contacts(poses.t, pts[:, i, 0], pts[:, i, 1])
        if not c.stances:
            raise InputError(
                f"{name}: the {side} foot never rests on a floor (no sole end within 2 cm of "
                "the floor and still); not a walk on level ground"
            )
        if len(c.stances) < 2:
            length = poses.t[-1] - poses.t[0]
            if length > _LONGEST_STRIDE_S:
                raise InputError(
                    f"{name}: no walking in the segment (the {side} foot rests once in "
                    f"{length:.1f} s)"
                )
            raise InputError(
                f"{name}: motion.duration_s: the segment holds less than one stride of the "
                f"{side} foot ({length:.2f} s)"
            )
        flats = [c.flat(a, b) or (a, b) for a, b in c.stances]
        xy = np.array([pts[f0 : f1 + 1, i, 2, :2].mean(axis=0) for f0, f1 in flats])
        longest = max(longest, float(np.max(np.linalg.norm(np.diff(xy, axis=0), axis=1))))
    if longest < MIN_STRIDE_M:
        raise InputError(
            f"{name}: no walking in the segment (its longest stride is {longest:.2f} m, "
            f"under {MIN_STRIDE_M:g} m)"
        )


def _start_frame(motion: SessionMotion, skel: LowerBodySkeleton, shoe: ShoeGeometry):
    """The rigid motion placing the session's start at the origin, heading +x."""
    p = motion.poses
    chain = poses_chain(p, skel, shoe)
    soles = chain.shoe_points(shoe.ankle_in_shoe, np.zeros((1, 3)))[:, :, 0]
    mid = soles[0].mean(axis=0)
    if motion.blend_weight[0] >= 1.0:  # a standing start: the pelvis faces the heading
        fwd = chain.R_WfromP[0, :, 0]
    else:
        k = min(len(p) - 1, int(round(1.0 / (p.t[1] - p.t[0]))))
        fwd = chain.p_P[k] - chain.p_P[0]
    R = so3_exp(np.array([0.0, 0.0, -np.arctan2(fwd[1], fwd[0])]))
    d = -R @ np.array([mid[0], mid[1], 0.0])
    return R, d


def _transformed(p: PoseSamples, R: np.ndarray, d: np.ndarray, J0: np.ndarray) -> PoseSamples:
    root = so3_log(R @ so3_exp(p.root_orient))
    trans = (J0 + p.trans) @ R.T + d - J0
    return PoseSamples(p.t, root, trans, p.joint_aa)


def build_clip_walk(cfg: SimConfig, subject_rng: np.random.Generator) -> ClipWalk:
    """The :class:`ClipWalk` of ``cfg.motion`` (module docstring); ``subject_rng`` draws the
    subject's shoes, clothes and radii."""
    motion = cfg.motion
    seg = read_clip_segment(motion, cfg.subject.height_m)
    name = str(seg.path)
    drawn = sample_subject(subject_rng, cfg.subject.height_range_m, seg.height_m)
    subject = _fit_subject(drawn, seg.skeleton, seg.height_m)
    skel = seg.skeleton
    shoe = ShoeGeometry(
        subject.ankle_in_shoe(), subject.shoe_length_m, shoe_mounting(seg.poses, skel)
    )
    J0 = skel.rest_joints[0]
    T_floor = floor_transform(seg.poses, skel, shoe)
    clip = _transformed(seg.poses, T_floor[:3, :3], T_floor[:3, 3], J0)
    _check_walking(clip, skel, shoe, name)
    width = cfg.gait.stand_width_m
    if width is None:
        width = max(STAND_WIDTH_M, subject.shoe_width_m + _SHOE_CLEARANCE_M)
    spec = StandingSpec(
        cfg.gait.stand_start_s, cfg.gait.stand_end_s, width, cfg.gait.knee_extended_deg
    )
    session = build_session_motion(clip, skel, shoe, motion.lead_in_s, motion.lead_out_s, spec)
    R, d = _start_frame(session, skel, shoe)
    session = replace(session, poses=_transformed(session.poses, R, d, J0))
    T = make_T(R, d) @ T_floor
    source = ClipSource(
        segment=seg,
        sha256=_sha256(seg.path),
        start_s=float(seg.poses.t[0]),
        end_s=float(seg.poses.t[-1]),
        floor_tilt_deg=float(np.degrees(np.arccos(np.clip(T_floor[2, 2], -1.0, 1.0)))),
        pelvis_tilt_deg=float(np.degrees(median_pelvis_tilt(poses_chain(clip, skel, shoe)))),
        T_session_from_clip=T,
        motion=session,
        lead_in_s=motion.lead_in_s,
        lead_out_s=motion.lead_out_s,
        lowpass_hz=motion.lowpass_hz,
    )
    return ClipWalk(subject, cfg.gait, skel, session.poses, shoe, source, name)
