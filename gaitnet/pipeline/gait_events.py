"""Gait events (initial contact, toe off) from gap-free foot trajectories (docs/report.md).

Input: the frame times and, per side, one point of the foot in the world frame (z up, floor
z = 0; a point on the shoe such as the instep marker, or the ankle), gap-free (swing frames
filled in). Optionally the pelvis and hips (7-joint positions) for the toe off.

The rule, per side:

1. **Resample and smooth.** The trajectory is interpolated onto a uniform grid at the median
   frame interval (dropped frames and timestamp jitter), then low-passed by a zero-phase
   second-order Butterworth filter at ``cutoff_hz`` (6 Hz, the usual cut-off for walking marker
   data: D. A. Winter, *Biomechanics and Motor Control of Human Movement*, 4th ed., Wiley 2009,
   sec. 3.4). The filter is skipped when the cut-off is above 0.8 × Nyquist.
2. **Still intervals** (the foot flat on the floor): the foot point's 3-D speed below
   ``still_enter_mps`` while its height above the foot's floor level (the 5th percentile of its
   z over the session: a foot rests on the floor most of the time) is below ``max_height_m``,
   with hysteresis: the interval ends when the speed rises above ``still_leave_mps`` or the
   height above ``max_height_m``. Consecutive intervals are joined when the gap between them is
   shorter than ``min_swing_s`` (no foot swings that fast) or their mean positions are closer
   than ``same_place_m`` (a foot is not lifted and set down on the same spot; the rule and
   value of :func:`gaitnet.vio.gait.merge_split_stances`); intervals shorter than
   ``min_still_s`` are dropped. Each still interval is one stance.
3. **Initial contact** (IC) of a stance: the minimum of the foot point's vertical velocity
   within ``search_s`` before the still interval starts (and after the middle of the preceding
   swing): the *foot velocity algorithm* of C. M. O'Connor, S. K. Thorpe, M. J. O'Malley, C. L.
   Vaughan, "Automatic detection of gait events using kinematic data", *Gait & Posture*
   25(3):469–474, 2007 (heel strike at the minimum of the foot centre's vertical velocity), with
   the one foot point in place of the heel–toe midpoint. A stance gets an IC only when the foot
   arrived from elsewhere: at the start of the search window it was at least ``same_place_m``
   from the stance's position (a stance already still at the first frame, or one that starts
   while the recording starts, has none).
4. **Toe off** (TO): within ``search_s`` after the still interval ends (and before the middle
   of the following swing). With the pelvis and hips given: the minimum of the foot's forward
   position relative to the pelvis (P. A. Zeni Jr., J. G. Richards, J. S. Higginson, "Two
   simple methods for determining gait events during treadmill and overground walking using
   kinematic data", *Gait & Posture* 27(4):710–714, 2008: toe off at the most posterior toe
   position relative to the sacrum; forward is z × (L_hip − R_hip)); without them the maximum
   of the vertical velocity (O'Connor et al. 2007). Likewise a TO needs the foot to have left:
   at the end of the search window it is at least ``same_place_m`` from the stance.

Extrema are refined to sub-frame times by a parabola through the three samples around them.
The measured timing errors against the simulator's events are in docs/report.md.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gaitnet.errors import InputError
from gaitnet.filters import butterworth2_lowpass, filtfilt2
from gaitnet.vio.gait import Stance

__all__ = [
    "SIDES",
    "EventParams",
    "check_points",
    "check_times",
    "FootContact",
    "detect_events",
    "stances_from_contacts",
]

log = logging.getLogger(__name__)

SIDES = ("left", "right")
MIN_FRAMES = 10
FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class EventParams:
    """Thresholds of the event rule (module docstring); SI units."""

    cutoff_hz: float = 6.0
    still_enter_mps: float = 0.15
    still_leave_mps: float = 0.30
    max_height_m: float = 0.08
    min_still_s: float = 0.08
    min_swing_s: float = 0.15
    same_place_m: float = 0.08
    search_s: float = 0.35

    def __post_init__(self) -> None:
        for name, value in vars(self).items():
            if not np.isfinite(value) or value < 0:
                raise InputError(f"event parameter {name}: {value} is not a finite value >= 0")
        if self.still_leave_mps < self.still_enter_mps:
            raise InputError(
                f"event parameter still_leave_mps ({self.still_leave_mps}) is below "
                f"still_enter_mps ({self.still_enter_mps}): the hysteresis needs leave >= enter"
            )
        if self.search_s <= 0 or self.max_height_m <= 0 or self.still_enter_mps <= 0:
            raise InputError("event parameters search_s, max_height_m, still_enter_mps must be > 0")


@dataclass(frozen=True)
class FootContact:
    """One stance of one foot: ``initial_contact_s`` / ``toe_off_s`` [s] (None when the stance
    began before the first frame or ended after the last), the still interval
    ``still_start_s`` … ``still_end_s`` [s] and the foot point's mean position ``position``
    (3,) [m] over it."""

    side: str
    initial_contact_s: float | None
    toe_off_s: float | None
    still_start_s: float
    still_end_s: float
    position: FloatArray


def check_times(t_s: ArrayLike) -> FloatArray:
    """``t_s`` as a float array: 1-D, >= MIN_FRAMES times, finite, strictly increasing."""
    t = np.asarray(t_s, dtype=float)
    if t.ndim != 1 or t.size < MIN_FRAMES:
        raise InputError(
            f"frame times t_s: need a 1-D array of >= {MIN_FRAMES} times, got shape {t.shape}"
        )
    if not np.all(np.isfinite(t)):
        raise InputError("frame times t_s: not all finite")
    if np.any(np.diff(t) <= 0):
        raise InputError("frame times t_s: not strictly increasing")
    return t


def check_points(value: ArrayLike, n: int, name: str) -> FloatArray:
    """``value`` as an (n, 3) finite float array; ``name`` goes into the error."""
    p = np.asarray(value, dtype=float)
    if p.shape != (n, 3):
        raise InputError(f"{name}: expected shape ({n}, 3), got {p.shape}")
    if not np.all(np.isfinite(p)):
        raise InputError(f"{name}: not all finite (the trajectory must be gap-free)")
    return p


def _resample(t: FloatArray, values: FloatArray, grid: FloatArray) -> FloatArray:
    return np.stack([np.interp(grid, t, values[:, k]) for k in range(values.shape[1])], axis=1)


def _lowpass(values: FloatArray, dt: float, cutoff_hz: float) -> FloatArray:
    nyquist = 0.5 / dt
    if cutoff_hz <= 0 or cutoff_hz >= 0.8 * nyquist:
        log.info("gait events: no low-pass (cut-off %.1f Hz, Nyquist %.1f Hz)", cutoff_hz, nyquist)
        return values
    b, a = butterworth2_lowpass(cutoff_hz / nyquist)
    return filtfilt2(b, a, values, padlen=min(3 * len(a), len(values) - 1))


def _still_intervals(
    foot: FloatArray, speed: FloatArray, height: FloatArray, dt: float, p: EventParams
) -> list[tuple[int, int]]:
    """Inclusive index intervals of still frames (module docstring, step 2)."""
    still = np.zeros(speed.size, dtype=bool)
    inside = False
    for i in range(speed.size):
        low = height[i] < p.max_height_m
        if not inside and speed[i] < p.still_enter_mps and low:
            inside = True
        elif inside and (speed[i] > p.still_leave_mps or not low):
            inside = False
        still[i] = inside
    edges = np.diff(np.concatenate(([0], still.astype(np.int8), [0])))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1
    joined: list[list[int]] = []
    for a, b in zip(starts.tolist(), ends.tolist(), strict=True):
        if joined and (
            (a - joined[-1][1] - 1) * dt < p.min_swing_s
            or np.linalg.norm(
                foot[a : b + 1].mean(axis=0) - foot[joined[-1][0] : joined[-1][1] + 1].mean(axis=0)
            )
            < p.same_place_m
        ):
            joined[-1][1] = b
        else:
            joined.append([a, b])
    return [(a, b) for a, b in joined if (b - a) * dt >= p.min_still_s]


def _refine(grid: FloatArray, y: FloatArray, i: int) -> float:
    """Sub-frame time of the extremum at sample ``i`` (parabola through i−1, i, i+1)."""
    if 0 < i < y.size - 1:
        den = y[i - 1] - 2.0 * y[i] + y[i + 1]
        if den != 0.0:
            offset = 0.5 * (y[i - 1] - y[i + 1]) / den
            return float(grid[i] + np.clip(offset, -0.5, 0.5) * (grid[1] - grid[0]))
    return float(grid[i])


def _forward_offset(
    foot: FloatArray, pelvis: FloatArray, l_hip: FloatArray, r_hip: FloatArray
) -> FloatArray:
    """The foot's forward position relative to the pelvis; forward = z × (L_hip − R_hip)."""
    lateral = l_hip - r_hip
    forward = np.stack([lateral[:, 1], -lateral[:, 0]], axis=1)
    norm = np.linalg.norm(forward, axis=1, keepdims=True)
    forward = forward / np.maximum(norm, 1e-9)
    return np.sum((foot[:, :2] - pelvis[:, :2]) * forward, axis=1)


def _side_events(
    side: str,
    grid: FloatArray,
    foot: FloatArray,
    offset: FloatArray | None,
    p: EventParams,
) -> list[FootContact]:
    dt = float(grid[1] - grid[0])
    velocity = np.gradient(foot, dt, axis=0)
    speed = np.linalg.norm(velocity, axis=1)
    height = foot[:, 2] - np.percentile(foot[:, 2], 5)
    intervals = _still_intervals(foot, speed, height, dt, p)
    window = max(1, int(round(p.search_s / dt)))
    vz = velocity[:, 2]
    last = grid.size - 1
    contacts = []
    for k, (a, b) in enumerate(intervals):
        ic = to = None
        here = foot[a : b + 1].mean(axis=0)
        lo = max(a - window, (intervals[k - 1][1] + a) // 2 if k > 0 else 0)
        if a > 0 and np.linalg.norm(foot[lo] - here) >= p.same_place_m:
            ic = _refine(grid, vz, lo + int(np.argmin(vz[lo : a + 1])))
        hi = min(b + window, (b + intervals[k + 1][0]) // 2 if k + 1 < len(intervals) else last)
        if b < last and np.linalg.norm(foot[hi] - here) >= p.same_place_m:
            if offset is None:
                to = _refine(grid, vz, b + int(np.argmax(vz[b : hi + 1])))
            else:
                to = _refine(grid, offset, b + int(np.argmin(offset[b : hi + 1])))
        contacts.append(FootContact(side, ic, to, float(grid[a]), float(grid[b]), here))
    return contacts


def detect_events(
    t_s: ArrayLike,
    feet: Mapping[str, ArrayLike],
    joints: ArrayLike | None = None,
    params: EventParams | None = None,
) -> list[FootContact]:
    """Stances with their initial contact and toe off (module docstring) of each side in
    ``feet`` (``"left"``/``"right"`` → (n, 3) world points, gap-free), ordered by still start.
    ``joints`` (n, 7, 3): pelvis, L_hip, R_hip, ... (docs/design.md); when given, toe off uses
    the foot's position relative to the pelvis (Zeni et al. 2008)."""
    p = params or EventParams()
    t = check_times(t_s)
    n = t.size
    unknown = set(feet) - set(SIDES)
    if unknown or not feet:
        raise InputError(f"feet: keys must be among {SIDES}, got {sorted(feet)}")
    dt = float(np.median(np.diff(t)))
    grid = t[0] + dt * np.arange(int(np.floor((t[-1] - t[0]) / dt + 1e-9)) + 1)
    joints_g = None
    if joints is not None:
        j = np.asarray(joints, dtype=float)
        if j.ndim != 3 or j.shape[0] != n or j.shape[1] < 3 or j.shape[2] != 3:
            raise InputError(f"joints: expected shape ({n}, 7, 3), got {j.shape}")
        if not np.all(np.isfinite(j[:, :3])):
            raise InputError("joints: pelvis or hips not all finite")
        joints_g = [_resample(t, j[:, k], grid) for k in range(3)]
    contacts: list[FootContact] = []
    for side in SIDES:
        if side not in feet:
            continue
        foot = check_points(feet[side], n, f"foot trajectory {side!r}")
        foot_g = _lowpass(_resample(t, foot, grid), dt, p.cutoff_hz)
        offset = None
        if joints_g is not None:
            offset = _lowpass(_forward_offset(foot_g, *joints_g)[:, None], dt, p.cutoff_hz)[:, 0]
        contacts += _side_events(side, grid, foot_g, offset, p)
    return sorted(contacts, key=lambda c: (c.still_start_s, c.side))


def stances_from_contacts(contacts: list[FootContact]) -> list[Stance]:
    """The contacts as :class:`gaitnet.vio.gait.Stance` (still interval, floor position), for
    :func:`gaitnet.vio.gait.strides_from_stances` when no filter strides are at hand."""
    return [
        Stance(c.side, c.still_start_s, c.still_end_s, np.asarray(c.position[:2], dtype=float))
        for c in contacts
    ]
