"""Gait parameters from stance-foot landmarks (thesis sec. 5.2.1; docs/ecosystem.md names).

A *stance* is one stance-foot landmark: the side of the foot, the first and last time it was
seen resting on the floor, and its position on the floor (x, y) in the world frame. Gait events
are taken at the stance's first observation, which is the start of foot-flat (the filter sees a
foot as a landmark once it rests on the floor), not the heel strike: times differ from heel-strike
based tools by the heel-strike → foot-flat delay (~0.1 s), differences of times do not.

- **stride** (thesis: "stride length is the distance between consecutive stance positions of the
  same foot"): consecutive stances ``k``, ``k+1`` of one side; ``stride_length_m`` = floor
  distance between them, ``stride_time_s`` = difference of their first times,
  ``walking_speed_mps`` = length / time, ``cadence_spm`` = 120 / stride time (steps per minute:
  two steps per stride).
- **step** ending a stride: from the latest stance of the other foot that began before the
  stride's last stance to that stance; ``step_length_m`` is the displacement along the stride's
  direction, ``step_width_m`` across it, ``step_time_s`` the difference of first times.
- one foot's stance reported as two (consecutive stances of a side less than
  ``min_swing_time_s`` apart in time and less than ``same_place_m`` apart on the floor: the
  foot cannot have been lifted and set down again) is **one stance**: from the first one's
  first time to the last one's last time, at the position of the one seen longer. This happens
  when the pose estimate jumps during a stance (the end tag sheet comes into view and corrects
  the drift: the foot's world point moves by cm and the tracker starts a new stance, seen in
  simulation at the last step) or the detector's point jumps (a shoe cut by depth holes).
- a stride is **steady** when its time is at most ``max_stride_time_s`` and neither of its
  stances was seen for longer than ``max_stance_time_s``; the others join a standing stance to
  the first or last step (gait initiation, termination) or bridge a pause, and are listed but
  left out of the means in :func:`summarise`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "Stance",
    "Stride",
    "merge_split_stances",
    "strides_from_stances",
    "summarise",
    "STRIDE_COLUMNS",
]

SIDES = ("left", "right")
STRIDE_COLUMNS = (
    "side",
    "stride",
    "start_s",
    "end_s",
    "stride_length_m",
    "stride_time_s",
    "step_length_m",
    "step_width_m",
    "step_time_s",
    "cadence_spm",
    "walking_speed_mps",
    "steady",
    "from_x_m",
    "from_y_m",
    "to_x_m",
    "to_y_m",
    "inferred",
)


@dataclass(frozen=True)
class Stance:
    """One stance-foot landmark: ``side``, first/last time seen [s], floor position ``xy`` [m];
    ``inferred``: laid from the step rhythm, never seen (:mod:`gaitnet.pipeline.hidden_stances`)."""

    side: str
    t_first_s: float
    t_last_s: float
    xy: np.ndarray
    inferred: bool = False


@dataclass(frozen=True)
class Stride:
    """One stride (module docstring); step values are NaN when no step of the other foot
    precedes the stride's last stance (they are then left empty in the CSV)."""

    side: str
    index: int
    start: Stance
    end: Stance
    step_length_m: float
    step_width_m: float
    step_time_s: float
    steady: bool

    @property
    def length_m(self) -> float:
        return float(np.linalg.norm(self.end.xy - self.start.xy))

    @property
    def time_s(self) -> float:
        return self.end.t_first_s - self.start.t_first_s

    @property
    def speed_mps(self) -> float:
        return self.length_m / self.time_s

    @property
    def cadence_spm(self) -> float:
        return 120.0 / self.time_s

    def row(self) -> dict[str, object]:
        """The stride as a CSV row (:data:`STRIDE_COLUMNS`), empty strings for missing steps."""

        def num(value: float) -> str:
            return "" if not np.isfinite(value) else f"{value:.6f}"

        return {
            "side": self.side,
            "stride": self.index,
            "start_s": num(self.start.t_first_s),
            "end_s": num(self.end.t_first_s),
            "stride_length_m": num(self.length_m),
            "stride_time_s": num(self.time_s),
            "step_length_m": num(self.step_length_m),
            "step_width_m": num(self.step_width_m),
            "step_time_s": num(self.step_time_s),
            "cadence_spm": num(self.cadence_spm),
            "walking_speed_mps": num(self.speed_mps),
            "steady": str(self.steady).lower(),
            "from_x_m": num(self.start.xy[0]),
            "from_y_m": num(self.start.xy[1]),
            "to_x_m": num(self.end.xy[0]),
            "to_y_m": num(self.end.xy[1]),
            "inferred": str(self.start.inferred or self.end.inferred).lower(),
        }


def _step(stances: list[Stance], end: Stance, direction: np.ndarray) -> tuple[float, float, float]:
    """(length, width, time) of the step landing on ``end``; NaNs when there is none."""
    other = [s for s in stances if s.side != end.side and s.t_first_s < end.t_first_s]
    if not other:
        return float("nan"), float("nan"), float("nan")
    prev = max(other, key=lambda s: s.t_first_s)
    d = end.xy - prev.xy
    length = float(d @ direction)
    width = float(abs(direction[0] * d[1] - direction[1] * d[0]))
    return length, width, end.t_first_s - prev.t_first_s


def merge_split_stances(
    stances: list[Stance], min_swing_time_s: float = 0.2, same_place_m: float = 0.08
) -> list[Stance]:
    """The stances with each foot's stance that was reported as two made one (module
    docstring), ordered by first time.

    ``min_swing_time_s`` [s]: a foot needs longer than this between leaving the floor and
    resting on it again (swing lasts ~0.35–0.45 s at 0.6–1.7 m/s, and the filter sees a foot
    from foot-flat to heel-off, ~0.5 s more); ``same_place_m`` [m]: closer than two feet can
    rest side by side (their centres are at least a shoe width, ~0.1 m, apart)."""
    merged: list[Stance] = []
    for side in SIDES:
        own = sorted((s for s in stances if s.side == side), key=lambda s: s.t_first_s)
        for s in own:
            prev = merged[-1] if merged and merged[-1].side == side else None
            if (
                prev is not None
                and s.t_first_s - prev.t_last_s < min_swing_time_s
                and float(np.linalg.norm(s.xy - prev.xy)) < same_place_m
            ):
                longer = max(prev, s, key=lambda x: x.t_last_s - x.t_first_s)
                merged[-1] = Stance(
                    side,
                    min(prev.t_first_s, s.t_first_s),
                    max(prev.t_last_s, s.t_last_s),
                    longer.xy,
                    longer.inferred,
                )
            else:
                merged.append(s)
    return sorted(merged, key=lambda s: s.t_first_s)


def strides_from_stances(
    stances: list[Stance],
    max_stride_time_s: float = 2.5,
    max_stance_time_s: float = 1.2,
    min_swing_time_s: float = 0.2,
    same_place_m: float = 0.08,
) -> list[Stride]:
    """Strides (module docstring) of both sides, ordered by end time, from the stances after
    :func:`merge_split_stances` (``min_swing_time_s``, ``same_place_m``). Two stances of the
    same side at the same time are an error of the caller (ValueError)."""
    ordered = merge_split_stances(stances, min_swing_time_s, same_place_m)
    strides: list[Stride] = []
    for side in SIDES:
        own = [s for s in ordered if s.side == side]
        for k, (a, b) in enumerate(zip(own[:-1], own[1:], strict=True)):
            if b.t_first_s <= a.t_first_s:
                raise ValueError(f"two {side} stances start at the same time {a.t_first_s} s")
            d = b.xy - a.xy
            norm = float(np.linalg.norm(d))
            direction = d / norm if norm > 1e-9 else np.array([1.0, 0.0])
            length, width, step_time = _step(ordered, b, direction)
            steady = (
                b.t_first_s - a.t_first_s <= max_stride_time_s
                and a.t_last_s - a.t_first_s <= max_stance_time_s
                and b.t_last_s - b.t_first_s <= max_stance_time_s
            )
            strides.append(Stride(side, k, a, b, length, width, step_time, steady))
    return sorted(strides, key=lambda s: (s.end.t_first_s, s.side))


def _stats(values: list[float]) -> dict[str, float]:
    v = np.asarray([x for x in values if np.isfinite(x)], dtype=float)
    if v.size == 0:
        return {}
    return {"mean": float(v.mean()), "std": float(v.std(ddof=1)) if v.size > 1 else 0.0}


def summarise(strides: list[Stride]) -> dict[str, object]:
    """Means and standard deviations per side over the steady strides (stride length and time,
    step length, width and time, cadence, speed), and the Robinson symmetry index of the mean
    stride and step lengths, ``2 (R − L) / (R + L) × 100`` [%]."""
    out: dict[str, object] = {}
    for side in SIDES:
        own = [s for s in strides if s.side == side and s.steady]
        out[side] = {
            "n_strides": len(own),
            "stride_length_m": _stats([s.length_m for s in own]),
            "stride_time_s": _stats([s.time_s for s in own]),
            "step_length_m": _stats([s.step_length_m for s in own]),
            "step_width_m": _stats([s.step_width_m for s in own]),
            "step_time_s": _stats([s.step_time_s for s in own]),
            "cadence_spm": _stats([s.cadence_spm for s in own]),
            "walking_speed_mps": _stats([s.speed_mps for s in own]),
        }
    symmetry: dict[str, float] = {}
    for key in ("stride_length_m", "step_length_m"):
        left = out["left"][key].get("mean")  # type: ignore[index]
        right = out["right"][key].get("mean")  # type: ignore[index]
        if left is not None and right is not None and left + right > 0:
            symmetry[key] = 200.0 * (right - left) / (right + left)
    out["robinson_symmetry_index_pct"] = symmetry
    return out
