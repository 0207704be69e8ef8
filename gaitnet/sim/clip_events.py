"""Foot contacts and gait events of a played motion, found from its shoes' heel and toe points.

A generated walk knows its events from its plan (:mod:`gaitnet.sim.gait`); a motion-capture
clip does not, so they are measured on what is rendered: the shoes' heel point (back of the
sole, shoe frame ``(−L/2, 0, 0)``) and toe point (``(+L/2, 0, 0)``) over the floor ``z = 0``.

A point touches the floor while it is within :data:`CONTACT_HEIGHT_M` of it and moves
horizontally slower than :data:`CONTACT_SPEED_MPS` (a swinging toe passes 1–2 cm over the floor
at several m/s; a planted sole of a clip slides at centimetres per second, and a rigid shoe
on a real foot, which bends, rests within a few degrees of level: 3 cm over a 28 cm sole is
6°). Contact runs shorter than :data:`MIN_CONTACT_S` are dropped and gaps shorter than
:data:`MIN_GAP_S` closed (marker noise). A stance is a run of heel or toe contact.

Its events are timed more tightly, against the heights the heel and the toe keep while both
are down (their medians over that time: a clip's foot rarely rests at exactly 0). A point
rests while it is within :data:`EVENT_HEIGHT_M` of its resting height and slower than
:data:`EVENT_SPEED_MPS`: heel strike (HS) is the stance's first sample with the heel resting
(the stance's start if it never does), foot flat (FF) the first with both points resting, heel
off (HO) the last, toe off (TO) the last with the toe resting. A stance without both points
down (toe walking) rests at its slowest sample. As in the generator, a stance that begins
with the motion has no HS/FF (standing) and one that lasts to its end no HO/TO; the foot-flat
placement of a stance (its ``sole_centre_W``, ``yaw_rad``) is the sole centre's mean and the
toe direction's circular mean over its time with both points down, so a clip's own foot
sliding is averaged, not hidden.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gaitnet.sim.gait import FootEvents, StepEvents
from gaitnet.sim.scene import SIDES, Side

__all__ = [
    "CONTACT_HEIGHT_M",
    "CONTACT_SPEED_MPS",
    "MIN_CONTACT_S",
    "EVENT_HEIGHT_M",
    "EVENT_SPEED_MPS",
    "MIN_GAP_S",
    "FootContacts",
    "foot_contacts",
    "foot_events",
    "step_events",
]

CONTACT_HEIGHT_M = 0.03
CONTACT_SPEED_MPS = 0.5
MIN_CONTACT_S = 0.06
MIN_GAP_S = 0.06
EVENT_HEIGHT_M = 0.008
EVENT_SPEED_MPS = 0.15


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """Inclusive index ranges ``(a, b)`` of the True runs of ``mask``."""
    m = np.concatenate([[False], np.asarray(mask, bool), [False]])
    edges = np.flatnonzero(np.diff(m.astype(np.int8)))
    return [(int(a), int(b) - 1) for a, b in zip(edges[::2], edges[1::2], strict=True)]


def _debounce(mask: np.ndarray, min_gap: int, min_run: int) -> np.ndarray:
    """Close False gaps shorter than ``min_gap`` samples between True runs, then drop True
    runs shorter than ``min_run``."""
    out = np.asarray(mask, bool).copy()
    runs = _runs(out)
    for (_, b0), (a1, _) in zip(runs[:-1], runs[1:], strict=True):
        if a1 - b0 - 1 < min_gap:
            out[b0 + 1 : a1] = True
    for a, b in _runs(out):
        if b - a + 1 < min_run:
            out[a : b + 1] = False
    return out


@dataclass(frozen=True, eq=False)
class FootContacts:
    """One foot's contact flags per sample (``heel``, ``toe``) and its stances (inclusive
    sample ranges)."""

    heel: np.ndarray
    toe: np.ndarray
    stances: tuple[tuple[int, int], ...]

    def flat(self, a: int, b: int) -> tuple[int, int] | None:
        """First and last sample with both points down within ``[a, b]`` (None: none)."""
        both = np.flatnonzero(self.heel[a : b + 1] & self.toe[a : b + 1])
        return None if len(both) == 0 else (a + int(both[0]), a + int(both[-1]))


def foot_contacts(t: np.ndarray, heel_W: np.ndarray, toe_W: np.ndarray) -> FootContacts:
    """Contacts of one foot from its heel and toe points ``(n, 3)`` at uniform times ``t``."""
    dt = float(np.median(np.diff(t)))
    min_gap = max(1, int(round(MIN_GAP_S / dt)))
    min_run = max(1, int(round(MIN_CONTACT_S / dt)))

    def touching(p: np.ndarray) -> np.ndarray:
        speed = np.linalg.norm(np.gradient(p[:, :2], t, axis=0), axis=1)
        down = (p[:, 2] < CONTACT_HEIGHT_M) & (speed < CONTACT_SPEED_MPS)
        return _debounce(down, min_gap, min_run)

    heel, toe = touching(heel_W), touching(toe_W)
    foot = _debounce(heel | toe, min_gap, min_run)
    return FootContacts(heel & foot, toe & foot, tuple(_runs(foot)))


def _circular_mean(angles: np.ndarray) -> float:
    return float(np.arctan2(np.mean(np.sin(angles)), np.mean(np.cos(angles))))


def _settled(p: np.ndarray, t: np.ndarray, level: float) -> np.ndarray:
    """Samples of a sole point ``p`` (m, 3) resting: within :data:`EVENT_HEIGHT_M` of its
    resting height and slower than :data:`EVENT_SPEED_MPS` along the floor."""
    speed = np.linalg.norm(np.gradient(p[:, :2], t, axis=0), axis=1) if len(p) > 1 else 0.0
    return (p[:, 2] <= level + EVENT_HEIGHT_M) & (speed < EVENT_SPEED_MPS)


def foot_events(
    side: Side,
    t: np.ndarray,
    contacts: FootContacts,
    soles_W: np.ndarray,
    toe_dir_W: np.ndarray,
    heel_W: np.ndarray,
    toe_W: np.ndarray,
) -> FootEvents:
    """The :class:`~gaitnet.sim.gait.FootEvents` of one foot (module docstring) from its
    contacts, sole centres ``(n, 3)``, toe directions ``(n, 3)`` and heel and toe points
    ``(n, 3)`` at times ``t``."""
    n, nan = len(t), float("nan")
    rows = []
    for a, b in contacts.stances:
        flat = contacts.flat(a, b)
        if flat is None:
            speed = np.linalg.norm(np.gradient(soles_W[a : b + 1, :2], axis=0), axis=1)
            k = a + int(np.argmin(speed)) if b > a else a
            flat = (k, k)
        f0, f1 = flat
        heel_level = float(np.median(heel_W[f0 : f1 + 1, 2]))
        toe_level = float(np.median(toe_W[f0 : f1 + 1, 2]))
        span = slice(a, b + 1)
        heel_down = _settled(heel_W[span], t[span], heel_level)
        toe_down = _settled(toe_W[span], t[span], toe_level)
        hs = a + int(np.flatnonzero(heel_down)[0]) if heel_down.any() else a
        to = a + int(np.flatnonzero(toe_down)[-1]) if toe_down.any() else b
        both = np.flatnonzero(heel_down & toe_down)
        ff, ho = (a + int(both[0]), a + int(both[-1])) if len(both) else (f0, f1)
        yaw = np.arctan2(toe_dir_W[f0 : f1 + 1, 1], toe_dir_W[f0 : f1 + 1, 0])
        starts, ends = a == 0, b == n - 1
        rows.append(
            (
                nan if starts else float(t[hs]),
                nan if starts else float(t[ff]),
                nan if ends else float(t[ho]),
                nan if ends else float(t[to]),
                0.0 if starts else float(t[ff]),
                float(t[-1]) if ends else float(t[ho]),
                soles_W[f0 : f1 + 1].mean(axis=0),
                _circular_mean(yaw),
            )
        )
    cols = list(zip(*rows, strict=True)) if rows else [()] * 8
    xy = np.array([c[:2] for c in cols[6]]).reshape(-1, 2)
    sole = np.concatenate([xy, np.zeros((len(xy), 1))], axis=1)
    return FootEvents(
        side=side,
        hs_s=np.array(cols[0], float),
        ff_s=np.array(cols[1], float),
        ho_s=np.array(cols[2], float),
        to_s=np.array(cols[3], float),
        flat_start_s=np.array(cols[4], float),
        flat_end_s=np.array(cols[5], float),
        sole_centre_W=sole,
        yaw_rad=np.array(cols[7], float),
        stride_lengths_m=np.linalg.norm(np.diff(xy, axis=0), axis=1),
    )


def step_events(events: dict[Side, FootEvents]) -> StepEvents:
    """One row per landing (a stance with a heel strike), in time order: its placement
    relative to the other foot's latest stance, along and across their mean toe direction."""
    landings = sorted(
        (float(ev.hs_s[i]), s, i)
        for s, ev in events.items()
        for i in range(len(ev.hs_s))
        if np.isfinite(ev.hs_s[i])
    )
    sides, hs, lengths, widths = [], [], [], []
    for t_hs, side, i in landings:
        other = events[SIDES[1 - SIDES.index(side)]]
        before = np.flatnonzero(other.flat_start_s <= t_hs)
        if len(before) == 0:
            continue
        j = int(before[-1])
        d = events[side].sole_centre_W[i, :2] - other.sole_centre_W[j, :2]
        mean_yaw = _circular_mean(np.array([events[side].yaw_rad[i], other.yaw_rad[j]]))
        heading = np.array([np.cos(mean_yaw), np.sin(mean_yaw)])
        sides.append(side)
        hs.append(t_hs)
        lengths.append(float(d @ heading))
        widths.append(float(abs(d[0] * heading[1] - d[1] * heading[0])))
    return StepEvents(tuple(sides), np.array(hs), np.array(lengths), np.array(widths))
