"""The body's midline seen from a camera worn off the middle of the waist.

A lone foot is sided by the sign of its lateral position along the camera's left axis minus
``feet.lateral_offset_m``, the body's midline (:mod:`gaitnet.segmentation.postprocess`). A
camera worn at the middle of the waist has the midline at 0; one worn on the side of a belt
does not: worn 10 cm to the left, the left foot of a normal stance lies about straight below
it and was sided right whenever it was in view alone (a simulated session with
``mount.offset_m=[0.14,0.1,0]`` had the left foot measured as the right one in 10 % of its
frames). The session tells where the midline is: while the subject stands at the start both
feet are in view, side by side, and sided apart by their lateral order, which needs no
midline. :class:`MidlineEstimate` takes those frames' midpoints among the first
``feet.midline_frames`` frames and, given at least :data:`MIN_PAIRS` of them, their median
becomes the offset the later frames are sided with.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from gaitnet.segmentation.postprocess import FootDetection, FootKeypointParams

__all__ = ["MIN_PAIRS", "MidlineEstimate", "pair_midpoint"]

MIN_PAIRS = 5
"""Fewest frames with both feet sided apart for an estimate."""


def pair_midpoint(feet: Sequence[FootDetection], params: FootKeypointParams) -> float | None:
    """The midpoint of a frame's left and right foot along the left axis, on the camera's
    scale (``lateral_offset_m`` added back), when the two largest feet were sided apart by
    their lateral order (at least ``min_separation_m``); else None."""
    pair = list(feet[:2])
    if len(pair) != 2 or {f.side for f in pair} != {"left", "right"}:
        return None
    if abs(pair[0].lateral_m - pair[1].lateral_m) < params.min_separation_m:
        return None
    return 0.5 * (pair[0].lateral_m + pair[1].lateral_m) + params.lateral_offset_m


class MidlineEstimate:
    """Collects :func:`pair_midpoint` of the first ``params.midline_frames`` frames (module
    docstring); :meth:`params` gives the parameters to side the later frames with."""

    def __init__(self, params: FootKeypointParams) -> None:
        self.base = params
        self.midpoints: list[float] = []
        self.frames = 0

    @property
    def collecting(self) -> bool:
        """Whether frames still count (the first ``midline_frames``)."""
        return self.frames < self.base.midline_frames

    def add(self, midpoint: float | None) -> None:
        """Count one frame, in frame order, with its :func:`pair_midpoint` (None: none)."""
        if not self.collecting:
            return
        self.frames += 1
        if midpoint is not None:
            self.midpoints.append(float(midpoint))

    @property
    def offset_m(self) -> float | None:
        """The median midpoint [m], None with fewer than :data:`MIN_PAIRS` frames."""
        if len(self.midpoints) < MIN_PAIRS:
            return None
        return float(np.median(self.midpoints))

    def params(self) -> FootKeypointParams:
        """The base parameters with ``lateral_offset_m`` set to the estimate (unchanged
        without one)."""
        offset = self.offset_m
        return self.base if offset is None else replace(self.base, lateral_offset_m=offset)
