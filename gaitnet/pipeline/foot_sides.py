"""A measured foot that lies where the other foot rests is the other foot.

The segmentation post-processing sides each foot blob from the frame alone
(:mod:`gaitnet.segmentation.postprocess`). When only one foot shows, under a flexed knee or at
the image's edge, it is sometimes given the wrong side: on a real CMU walk played by the
simulator the planted left foot was measured as the right foot in 6 frames around its landing,
and the pose correction then pulled the right leg 30–60 cm forward. The filter knows better
where each foot rests: its stance landmarks, with their sides from the whole walk
(:class:`gaitnet.vio.stance_tracker.StanceTracker`). A foot cannot be where the other foot
rests while it rests there, so a point measured for one foot within ``radius_m`` of a rest
point of the other foot (:func:`gaitnet.pipeline.swing_fill.rest_points`), at a time from
``margin_s`` before that rest's first frame (the landing comes before the stance is
confirmed) to ``margin_s`` after its last, is given to the other foot when that one has no
point in the frame, and dropped otherwise.

A rest whose own foot was never measured in it (a stance laid from the step rhythm,
:mod:`gaitnet.pipeline.hidden_stances`, or found by the filter from a few sightings) has no
measured point: its point is then its landmark moved by that foot's median offset of measured
rest point from landmark (none when the foot has no measured rest), at the median height of
all measured rest points, and the test is along the floor within ``radius_m`` and within
:data:`UNMEASURED_REST_HEIGHT_M` of that height. On a 1.88 m CMU walker looped to 20 s the
right foot was measured in 19 % of the frames and its stances were laid; the landing right
foot was measured as the left one for 4–5 frames of every stride, 60–75 cm ahead of the
left foot.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from gaitnet.pipeline.gap_bridge import feet_steadily_seen
from gaitnet.pipeline.swing_fill import rest_points, rests_of
from gaitnet.vio.gait import SIDES, Stance
from gaitnet.vio.result import StanceFoot

__all__ = [
    "OTHER_FOOT_MARGIN_S",
    "OTHER_FOOT_RADIUS_M",
    "UNMEASURED_REST_HEIGHT_M",
    "reside_measured_feet",
]

OTHER_FOOT_RADIUS_M = 0.06
"""A measured point this close [m] (3-D) to the other foot's rest point is that foot: the two
feet's points lie at least a step width (~0.1 m) apart when they pass, and the swing foot
higher."""
OTHER_FOOT_MARGIN_S = 0.25
"""The rest is taken to begin this long [s] before its landmark's first frame (the stance is
confirmed 0.06–0.2 s after the landing) and to end this long after its last."""


UNMEASURED_REST_HEIGHT_M = 0.08
"""A point this close [m] in height to the measured rests' median height may be a foot at a
rest without a measured point (a landing foot's marker is up to ~6 cm higher than at rest)."""


def _unmeasured_rest_points(
    rests: Sequence[Stance], points: dict[int, np.ndarray]
) -> dict[int, np.ndarray]:
    """Points (3,) for the rests without a measured point (module docstring), by ``id``; none
    when no rest of either foot was measured (no height to compare with)."""
    if not points:
        return {}
    height = float(np.median([p[2] for p in points.values()]))
    out: dict[int, np.ndarray] = {}
    for side in SIDES:
        own = [r for r in rests if r.side == side]
        offsets = [points[id(r)][:2] - r.xy for r in own if id(r) in points]
        offset = np.median(offsets, axis=0) if offsets else np.zeros(2)
        for r in own:
            if id(r) not in points:
                out[id(r)] = np.array([*(np.asarray(r.xy, dtype=np.float64) + offset), height])
    return out


def reside_measured_feet(
    t_s: np.ndarray,
    measured: np.ndarray,
    stance_feet: Sequence[StanceFoot],
    radius_m: float = OTHER_FOOT_RADIUS_M,
    margin_s: float = OTHER_FOOT_MARGIN_S,
) -> tuple[np.ndarray, int]:
    """``measured`` (n, 2, 3) world foot points (left, right; NaN where not seen) with each
    point that lies at the other foot's rest given to that foot or dropped (module docstring),
    and the number of points moved or dropped."""
    t_s = np.asarray(t_s, dtype=np.float64)
    out = np.array(measured, dtype=np.float64, copy=True)
    seen = feet_steadily_seen(out)
    rests = rests_of(stance_feet)
    points = rest_points(t_s, out, seen, rests)
    laid = _unmeasured_rest_points(rests, points)
    changed = 0
    for r in rests:
        other = SIDES.index(r.side)
        wrong = 1 - other
        during = (t_s >= r.t_first_s - margin_s) & (t_s <= r.t_last_s + margin_s)
        if id(r) in points:
            near = np.linalg.norm(out[:, wrong] - points[id(r)], axis=1) < radius_m
        elif id(r) in laid:
            p = laid[id(r)]
            near = (np.linalg.norm(out[:, wrong, :2] - p[:2], axis=1) < radius_m) & (
                np.abs(out[:, wrong, 2] - p[2]) < UNMEASURED_REST_HEIGHT_M
            )
        else:
            continue
        for k in np.flatnonzero(during & near):
            if not np.isfinite(out[k, other]).all():
                out[k, other] = out[k, wrong]
            out[k, wrong] = np.nan
            changed += 1
    return out, changed
