"""Stances the camera never saw, laid from the rhythm of the steps (``pipeline.hidden_stances``).

Under a knee flexed 25–30° in early stance, a real walker's thigh hides the planted foot from a
waist-worn camera looking down: a tall walker's foot shows 0–300 pixels through its whole
foot-flat, with little or no depth (docs/benchmarks.md, *Real motion*), and the filter finds no
landmark there. Each missed stance costs its foot two strides. The camera's own height still
shows the step: the pelvis is lowest just after each heel strike (the double support of the
inverted-pendulum gait) and highest at mid-stance, 2–5 cm apart on a walk, and the smoothed
camera path follows it to millimetres.

:func:`step_dips` finds those dips: the camera's height, resampled at the frame rate and
low-passed at :data:`LOWPASS_HZ`, has a minimum of prominence ``pipeline.step_dip_m`` at least
:data:`MIN_STEP_S` after the previous one while the camera moves faster than
:data:`WALKING_SPEED_MPS` along the floor. On the simulated walks, generated and real, each dip
lies 0–0.1 s after a heel strike; the last step of a walk, which brings the feet together, has
none.

:func:`hidden_stances` numbers the steps by their dips and gives each landmark its step:

- landmarks beginning before the first dip (less :data:`BEFORE_DIP_S`) stood there: step −1;
- a landmark beginning :data:`BEFORE_DIP_S` before to :data:`AFTER_DIP_S` after a dip is that
  dip's step (the nearest to :data:`DEFAULT_DELAY_S` after it);
- one beginning later than that after the last dip closes the walk: step ``n`` (the dips).

Taken in time order, two landmarks with steps ``a`` and ``b ≥ a + 2`` and no landmark between
them bound unseen steps ``a + 1 … b − 1``, whose sides alternate back from ``b``'s. Where ``a``'s
side breaks that alternation, a dip was missed or one too many was found between them, and
that gap is left; so is every gap next to a landmark on no step or to two landmarks on one
walking step. Each step of a gap gets a stance of its side:

- along the walking line (the camera's path averaged over ``vio.stance.line_window_s`` either
  side, as the stance tracker's sides: docs/vio.md), at the arc length interpolated in step
  number between those of steps ``a`` and ``b`` (steady steps between two seen ones; the
  closing step ``n`` rests beside step ``n − 1``, and counts as that step here);
- across it at the median offset of that foot's walking landmarks (those of steps
  ``0 … n − 1`` but each foot's last); a foot without one mirrors the other foot's about the
  middle of the feet (that of the feet standing before the first dip, else the mean of each
  foot's median offset over all its landmarks), and a walk without any lies
  :data:`HALF_STEP_WIDTH_M` either side of that middle: feet standing lie wider apart than
  walking ones;
- beginning at its dip plus the walk's median delay from dip to landmark (0.1 s when fewer than
  two landmarks give one), lasting the median of the walking landmarks' durations (half a
  step when none has one). Each foot's last landmark gives neither: the foot may stand there
  to the end, settled late.

A walking landmark (steps ``0 … n − 1``) first seen more than :data:`LATE_S` after its dip plus
that delay was hidden as the foot came down (the last stance of a tall walker: 0.34 s late,
which put its stride out of a 0.25 s match): it starts at its dip plus the delay instead, when
that dip keeps the walk's rhythm (:data:`RHYTHM_TOLERANCE`; a walk of fewer than three dips
has none).

Such a stance is ``inferred``: it has no observation (``n_observations`` 0, a negative
``landmark_id``), its standard deviations are :data:`INFERRED_STD_M`, and a stride that joins
it says so in ``strides.csv`` (``inferred``). Its position assumes the steps between two seen
stances are equal: an asymmetric gait is averaged there.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from gaitnet.filters import butterworth2_lowpass, filtfilt2
from gaitnet.vio.gait import SIDES, Stance, strides_from_stances
from gaitnet.vio.result import StanceFoot, VioResult

__all__ = [
    "AFTER_DIP_S",
    "BEFORE_DIP_S",
    "HALF_STEP_WIDTH_M",
    "HEADING_CHORD_M",
    "INFERRED_STD_M",
    "LATE_S",
    "LOWPASS_HZ",
    "MIN_STEP_S",
    "RHYTHM_TOLERANCE",
    "WALKING_SPEED_MPS",
    "WalkingLine",
    "hidden_stances",
    "step_dips",
    "with_hidden_stances",
]

log = logging.getLogger(__name__)

LOWPASS_HZ = 4.0
"""Cut-off of the low-pass on the camera's height: above a fast cadence's step rate (2.5 Hz)
and below the strap's bounce."""
MIN_STEP_S = 0.3
"""Dips closer than this are one step (a cadence of 200 steps per minute)."""
WALKING_SPEED_MPS = 0.3
"""A dip counts only where the walking line moves faster than this along the floor."""
BEFORE_DIP_S = 0.15
"""A landmark may begin this long before its step's dip (the dip trails the heel strike)."""
AFTER_DIP_S = 0.45
"""... and this long after it (a landmark is confirmed a few frames into foot-flat; the last
stance of a walk later, as the foot settles)."""
DEFAULT_DELAY_S = 0.1
"""Dip to landmark where fewer than two landmarks give the walk's own delay."""
LATE_S = 0.15
"""A walking landmark first seen more than this after its dip plus the walk's delay was hidden
as the foot came down: it starts at its dip plus the delay."""
RHYTHM_TOLERANCE = 0.25
"""A dip re-times a landmark only when its intervals to the dips either side lie within this
fraction of the walk's median interval (in gait initiation a dip came 0.15 s before its heel
strike, 0.72 and 1.33 intervals from its neighbours)."""
HEADING_CHORD_M = 0.5
"""The walking line's heading is its chord over this much path either side [m]."""
HALF_STEP_WIDTH_M = 0.04
"""Half a typical walking step width (8 cm between the feet's lines), for a walk with no
walking landmark to measure it: standing feet lie wider apart (16 cm on the simulated walks,
which put the laid stances of CMU walks 5–7 cm out)."""
INFERRED_STD_M = 0.03
"""Standard deviation given to an inferred stance's position [m] (steps differ by 1–3 cm)."""


def _uniform(t_s: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``values`` (n, ...) resampled on a grid at the median frame interval."""
    dt = float(np.median(np.diff(t_s)))
    grid = np.arange(t_s[0], t_s[-1] + 0.5 * dt, dt)
    cols = values.reshape(len(t_s), -1)
    out = np.stack([np.interp(grid, t_s, c) for c in cols.T], axis=1)
    return grid, out.reshape((len(grid),) + values.shape[1:])


def _moving_average(t_s: np.ndarray, values: np.ndarray, half_window_s: float) -> np.ndarray:
    """The mean of ``values`` (n, d) over ``t ± half_window_s`` at each time, by cumulative sums."""
    c = np.vstack([np.zeros((1, values.shape[1])), np.cumsum(values, axis=0)])
    lo = np.searchsorted(t_s, t_s - half_window_s, side="left")
    hi = np.searchsorted(t_s, t_s + half_window_s, side="right")
    return (c[hi] - c[lo]) / (hi - lo)[:, None]


@dataclass(frozen=True)
class WalkingLine:
    """The camera's path along the floor averaged over a step either side: at the times ``t_s``
    (n,), its points ``xy`` (n, 2), arc length ``s`` (n,, never decreasing) and unit heading
    ``u`` (n, 2): the chord from :data:`HEADING_CHORD_M` back along the path to as far ahead
    (shorter at the ends), so that standing takes the heading of the walk's first metre and
    not the sideways start of gait initiation, nor the millimetres the averaged path wanders."""

    t_s: np.ndarray
    xy: np.ndarray
    s: np.ndarray
    u: np.ndarray

    @classmethod
    def of(cls, t_s: np.ndarray, T_WfromC: np.ndarray, half_window_s: float) -> WalkingLine:
        xy = _moving_average(t_s, T_WfromC[:, :2, 3], half_window_s)
        s = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(xy, axis=0), axis=1))]
        ahead = np.minimum(np.searchsorted(s, s + HEADING_CHORD_M), len(s) - 1)
        back = np.maximum(np.searchsorted(s, s - HEADING_CHORD_M, side="right") - 1, 0)
        chord = xy[ahead] - xy[back]
        length = np.linalg.norm(chord, axis=1)
        u = np.tile([1.0, 0.0], (len(t_s), 1))
        moved = length > 1e-6
        u[moved] = chord[moved] / length[moved, None]
        return cls(t_s, xy, s, u)

    def frame_at(self, t: float) -> tuple[np.ndarray, float, np.ndarray]:
        """The line's point, arc length and heading at time ``t``."""
        k = int(np.clip(np.searchsorted(self.t_s, t), 0, len(self.t_s) - 1))
        return self.xy[k], float(self.s[k]), self.u[k]

    def along_across(self, xy: np.ndarray, t: float) -> tuple[float, float]:
        """A floor point's arc length along the line and offset across it (left positive),
        taken at the line's point of time ``t``."""
        p, s, u = self.frame_at(t)
        d = np.asarray(xy, dtype=float) - p
        return s + float(d @ u), float(u[0] * d[1] - u[1] * d[0])

    def point(self, s: float, across: float) -> np.ndarray:
        """The floor point at arc length ``s`` along the line and ``across`` to its left."""
        k = int(np.clip(np.searchsorted(self.s, s), 0, len(self.s) - 1))
        u = self.u[k]
        return self.xy[k] + (s - self.s[k]) * u + across * np.array([-u[1], u[0]])


def _prominent_minima(z: np.ndarray, prominence: float, distance: int) -> np.ndarray:
    """Indices of the local minima of ``z`` (the middle of a flat one) whose prominence is at
    least ``prominence``: their depth below the lower of the highest points between them and
    the nearest lower sample on each side (or the signal's end). Of minima closer than
    ``distance`` samples the deepest is kept."""
    n = len(z)
    if n < 3:
        return np.zeros(0, dtype=np.int64)
    d = np.sign(np.diff(z))
    for k in range(len(d) - 2, -1, -1):  # a flat stretch takes the slope after it
        if d[k] == 0:
            d[k] = d[k + 1]
    starts = np.flatnonzero((d[:-1] < 0) & (d[1:] > 0)) + 1
    found = []
    for i in starts:
        j = i
        while j + 1 < n and z[j + 1] == z[i]:
            j += 1
        lower_left = np.flatnonzero(z[:i] < z[i])
        lower_right = np.flatnonzero(z[j + 1 :] < z[i])
        left = z[lower_left[-1] + 1 : i].max() if lower_left.size else z[:i].max()
        right = z[j + 1 : j + 1 + lower_right[0]].max() if lower_right.size else z[j + 1 :].max()
        if min(left, right) - z[i] >= prominence:
            found.append((i + j) // 2)
    kept: list[int] = []
    for k in sorted(found, key=lambda k: z[k]):  # deepest first
        if all(abs(k - m) >= distance for m in kept):
            kept.append(k)
    return np.array(sorted(kept), dtype=np.int64)


def step_dips(t_s: np.ndarray, T_WfromC: np.ndarray, min_dip_m: float) -> np.ndarray:
    """Times [s] of the camera's height dips that mark steps (module docstring), in order."""
    t_s = np.asarray(t_s, dtype=float)
    if len(t_s) < 16 or t_s[-1] - t_s[0] < 1.0:
        return np.zeros(0)
    grid, pose = _uniform(t_s, np.asarray(T_WfromC, dtype=float)[:, :3, 3])
    fs = 1.0 / (grid[1] - grid[0])
    z = pose[:, 2]
    if fs > 2.5 * LOWPASS_HZ and len(z) > 12:
        b, a = butterworth2_lowpass(LOWPASS_HZ / (fs / 2.0))
        z = filtfilt2(b, a, z, padlen=9)
    dips = _prominent_minima(z, min_dip_m, max(1, int(MIN_STEP_S * fs)))
    path = _moving_average(grid, pose[:, :2], 0.3)
    speed = np.linalg.norm(np.gradient(path, grid, axis=0), axis=1)
    return grid[[k for k in dips if speed[k] > WALKING_SPEED_MPS]]


def _in_rhythm(dips: np.ndarray) -> np.ndarray:
    """(n,) whether each dip lies in the walk's rhythm (:data:`RHYTHM_TOLERANCE`)."""
    if len(dips) < 3:
        return np.zeros(len(dips), dtype=bool)
    gaps = np.diff(dips) / np.median(np.diff(dips))
    fits = np.abs(gaps - 1.0) <= RHYTHM_TOLERANCE
    return np.r_[True, fits] & np.r_[fits, True]


def _step_of(foot: StanceFoot, dips: np.ndarray) -> int | None:
    """A landmark's step (module docstring); None: it lies on no step."""
    d = foot.t_first_s - dips
    inside = np.flatnonzero((d >= -BEFORE_DIP_S) & (d <= AFTER_DIP_S))
    if inside.size:
        return int(inside[np.argmin(np.abs(d[inside] - DEFAULT_DELAY_S))])
    if d[0] < -BEFORE_DIP_S:
        return -1
    if d[-1] > AFTER_DIP_S:
        return len(dips)
    return None


@dataclass(frozen=True)
class _Anchor:
    """Landmarks of one step, in the order of the walk; ``step`` None: a landmark on no
    step, or two on one walking step (the dips do not count the steps there)."""

    step: int | None
    feet: tuple[StanceFoot, ...]

    @property
    def t_s(self) -> float:
        return min(f.t_first_s for f in self.feet)


def _anchors(stance_feet: Sequence[StanceFoot], dips: np.ndarray) -> list[_Anchor]:
    """The landmarks grouped by step (standing ones together), in time order."""
    groups: dict[int, list[StanceFoot]] = {}
    anchors: list[_Anchor] = []
    for foot in stance_feet:
        k = _step_of(foot, dips)
        if k is None:
            anchors.append(_Anchor(None, (foot,)))
        else:
            groups.setdefault(k, []).append(foot)
    for k, feet in groups.items():
        anchors.append(_Anchor(k if k < 0 or len(feet) == 1 else None, tuple(feet)))
    return sorted(anchors, key=lambda a: a.t_s)


def _gap_sides(a: _Anchor, b: _Anchor) -> list[tuple[int, str]] | None:
    """The steps strictly between anchors ``a`` and ``b`` with the sides the alternation gives
    them from ``b``'s, or None where ``a``'s side breaks the alternation (a dip missed or one
    too many between them)."""
    if a.step is None or b.step is None:
        return None
    side_b = b.feet[0].side
    other = {"left": "right", "right": "left"}
    if a.step >= 0 and (a.feet[0].side == side_b) != ((b.step - a.step) % 2 == 0):
        return None
    return [(k, side_b if (b.step - k) % 2 == 0 else other[side_b])
            for k in range(a.step + 1, b.step)]  # fmt: skip


def _offsets_across(
    line: WalkingLine,
    stance_feet: Sequence[StanceFoot],
    walking: Sequence[StanceFoot],
    standing: Sequence[StanceFoot],
) -> dict[str, float]:
    """Each foot's offset across the walking line while walking (module docstring)."""

    def median(feet: Sequence[StanceFoot]) -> float | None:
        values = [line.along_across(f.xy, f.t_first_s)[1] for f in feet]
        return float(np.median(values)) if values else None

    if {f.side for f in standing} == set(SIDES):
        centre = float(np.mean([median([f]) for f in standing]))
    else:
        every = [median([f for f in stance_feet if f.side == side]) for side in SIDES]
        centre = float(np.mean([v for v in every if v is not None]))
    own = {side: median([f for f in walking if f.side == side]) for side in SIDES}
    out = {}
    for side, other in (("left", "right"), ("right", "left")):
        if own[side] is not None:
            out[side] = own[side]
        elif own[other] is not None:
            out[side] = 2.0 * centre - own[other]
        else:
            out[side] = centre + (HALF_STEP_WIDTH_M if side == "left" else -HALF_STEP_WIDTH_M)
    return out


def hidden_stances(
    stance_feet: Sequence[StanceFoot],
    t_s: np.ndarray,
    T_WfromC: np.ndarray,
    min_dip_m: float,
    line_window_s: float,
) -> tuple[list[StanceFoot], str]:
    """``stance_feet`` with the stances that the camera's height dips show and no landmark
    holds added, and the walking landmarks first seen late re-timed (module docstring), in
    time order, with a sentence saying what was done."""
    dips = step_dips(t_s, T_WfromC, min_dip_m)
    if dips.size == 0 or not stance_feet:
        return list(stance_feet), "no step dips in the camera's height"
    n = len(dips)
    anchors = _anchors(stance_feet, dips)
    line = WalkingLine.of(np.asarray(t_s, float), np.asarray(T_WfromC, float), line_window_s)
    last_of = {f.side: f for f in sorted(stance_feet, key=lambda f: f.t_first_s)}
    walking_all = [(a.step, a.feet[0]) for a in anchors if a.step is not None and 0 <= a.step < n]
    walking = [  # a foot's last landmark may be where it stands at the end: late, and long
        (k, f) for k, f in walking_all if f is not last_of[f.side]
    ]
    delays = [f.t_first_s - dips[k] for k, f in walking]
    delay = float(np.median(delays)) if len(delays) >= 2 else DEFAULT_DELAY_S
    lasting = [f.t_last_s - f.t_first_s for _, f in walking]
    duration = float(np.median(lasting)) if lasting else 0.5 * float(np.median(np.diff(dips)))
    standing = [f for a in anchors if a.step == -1 for f in a.feet]
    across = _offsets_across(line, stance_feet, [f for _, f in walking], standing)

    def along(a: _Anchor) -> float:
        return float(np.mean([line.along_across(f.xy, f.t_first_s)[0] for f in a.feet]))

    rhythm = _in_rhythm(dips)
    retimed = {
        id(f): replace(f, t_first_s=float(dips[k] + delay))
        for k, f in walking_all
        if f.t_first_s > dips[k] + delay + LATE_S and rhythm[k]
    }
    laid: list[StanceFoot] = []
    broken = 0
    for a, b in zip(anchors, anchors[1:], strict=False):
        if a.step is None or b.step is None or b.step - a.step < 2:
            continue
        sides = _gap_sides(a, b)
        if sides is None:
            broken += 1
            continue
        b_step = min(b.step, n - 1)  # the closing foot comes to rest beside the last step
        for k, side in sides:
            s = along(a) + (along(b) - along(a)) * (k - a.step) / (b_step - a.step)
            t_first = float(dips[k] + delay)
            laid.append(
                StanceFoot(
                    -1 - k, side, t_first, t_first + duration,
                    line.point(s, across[side]),
                    np.full(2, INFERRED_STD_M), 0, inferred=True,
                )  # fmt: skip
            )
    note = f"{n} step dips, {len(laid)} hidden stances laid, {len(retimed)} seen late re-timed"
    if broken:
        note += f"; {broken} gap(s) left where the landmarks' sides break the alternation"
    feet = [retimed.get(id(f), f) for f in stance_feet] + laid
    return sorted(feet, key=lambda f: f.t_first_s), note


def with_hidden_stances(
    vio: VioResult, min_dip_m: float, line_window_s: float, gait_limits: tuple[float, float]
) -> VioResult:
    """``vio`` with its stance feet as :func:`hidden_stances` gives them and its strides
    recomputed (``gait_limits``: ``vio.gait.max_stride_time_s``, ``max_stance_time_s``)."""
    feet, note = hidden_stances(vio.stance_feet, vio.t_s, vio.T_WfromC, min_dip_m, line_window_s)
    log.info("%s", note)
    if {id(f) for f in feet} == {id(f) for f in vio.stance_feet}:  # nothing laid or re-timed
        return vio
    stances = [Stance(f.side, f.t_first_s, f.t_last_s, f.xy, f.inferred) for f in feet]
    try:
        strides = strides_from_stances(stances, *gait_limits)
    except ValueError as exc:  # two stances of a foot at one time: the dips misled
        log.warning("the stances laid from the step rhythm are dropped: %s", exc)
        return vio
    return replace(vio, stance_feet=feet, strides=strides)
