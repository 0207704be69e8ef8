"""Filling a foot's unseen swing from the filter's stance landmarks (``pipeline.gap_fill: swing``).

A waist camera loses each foot for 0.5–0.8 s of every stride (thesis Fig. 5.10): from about
heel off, when the foot is behind the body, to late swing. The motion predictor alone moves the
foot there too early and too evenly (the true foot rests, rolls over the toes, then swings with
its peak speed late), which left 8–10 cm errors in those frames (docs/pipeline.md). The filter
knows more than the frames do: where the foot stood before the gap and where it lands after
it (two consecutive stance landmarks of that foot, :class:`gaitnet.vio.result.StanceFoot`), and
when it lands (the next landmark's first frame, at foot flat). Between them the swing of a
walking foot has a stereotyped shape, which this module lays between the two rests:

    f(t) = p₀ + ρ(τ) (p₁ − p₀) + λ(τ) H ẑ,   τ = clip((t − t_HO) / (t_FF′ − t_HO), 0, 1)

- ``p₀``, ``p₁``: the median measured foot point over the frames of each stance (the points
  the correction is given, so the fill is the same kind of point);
- ``t_FF′``: the next landmark's first frame time; ``t_HO``, heel off of the first stance,
  ``t_FF′ − c · T`` with ``T`` the landmarks' foot-flat to foot-flat time (one gait cycle; the
  foot's median one when they differ by more than :data:`CYCLE_TOLERANCE`, as after a
  standing start, where the first landmark began long before the foot flat) and
  ``c`` = ``pipeline.swing_heel_off_fraction`` (0.75: heel off at 31–38 % of the cycle and foot
  flat at 8–10 % of the next, docs/references.md *Gait phases*), and never before the last
  frame the filter saw the foot resting;
- ``ρ`` (0 → 1, :data:`SWING_PROGRESS`) and ``λ`` (:data:`SWING_LIFT`, a fraction of the body
  height ``H``): the mean path of the instep marker from heel off to the next foot flat over
  the simulator's walks at 0.8–1.6 m/s (458 swings of 30 subjects; derived by
  ``data/derive_swing_template.py`` with :func:`gaitnet.sim.swing_profile.derive_swing_template`,
  and checked against a fresh derivation by a test); its timing is checked against real
  walking in docs/pipeline.md.

Only frames where the foot is not steadily seen (:func:`gaitnet.pipeline.gap_bridge.steadily_seen`)
between the two landmarks are filled; a pair of landmarks is skipped when it cannot be one
stride of one foot (:data:`CYCLE_RANGE_S`, :data:`MIN_STRIDE_M`, :data:`MAX_STRIDE_M`) or
either stance has no measured point. :func:`gaitnet.pipeline.infer.reconstruct` runs the pose
correction a second time with the filled points as that foot's measurements.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from gaitnet.pipeline.gap_bridge import steadily_seen
from gaitnet.vio.result import StanceFoot

__all__ = [
    "CYCLE_RANGE_S",
    "CYCLE_TOLERANCE",
    "MAX_STRIDE_M",
    "MIN_STRIDE_M",
    "SWING_LIFT",
    "SWING_PROGRESS",
    "SWING_TAU",
    "swing_fill",
]

SIDES = ("left", "right")
SWING_TAU = np.linspace(0.0, 1.0, 21)
# fmt: off
SWING_PROGRESS = np.array([
    0.0, 0.0003, 0.0026, 0.0087, 0.0206, 0.0397, 0.0654, 0.0973, 0.1392, 0.1968, 0.2803,
    0.3942, 0.5307, 0.6718, 0.7967, 0.8898, 0.9467, 0.9750, 0.9893, 0.9981, 1.0,
])
SWING_LIFT = np.array([
    0.0, 0.0004, 0.0032, 0.0096, 0.0190, 0.0292, 0.0371, 0.0414, 0.0462, 0.0503, 0.0530,
    0.0531, 0.0508, 0.0480, 0.0451, 0.0400, 0.0318, 0.0220, 0.0113, 0.0023, 0.0,
])
# fmt: on
CYCLE_RANGE_S = (0.5, 3.0)  # foot flat to foot flat of one foot, slow to fast walking
CYCLE_TOLERANCE = 0.25  # a pair's cycle further than this from the foot's median is not used
MIN_STRIDE_M = 0.2  # shorter: a shuffle or one stance seen as two, not a swing
MAX_STRIDE_M = 2.2  # longer than any walking stride


def swing_fill(
    t_s: np.ndarray,
    measured: np.ndarray,
    stance_feet: Sequence[StanceFoot],
    body_height_m: float,
    heel_off_fraction: float = 0.75,
) -> np.ndarray:
    """Foot points (n, 2, 3) for the unseen frames of each foot's swings (module docstring),
    NaN elsewhere. ``t_s`` (n,) frame times, ``measured`` (n, 2, 3) the measured foot points
    (left, right; NaN where not seen), ``stance_feet`` the filter's landmarks."""
    t_s = np.asarray(t_s, dtype=np.float64)
    measured = np.asarray(measured, dtype=np.float64)
    if measured.shape != (len(t_s), 2, 3):
        raise ValueError(
            f"swing_fill: measured must be (n, 2, 3) for n = {len(t_s)} frames, "
            f"got {measured.shape}"
        )
    out = np.full(measured.shape, np.nan)
    for s, side in enumerate(SIDES):
        seen = steadily_seen(~np.isnan(measured[:, s, 0]))
        rests = sorted((f for f in stance_feet if f.side == side), key=lambda f: f.t_first_s)
        pairs = list(zip(rests, rests[1:], strict=False))
        cycles = np.array([b.t_first_s - a.t_first_s for a, b in pairs])
        plausible = cycles[(cycles >= CYCLE_RANGE_S[0]) & (cycles <= CYCLE_RANGE_S[1])]
        typical = float(np.median(plausible)) if plausible.size else np.nan
        for (before, after), cycle in zip(pairs, cycles, strict=True):
            if not CYCLE_RANGE_S[0] <= cycle <= CYCLE_RANGE_S[1]:
                continue
            if abs(cycle - typical) > CYCLE_TOLERANCE * typical:
                cycle = typical  # a landmark first seen late or early (a standing start)
            p0 = _rest_point(t_s, measured[:, s], seen, before)
            p1 = _rest_point(t_s, measured[:, s], seen, after)
            if p0 is None or p1 is None:
                continue
            if not MIN_STRIDE_M <= np.hypot(*(p1 - p0)[:2]) <= MAX_STRIDE_M:
                continue
            heel_off = max(after.t_first_s - heel_off_fraction * cycle, before.t_last_s)
            window = (t_s > before.t_last_s) & (t_s < after.t_first_s) & ~seen
            if not window.any():
                continue
            span = max(after.t_first_s - heel_off, 1e-6)
            tau = np.clip((t_s[window] - heel_off) / span, 0.0, 1.0)
            rho = np.interp(tau, SWING_TAU, SWING_PROGRESS)
            lift = np.interp(tau, SWING_TAU, SWING_LIFT) * body_height_m
            out[window, s] = p0 + rho[:, None] * (p1 - p0)
            out[window, s, 2] += lift
    return out


def _rest_point(
    t_s: np.ndarray, points: np.ndarray, seen: np.ndarray, rest: StanceFoot
) -> np.ndarray | None:
    """Median measured point (3,) over the frames of one stance, None when none is measured."""
    inside = seen & (t_s >= rest.t_first_s - 1e-6) & (t_s <= rest.t_last_s + 1e-6)
    if not inside.any():
        return None
    return np.median(points[inside], axis=0)
