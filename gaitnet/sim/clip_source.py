"""Read the motion-capture clip a session plays (``motion.clip``), pick its segment and skeleton.

The clip is read by the motion predictor's own reader (:func:`gaitnet.motion.amass.
read_amass_npz`: AMASS SMPL+H G ``*_poses.npz`` or SMPL-X ``*_stageii.npz``, any frame rate;
a missing key, NaN or a rate ≤ 0 is a one-line error naming the file and the key), filtered
(:func:`gaitnet.sim.clip_pose.lowpass_poses`, ``motion.lowpass_hz``) over its whole length and
cut to ``[motion.start_s, motion.start_s + motion.duration_s]``; a start at or beyond the
clip's end is refused, a segment that runs past the end is shortened (logged).

Skeleton, first found of:
1. the clip's own rest joints (``gaitnet_rest_joints``, :data:`gaitnet.motion.amass.
   REST_JOINTS_KEY`: the generator's clips carry them; AMASS files do not);
2. the anthropometric skeleton (:func:`gaitnet.motion.skeleton.builtin_skeleton`) of
   ``subject.height_m``;
3. the anthropometric skeleton of the height, within 1.2–2.2 m, whose stance ankles slide
   least: a clip's translation is the recorded person's, its joint angles are only rotations,
   so legs of another length make the planted feet slide by the difference times the leg's
   swing (a 10 % longer leg: about 6 cm per stance). The score is the 15th percentile of each
   ankle's horizontal speed over the frames where the pelvis moves faster than 0.3 m/s (the
   planted part of every stance), searched on a 1 cm grid.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gaitnet.errors import InputError
from gaitnet.motion.amass import REST_JOINTS_KEY, read_amass_npz
from gaitnet.motion.skeleton import LowerBodySkeleton, builtin_skeleton, from_rest_joints
from gaitnet.sim.clip_pose import PoseSamples, body_chain, lowpass_poses
from gaitnet.sim.config import HEIGHT_LIMITS_M, MotionConfig

log = logging.getLogger(__name__)

__all__ = ["ClipSegment", "estimate_height", "read_clip_segment"]

_HEIGHT_STEP_M = 0.01
_MOVING_MPS = 0.3  # pelvis speed above which a frame counts for the height estimate
_PLANTED_PERCENTILE = 15.0
LEG_FRACTION = 0.245 + 0.246  # builtin_skeleton: thigh + shank as a fraction of the height


@dataclass(frozen=True, eq=False)
class ClipSegment:
    """The played part of a clip: ``poses`` on the clip's own clock (times from the clip's
    first frame), its ``skeleton`` and where that came from (``skeleton_source``: one of
    ``rest_joints``, ``subject.height_m``, ``estimated``), the body ``height_m`` it implies,
    and the clip's frame rate and length."""

    path: Path
    poses: PoseSamples
    skeleton: LowerBodySkeleton
    skeleton_source: str
    height_m: float
    fps: float
    clip_duration_s: float


def estimate_height(poses: PoseSamples) -> float:
    """The anthropometric body height whose stance ankles slide least (module docstring)."""
    J0 = builtin_skeleton(1.75).rest_joints[0]  # the built-in pelvis joint is the rest origin
    speed = np.linalg.norm(np.gradient(poses.trans[:, :2] + J0[:2], poses.t, axis=0), axis=1)
    moving = speed > _MOVING_MPS
    if moving.sum() < 10:
        moving = np.ones_like(moving)
    lo, hi = HEIGHT_LIMITS_M
    heights = np.arange(lo, hi + 1e-9, _HEIGHT_STEP_M)
    scores = []
    for h in heights:
        ankles = body_chain(
            builtin_skeleton(h), poses.root_orient, poses.trans, poses.joint_aa
        ).joints[:, 5:7, :2]
        v = np.linalg.norm(np.gradient(ankles, poses.t, axis=0), axis=-1)[moving]
        scores.append(float(np.percentile(v, _PLANTED_PERCENTILE, axis=0).mean()))
    return float(heights[int(np.argmin(scores))])


def read_clip_segment(motion: MotionConfig, subject_height_m: float | None) -> ClipSegment:
    """Read ``motion.clip`` and cut, filter and give a skeleton to its played segment."""
    if motion.clip is None:
        raise InputError("motion.clip: no clip given")
    path = Path(motion.clip)
    clip = read_amass_npz(path)
    t = np.arange(clip.n_frames) / clip.fps
    duration = float(t[-1])
    start = float(motion.start_s)
    if start >= duration:
        raise InputError(
            f"{path}: motion.start_s {start:g} s is outside the clip ({duration:.2f} s long)"
        )
    end = duration if motion.duration_s is None else start + float(motion.duration_s)
    if end > duration + 0.5 / clip.fps:
        log.warning(
            "%s: motion.start_s + motion.duration_s = %.2f s runs past the clip's end; "
            "playing %.2f s (to the end)",
            path,
            end,
            duration - start,
        )
        end = duration
    full = PoseSamples(t, clip.root_orient, clip.trans, clip.joint_aa)
    poses = lowpass_poses(full, motion.lowpass_hz).select(
        (t >= start - 0.5 / clip.fps) & (t <= end + 0.5 / clip.fps)
    )
    if len(poses) < 3:
        raise InputError(
            f"{path}: motion.duration_s: the segment holds {len(poses)} frames, too few to play"
        )
    if clip.rest_joints is not None:
        try:
            skeleton, source = from_rest_joints(clip.rest_joints), "rest_joints"
        except ValueError as exc:  # a zero-length bone
            raise InputError(f"{path}: key {REST_JOINTS_KEY!r}: {exc}") from None
        leg = np.mean(np.add(skeleton.thigh_lengths, skeleton.shank_lengths))
        height = float(np.clip(leg / LEG_FRACTION, *HEIGHT_LIMITS_M))
    elif subject_height_m is not None:
        height = float(subject_height_m)
        skeleton, source = builtin_skeleton(height), "subject.height_m"
    else:
        height = estimate_height(poses)
        skeleton, source = builtin_skeleton(height), "estimated"
    return ClipSegment(path, poses, skeleton, source, height, float(clip.fps), duration)
