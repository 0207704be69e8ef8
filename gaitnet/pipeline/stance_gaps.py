"""Whether the filter's stance landmarks show a missed stance (``gaitnet infer``'s second
filter run, ``pipeline.segmented_stances``).

The filter's second run, handed the segmenter's foot pixels, exists to find planted feet the
depth image does not show (docs/vio.md, *Feet the depth does not show*); it costs a second pass
of the filter (about 30 ms per frame). Where the first run's landmarks already hold every
stance of the walk it has nothing to find, so ``gaitnet infer`` skips it unless
``pipeline.segmented_stances_always``. A stance is missed where

- two consecutive landmarks, in order of their first frame, are of one foot and the second
  begins after the first ended (the other foot's stance between them was not found).
  Landmarks that begin together (within :data:`TIE_S`: standing at the start) are ordered by
  their last frame, the foot that steps first first; or
- a foot's landmark begins more than :data:`CYCLE_TOLERANCE` times the walk's typical gait
  cycle after that foot's previous one (its own stance between them was missed). The typical
  cycle is the median of the feet's landmark-to-landmark times, the step out of standing
  (each foot's first pair) left out; or
- there are fewer than :data:`MIN_WALKING_STANCES` landmarks besides each foot's first
  (nothing to judge a walk by).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from gaitnet.vio.result import StanceFoot

__all__ = ["CYCLE_TOLERANCE", "MIN_WALKING_STANCES", "TIE_S", "stance_missed"]

CYCLE_TOLERANCE = 1.5
"""A foot's landmark-to-landmark time above this multiple of the typical cycle spans a missed
stance (a missed stance doubles it)."""
TIE_S = 0.05
"""Landmarks beginning within this of each other [s] began together (standing)."""
MIN_WALKING_STANCES = 2
"""Landmarks besides each foot's first needed to judge the walk."""


def _walking_order(stance_feet: Sequence[StanceFoot]) -> list[StanceFoot]:
    """The landmarks by first frame; those that began together by last frame."""
    groups: list[list[StanceFoot]] = []
    for foot in sorted(stance_feet, key=lambda f: f.t_first_s):
        if groups and foot.t_first_s - groups[-1][0].t_first_s <= TIE_S:
            groups[-1].append(foot)
        else:
            groups.append([foot])
    return [f for group in groups for f in sorted(group, key=lambda f: f.t_last_s)]


def stance_missed(stance_feet: Sequence[StanceFoot]) -> bool:
    """Whether the landmarks show a missed stance (module docstring)."""
    ordered = _walking_order(stance_feet)
    for a, b in zip(ordered, ordered[1:], strict=False):
        if a.side == b.side and b.t_first_s > a.t_last_s:
            return True
    cycles, walking = [], 0
    for side in ("left", "right"):
        own = [f for f in ordered if f.side == side]
        walking += max(len(own) - 1, 0)
        cycles += [b.t_first_s - a.t_first_s for a, b in zip(own[1:], own[2:], strict=False)]
    if walking < MIN_WALKING_STANCES:
        return True
    if not cycles:
        return False
    typical = float(np.median(cycles))
    return any(c > CYCLE_TOLERANCE * typical for c in cycles)
