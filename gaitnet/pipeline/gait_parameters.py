"""Gait parameters per stride and per side: the time-distance table (docs/report.md).

Two sources, each used for what it measures best:

- **Distances and the filter's times** come from :mod:`gaitnet.vio.gait` (thesis sec. 5.2.1):
  stride length and time, step length, width and time, cadence (steps per minute, 120 / stride
  time) and walking speed of each :class:`~gaitnet.vio.gait.Stride` between two stance-foot
  landmarks, and its ``steady`` flag.
- **Phases** come from the gait events of :mod:`gaitnet.pipeline.gait_events`: each of the
  stride's two stances is matched to the foot contact of its side whose still interval overlaps
  it most (else the nearest within ``tolerance_s``). With IC = initial contact and TO = toe off
  of the stride's first stance and IC' the initial contact of its second, the gait cycle is
  IC → IC' and

  - ``stance_time_s`` = TO − IC, ``swing_time_s`` = IC' − TO, ``stance_pct`` and ``swing_pct``
    their shares of the cycle (they add to 100 %);
  - ``initial_double_support_pct``: from IC to the toe off of the other foot, which was on the
    floor at IC; ``terminal_double_support_pct``: from the other foot's next initial contact
    (between IC and TO) to TO; ``double_support_pct`` their sum (the total double support of
    the cycle, about 20 % in normal walking, two periods of about 10 %: Perry & Burnfield 2010).

  A value whose events are missing (the stance began or ended with the recording, or an event
  was not found) is None (an empty cell).

The per-side summary (:func:`summarise`) is the mean and sample standard deviation over the
steady strides with a value, and for each parameter the Robinson symmetry index
``SI = 2 (R − L) / (R + L) × 100`` [%] of the two sides' means (R. O. Robinson, W. Herzog,
B. M. Nigg, *J. Manipulative Physiol. Ther.* 10(4), 1987; signed: positive when the right
side's value is larger; |SI| is the asymmetry regardless of side; 0 = symmetric), the index
:func:`gaitnet.vio.gait.summarise` gives for the stride and step lengths.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from gaitnet.errors import InputError
from gaitnet.pipeline.gait_events import SIDES, FootContact
from gaitnet.vio.gait import Stance, Stride

__all__ = [
    "PARAMETERS",
    "STRIDE_TABLE_COLUMNS",
    "StrideParameters",
    "robinson_index_pct",
    "stride_parameters",
    "stride_table_csv",
    "summarise",
    "table_cycles",
]

#: Every parameter: key (unit as suffix, docs/ecosystem.md), display label, display unit.
PARAMETERS: tuple[tuple[str, str, str], ...] = (
    ("stride_length_m", "stride length", "m"),
    ("stride_time_s", "stride time", "s"),
    ("step_length_m", "step length", "m"),
    ("step_width_m", "step width", "m"),
    ("step_time_s", "step time", "s"),
    ("cadence_spm", "cadence", "steps/min"),
    ("walking_speed_mps", "walking speed", "m/s"),
    ("stance_time_s", "stance time", "s"),
    ("swing_time_s", "swing time", "s"),
    ("stance_pct", "stance", "% of cycle"),
    ("swing_pct", "swing", "% of cycle"),
    ("initial_double_support_pct", "initial double support", "% of cycle"),
    ("terminal_double_support_pct", "terminal double support", "% of cycle"),
    ("double_support_pct", "double support (total)", "% of cycle"),
)
KEYS = tuple(key for key, _, _ in PARAMETERS)
EVENT_COLUMNS = ("initial_contact_s", "toe_off_s", "next_initial_contact_s")
STRIDE_TABLE_COLUMNS = ("side", "stride", "steady", "inferred", *EVENT_COLUMNS, *KEYS)
DEFAULT_TOLERANCE_S = 0.25


@dataclass(frozen=True)
class StrideParameters:
    """One stride's parameters: ``values`` maps every key of :data:`PARAMETERS` and
    :data:`EVENT_COLUMNS` to a finite float or None; ``inferred``: a stance of the stride was
    laid from the step rhythm, not seen (:mod:`gaitnet.pipeline.hidden_stances`)."""

    side: str
    index: int
    steady: bool
    values: dict[str, float | None]
    inferred: bool = False

    def row(self) -> dict[str, str]:
        """The stride as a CSV row (:data:`STRIDE_TABLE_COLUMNS`), None as an empty cell."""
        out = {
            "side": self.side,
            "stride": str(self.index),
            "steady": str(self.steady).lower(),
            "inferred": str(self.inferred).lower(),
        }
        for key in (*EVENT_COLUMNS, *KEYS):
            value = self.values.get(key)
            out[key] = "" if value is None else f"{value:.6f}"
        return out


def _finite(value: float | None) -> float | None:
    return float(value) if value is not None and math.isfinite(value) else None


def _contact_for(stance: Stance, own: list[FootContact], tolerance_s: float) -> FootContact | None:
    """The contact of the stance's side overlapping it most, else the nearest in time."""

    def overlap(c: FootContact) -> float:
        return min(c.still_end_s, stance.t_last_s) - max(c.still_start_s, stance.t_first_s)

    best = max(own, key=overlap, default=None)
    if best is not None and overlap(best) >= 0:
        return best
    best = min(own, key=lambda c: abs(c.still_start_s - stance.t_first_s), default=None)
    if best is not None and abs(best.still_start_s - stance.t_first_s) <= tolerance_s:
        return best
    return None


def _phases(
    a: FootContact | None, b: FootContact | None, other: list[FootContact]
) -> dict[str, float | None]:
    """Stance, swing and double support of the cycle from ``a``'s IC to ``b``'s IC."""
    out: dict[str, float | None] = dict.fromkeys(
        (*EVENT_COLUMNS, *(k for k in KEYS if k.startswith(("stance", "swing")) or "double" in k))
    )
    if a is None or b is None:
        return out
    ic, to, ic_next = a.initial_contact_s, a.toe_off_s, b.initial_contact_s
    out.update(initial_contact_s=ic, toe_off_s=to, next_initial_contact_s=ic_next)
    if ic is None or to is None or ic_next is None or not ic < to < ic_next:
        return out
    cycle = ic_next - ic
    out.update(
        stance_time_s=to - ic,
        swing_time_s=ic_next - to,
        stance_pct=100.0 * (to - ic) / cycle,
        swing_pct=100.0 * (ic_next - to) / cycle,
    )
    off = [
        c.toe_off_s
        for c in other
        if c.toe_off_s is not None
        and ic < c.toe_off_s < to
        and (c.initial_contact_s is None or c.initial_contact_s <= ic)
    ]
    on = [c.initial_contact_s for c in other if c.initial_contact_s is not None]
    on = [x for x in on if ic < x < to]
    if off:
        out["initial_double_support_pct"] = 100.0 * (min(off) - ic) / cycle
    if on:
        out["terminal_double_support_pct"] = 100.0 * (to - min(on)) / cycle
    if off and on:
        out["double_support_pct"] = 100.0 * ((min(off) - ic) + (to - min(on))) / cycle
    return out


def stride_parameters(
    strides: Sequence[Stride],
    contacts: Sequence[FootContact],
    tolerance_s: float = DEFAULT_TOLERANCE_S,
) -> list[StrideParameters]:
    """The parameters (module docstring) of every stride, in the order given."""
    if not math.isfinite(tolerance_s) or tolerance_s < 0:
        raise InputError(f"stride parameters: tolerance_s {tolerance_s} is not a finite value >= 0")
    by_side = {side: [c for c in contacts if c.side == side] for side in SIDES}
    out = []
    for s in strides:
        if s.side not in SIDES:
            raise InputError(f"stride {s.index}: side {s.side!r} is not one of {SIDES}")
        own, other = by_side[s.side], by_side["right" if s.side == "left" else "left"]
        a = _contact_for(s.start, own, tolerance_s)
        b = _contact_for(s.end, own, tolerance_s)
        values: dict[str, float | None] = {
            "stride_length_m": s.length_m,
            "stride_time_s": s.time_s,
            "step_length_m": s.step_length_m,
            "step_width_m": s.step_width_m,
            "step_time_s": s.step_time_s,
            "cadence_spm": s.cadence_spm if s.time_s > 0 else None,
            "walking_speed_mps": s.speed_mps if s.time_s > 0 else None,
        }
        values.update(_phases(a, b, other))
        values = {k: _finite(v) for k, v in values.items()}
        inferred = s.start.inferred or s.end.inferred
        out.append(StrideParameters(s.side, s.index, s.steady, values, inferred))
    return out


def robinson_index_pct(left: float, right: float) -> float | None:
    """Robinson symmetry index 2 (R − L) / (R + L) × 100 [%]; None when R + L is 0."""
    total = left + right
    return None if total == 0 else 200.0 * (right - left) / total


def summarise(rows: Sequence[StrideParameters]) -> dict[str, object]:
    """Per side: ``n_strides`` (steady), ``n_inferred`` (of those, the strides with a stance
    laid from the step rhythm) and for every parameter ``{mean, sd, n}`` over the
    steady strides with a value (sample SD, 0 for one value; the parameter is left out when no
    stride has it); ``symmetry_index_pct``: the Robinson index per parameter (module
    docstring) where both sides have a mean."""
    out: dict[str, object] = {}
    for side in SIDES:
        own = [r for r in rows if r.side == side and r.steady]
        stats: dict[str, object] = {
            "n_strides": len(own),
            "n_inferred": sum(r.inferred for r in own),
        }
        for key in KEYS:
            v = np.array([r.values[key] for r in own if r.values.get(key) is not None])
            if v.size:
                sd = float(v.std(ddof=1)) if v.size > 1 else 0.0
                stats[key] = {"mean": float(v.mean()), "sd": sd, "n": int(v.size)}
        out[side] = stats
    symmetry: dict[str, float] = {}
    for key in KEYS:
        left, right = out["left"].get(key), out["right"].get(key)  # type: ignore[union-attr]
        if left is not None and right is not None:
            si = robinson_index_pct(left["mean"], right["mean"])
            if si is not None:
                symmetry[key] = si
    out["symmetry_index_pct"] = symmetry
    out["symmetry_index"] = "Robinson 1987: 2 (R - L) / (R + L) x 100 of the side means"
    return out


def table_cycles(rows: Sequence[StrideParameters]) -> dict[str, list[tuple[float, float, float]]]:
    """Per side, the gait cycles ``(initial contact, toe off, next initial contact)`` [s] of
    the steady strides whose stance and swing the table gives (:func:`summarise`'s
    ``stance_pct`` n): the cycles the joint-angle figure averages."""
    out: dict[str, list[tuple[float, float, float]]] = {side: [] for side in SIDES}
    for r in rows:
        if r.steady and r.values.get("stance_pct") is not None:
            v = r.values
            out[r.side].append(
                (v["initial_contact_s"], v["toe_off_s"], v["next_initial_contact_s"])  # type: ignore[arg-type]
            )
    return out


def stride_table_csv(rows: Sequence[StrideParameters]) -> str:
    """The per-stride table as CSV text (:data:`STRIDE_TABLE_COLUMNS`)."""
    text = io.StringIO()
    writer = csv.DictWriter(text, fieldnames=STRIDE_TABLE_COLUMNS, lineterminator="\n")
    writer.writeheader()
    writer.writerows(r.row() for r in rows)
    return text.getvalue()
