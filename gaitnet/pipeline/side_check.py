"""The measured feet's sides checked against the filter's stance landmarks
(``pipeline.side_check``).

The segmenter's post-processing sides a foot seen alone by where it lies against the body's
midline (:func:`gaitnet.segmentation.postprocess.foot_keypoints`), which fails where a foot
crosses it: in a turn the outer foot steps across the camera's line, and at the end of a walk
a foot is set down beside the other. A foot measured on the wrong side for a few frames drags
the pose there (a 90° turn, `gaitnet simulate --seed 9004 gait.turn_deg=90
gait.walk_length_m=8`: ten frames of the right foot measured as the left one, filled right
foot NMATE 7.6 cm). The filter's stance landmarks are sided with more evidence (the steps'
alternation and offsets over the whole walk, :mod:`gaitnet.vio.stance_tracker`) and say where
each foot rests while it rests. In a frame where landmarks are active (between a landmark's
first and last observation):

- a measured point closer than ``near_m`` to an active landmark of the other side, and
  closer to it than to any of its own side's, is that other foot (two feet cannot rest
  within ``near_m`` of each other: ``vio.stance.same_foot_m``): it becomes that side's point,
  or is dropped when that side has its own point there; two points that are each other's
  foot are swapped;
- a measured point farther than ``far_m`` from every active landmark of its own side (and
  near none of the other's) is not that foot while it rests: dropped.

On the 17 simulated sessions of docs/pipeline.md's measurements a correctly sided point lies
at most 0.11 m from its own active landmark (median 0.01–0.04 m: the segmenter's mid
keypoint against the filter's foot point) and at least 0.11 m from the other side's, so
neither rule touches them (docs/pipeline.md, *Sides checked against the landmarks*).
Frames without an active landmark (the foot in swing) are left as measured.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from gaitnet.vio.result import StanceFoot

__all__ = ["check_sides"]

SIDES = ("left", "right")
_DROP = -1


def check_sides(
    t_s: np.ndarray,
    foot_W: np.ndarray,
    stance_feet: Sequence[StanceFoot],
    near_m: float,
    far_m: float,
) -> tuple[np.ndarray, dict[str, int]]:
    """``foot_W`` (n, 2, 3) (rows left, right; NaN where not seen) at the frame times ``t_s``
    (n,) with each point moved to the side the active landmarks say, or dropped (module
    docstring). Returns the new points and how many were ``moved``, ``swapped`` (pairs) and
    ``dropped``."""
    out = np.array(foot_W, dtype=np.float64, copy=True)
    counts = {"moved": 0, "swapped": 0, "dropped": 0}
    t_s = np.asarray(t_s, dtype=np.float64)
    xy = {s: np.array([f.xy for f in stance_feet if f.side == s]).reshape(-1, 2) for s in SIDES}
    span = {
        s: np.array([(f.t_first_s, f.t_last_s) for f in stance_feet if f.side == s]).reshape(-1, 2)
        for s in SIDES
    }
    for k, t in enumerate(t_s):
        active = [xy[s][(span[s][:, 0] <= t) & (t <= span[s][:, 1])] for s in SIDES]
        if not (len(active[0]) or len(active[1])):
            continue
        target = [_target(out[k, i], i, active, near_m, far_m) for i in range(2)]
        if target == [1, 0]:
            out[k] = out[k, ::-1].copy()
            counts["swapped"] += 1
            continue
        new = np.full((2, 3), np.nan)
        for i in range(2):  # the points that stay first, then the ones that move
            if target[i] == i:
                new[i] = out[k, i]
        for i in range(2):
            goal = target[i]
            if goal is None or goal == i:
                continue
            if goal == _DROP or target[goal] == goal:  # not this foot, or the other has its own
                counts["dropped"] += 1
            else:
                new[goal] = out[k, i]
                counts["moved"] += 1
        out[k] = new
    return out, counts


def _target(
    p: np.ndarray, side: int, active: list[np.ndarray], near_m: float, far_m: float
) -> int | None:
    """Where the point ``p`` of ``side`` belongs: its side, the other (0 or 1), :data:`_DROP`,
    or None when it is not measured."""
    if not np.isfinite(p[0]):
        return None
    d = [np.min(np.linalg.norm(a - p[:2], axis=1)) if len(a) else np.inf for a in active]
    other = 1 - side
    if d[other] < near_m and d[other] < d[side]:
        return other
    if np.isfinite(d[side]) and d[side] > far_m:
        return _DROP
    return side
