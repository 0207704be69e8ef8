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
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from gaitnet.pipeline.gap_bridge import feet_steadily_seen
from gaitnet.pipeline.swing_fill import rest_points, rests_of
from gaitnet.vio.gait import SIDES
from gaitnet.vio.result import StanceFoot

__all__ = ["OTHER_FOOT_MARGIN_S", "OTHER_FOOT_RADIUS_M", "reside_measured_feet"]

OTHER_FOOT_RADIUS_M = 0.06
"""A measured point this close [m] (3-D) to the other foot's rest point is that foot: the two
feet's points lie at least a step width (~0.1 m) apart when they pass, and the swing foot
higher."""
OTHER_FOOT_MARGIN_S = 0.25
"""The rest is taken to begin this long [s] before its landmark's first frame (the stance is
confirmed 0.06–0.2 s after the landing) and to end this long after its last."""


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
    changed = 0
    for r in rests:
        if id(r) not in points:
            continue
        other = SIDES.index(r.side)
        wrong = 1 - other
        during = (t_s >= r.t_first_s - margin_s) & (t_s <= r.t_last_s + margin_s)
        near = np.linalg.norm(out[:, wrong] - points[id(r)], axis=1) < radius_m
        for k in np.flatnonzero(during & near):
            if not np.isfinite(out[k, other]).all():
                out[k, other] = out[k, wrong]
            out[k, wrong] = np.nan
            changed += 1
    return out, changed
