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

The same frames give the body's forward in the camera frame (``feet.forward_in_camera``): the
lateral axis is ``up × forward``, and the optical axis made horizontal is forward only while
the pelvis is level. Walking tilts it from side to side (pelvic obliquity, about ±4°): its
horizontal part then swings sideways by about tan(pitch) times the tilt, ±7° at the default
70° pitch and ±30° at 85° (measured on simulated sessions' true camera poses), enough to put a
lone foot at 0.5 m on the other side of the midline (a session at 85° had 15 / 11 cm foot
NMATE from feet given the wrong side). The standing frames' horizontal optical axis, kept as a
direction fixed to the camera, is the pelvis's forward: a sideways tilt of the pelvis turns it
about itself, which leaves its horizontal direction unchanged (±2° at 85°, ±5° at 70°, where
what is left is the pelvis's own rotation about the vertical).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from gaitnet.segmentation.body_axes import horizontal_forward
from gaitnet.segmentation.postprocess import FootDetection, FootKeypointParams

__all__ = ["MIN_FORWARD_FRAMES", "MIN_PAIRS", "MidlineEstimate", "pair_midpoint"]

MIN_PAIRS = 5
"""Fewest frames with both feet sided apart for an estimate."""
MIN_FORWARD_FRAMES = 5
"""Fewest frames with gravity for an estimate of the body's forward."""


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
        self.forwards: list[np.ndarray] = []
        self.frames = 0

    @property
    def collecting(self) -> bool:
        """Whether frames still count (the first ``midline_frames``)."""
        return self.frames < self.base.midline_frames

    def add(self, midpoint: float | None, up_C: np.ndarray | None = None) -> None:
        """Count one frame, in frame order, with its :func:`pair_midpoint` (None: none) and
        its up direction in the camera frame (None: unknown)."""
        if not self.collecting:
            return
        self.frames += 1
        if midpoint is not None:
            self.midpoints.append(float(midpoint))
        if up_C is not None:
            up = np.asarray(up_C, dtype=np.float64)
            if up.shape == (3,) and np.all(np.isfinite(up)) and np.linalg.norm(up) > 0:
                self.forwards.append(horizontal_forward(up))

    @property
    def offset_m(self) -> float | None:
        """The median midpoint [m], None with fewer than :data:`MIN_PAIRS` frames."""
        if len(self.midpoints) < MIN_PAIRS:
            return None
        return float(np.median(self.midpoints))

    @property
    def forward_C(self) -> np.ndarray | None:
        """The body's forward in the camera frame (unit; module docstring): the normalised
        median of the frames' horizontal optical axes, None with fewer than
        :data:`MIN_FORWARD_FRAMES` frames."""
        if len(self.forwards) < MIN_FORWARD_FRAMES:
            return None
        forward = np.median(np.array(self.forwards), axis=0)
        norm = float(np.linalg.norm(forward))
        return forward / norm if norm > 1e-6 else None

    def params(self) -> FootKeypointParams:
        """The base parameters with ``lateral_offset_m`` and, unless the base gives it,
        ``forward_in_camera`` set to the estimates (each unchanged without one)."""
        changes: dict[str, object] = {}
        if (offset := self.offset_m) is not None:
            changes["lateral_offset_m"] = offset
        if self.base.forward_in_camera is None and (forward := self.forward_C) is not None:
            changes["forward_in_camera"] = tuple(float(v) for v in forward)
        return replace(self.base, **changes) if changes else self.base  # type: ignore[arg-type]
