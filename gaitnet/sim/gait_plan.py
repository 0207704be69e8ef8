"""Footstep plan of a walk: the path, where each foot lands and when (gait events).

A walk starts and ends standing with the feet side by side, ``stand_width`` apart. Steps alternate;
step ``k`` (``k = 1..N``) moves foot ``side[k]`` from its previous foot-flat place to a new one
whose sole centre lies ``±width/2`` beside the path at arc length ``s_k``. Step lengths ramp up over
the first two steps (0.6, 0.9 of the steady length) and down over the last (0.8) and a closing step
brings the trailing foot beside the leading one.

Timing (fractions of the gait cycle = 2 steps, steady state): heel strike (HS) at 0, foot flat
(FF) at ``foot_flat_fraction``, heel off (HO) at ``heel_off_fraction``, toe off (TO) at
``stance_fraction``, next HS at 1. With step ``k`` landing at ``h_k``:
``HO_k = h_{k−1} − (1 − 2·heel_off)·T_k``, ``TO_k = h_{k−1} + (2·stance − 1)·T_k``,
``FF_k = h_k + 2·foot_flat·T_k`` where ``T_k = h_k − h_{k−1}``; ``h_0`` is a virtual heel
strike of the first stance foot, which really stands still until its own heel off.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.interpolate import CubicSpline

__all__ = ["FootStance", "StepPlan", "WalkPath", "WalkVariation", "plan_steps", "smoothstep7"]

LEFT, RIGHT = 0, 1
SIDE_SIGN = (1.0, -1.0)  # left foot is on the +normal (left) side of the path

_RAMP_UP = (0.6, 0.9)
_RAMP_DOWN = (0.8,)


def smoothstep7(u: np.ndarray) -> np.ndarray:
    """``S(u) = 35u⁴ − 84u⁵ + 70u⁶ − 20u⁷`` on [0, 1] (clipped): C³ ramp from 0 to 1."""
    u = np.clip(u, 0.0, 1.0)
    return u**4 * (35.0 + u * (-84.0 + u * (70.0 - 20.0 * u)))


@dataclass(frozen=True)
class WalkVariation:
    """Within-walk changes beyond the simulator's config (the predictor's training clips).

    The defaults change nothing (and draw nothing from the random generator), so the
    simulator's sessions are unaffected. ``speed_change``: relative speed change over the walk,
    step ``k`` of ``n`` walks at ``1 + speed_change · S(k / (n − 1))`` times the configured
    speed (``S`` :func:`smoothstep7`; its length scales with the square root of that factor,
    its duration inversely, and all lengths are rescaled so the walk keeps its length).
    ``step_length_asymmetry`` / ``step_time_asymmetry``: steps of the left foot are
    ``1 + a`` times, those of the right ``1 − a`` times as long (in metres / seconds): a
    limp-like asymmetric gait. ``turn_arc_m``: the turn of the path happens within this arc
    length centred at ``turn_at`` of the walk (None: spread over the whole walk).
    """

    speed_change: float = 0.0
    step_length_asymmetry: float = 0.0
    step_time_asymmetry: float = 0.0
    turn_arc_m: float | None = None
    turn_at: float = 0.5

    def __post_init__(self) -> None:
        if not -0.6 <= self.speed_change <= 1.0:
            raise ValueError(f"speed_change must be in [-0.6, 1], got {self.speed_change}")
        for name in ("step_length_asymmetry", "step_time_asymmetry"):
            if not -0.3 <= getattr(self, name) <= 0.3:
                raise ValueError(f"{name} must be in [-0.3, 0.3], got {getattr(self, name)}")
        if self.turn_arc_m is not None and not 0.5 <= self.turn_arc_m <= 100.0:
            raise ValueError(f"turn_arc_m must be in [0.5, 100] m, got {self.turn_arc_m}")
        if not 0.0 <= self.turn_at <= 1.0:
            raise ValueError(f"turn_at must be in [0, 1], got {self.turn_at}")


class WalkPath:
    """Planar walking path by arc length ``s``: start at the origin heading +x.

    The heading turns by ``turn_rad`` in total, spread smoothly (C³) over ``s ∈ [0, length]``
    (or, with ``turn_arc_m``, over that arc length centred at ``turn_at · length``, kept
    within the walk); outside that range the path is straight.
    """

    def __init__(
        self,
        length_m: float,
        turn_rad: float,
        *,
        turn_arc_m: float | None = None,
        turn_at: float = 0.5,
    ) -> None:
        self.length_m = float(length_m)
        self.turn_rad = float(turn_rad)
        self._turn_from, self._turn_arc = 0.0, self.length_m
        if turn_arc_m is not None:
            self._turn_arc = min(float(turn_arc_m), self.length_m)
            start = float(turn_at) * self.length_m - 0.5 * self._turn_arc
            self._turn_from = min(max(start, 0.0), self.length_m - self._turn_arc)
        s = np.arange(-3.0, self.length_m + 3.0 + 5e-4, 1e-3)
        psi = self.heading(s)
        dx, dy = np.cos(psi), np.sin(psi)
        x = np.concatenate([[0.0], np.cumsum(0.5 * (dx[1:] + dx[:-1]) * np.diff(s))])
        y = np.concatenate([[0.0], np.cumsum(0.5 * (dy[1:] + dy[:-1]) * np.diff(s))])
        i0 = int(np.argmin(np.abs(s)))
        xy = np.stack([x - x[i0], y - y[i0]], axis=-1)
        self._spline = CubicSpline(s[::10], xy[::10], axis=0)

    def heading(self, s: np.ndarray) -> np.ndarray:
        """Heading angle [rad] at arc length ``s``."""
        u = (np.asarray(s, dtype=np.float64) - self._turn_from) / self._turn_arc
        return self.turn_rad * smoothstep7(u)

    def point(self, s: np.ndarray) -> np.ndarray:
        """Path point ``(..., 2)`` at arc length ``s``."""
        return self._spline(np.asarray(s, dtype=np.float64))

    def normal(self, s: np.ndarray) -> np.ndarray:
        """Unit left normal ``(..., 2)``."""
        psi = self.heading(s)
        return np.stack([-np.sin(psi), np.cos(psi)], axis=-1)


@dataclass(frozen=True)
class FootStance:
    """One foot-flat period of one foot, with the events that bound it.

    ``t_hs``/``t_ff`` are NaN for the initial stance (the foot was standing), ``t_ho``/
    ``t_to`` NaN for the final one. ``hs_pitch_rad`` is the toe-up angle at this HS and
    ``to_pitch_rad`` the heel-up angle at this stance's TO.
    """

    side: int
    xy: tuple[float, float]  # sole centre on the floor
    yaw: float
    t_hs: float
    t_ff: float
    t_ho: float
    t_to: float
    hs_pitch_rad: float
    to_pitch_rad: float


@dataclass(frozen=True)
class StepPlan:
    """All stances of both feet (time-ordered per foot) and the step table."""

    stances: tuple[tuple[FootStance, ...], tuple[FootStance, ...]]
    step_side: np.ndarray  # (N,) foot of each step (0 left, 1 right)
    step_hs: np.ndarray  # (N + 1,) heel-strike times h_0 (virtual) .. h_N
    step_arc: np.ndarray  # (N + 1,) arc length of each placement (s_0 = 0)
    steady_step_m: float
    steady_step_s: float
    t_first_move: float  # first heel off
    t_last_ff: float  # foot flat of the closing step


@dataclass(frozen=True)
class _Timing:
    stance: float
    foot_flat: float
    heel_off: float


def _step_factors(walk_length_m: float, step0_m: float) -> tuple[np.ndarray, float]:
    """Nominal step-length factors (ramp up, steady, ramp down, 0 closing) and the steady length."""
    fixed = sum(_RAMP_UP) + sum(_RAMP_DOWN)
    n_steady = max(0, round(walk_length_m / step0_m - fixed))
    factors = np.array([*_RAMP_UP, *([1.0] * n_steady), *_RAMP_DOWN, 0.0])
    return factors, walk_length_m / (fixed + n_steady)


def plan_steps(
    path: WalkPath,
    *,
    step_m: float,
    speed_mps: float,
    step_width_m: float,
    stand_width_m: float,
    step_length_cv: float,
    step_time_cv: float,
    step_width_std_m: float,
    toe_out_rad: float,
    hs_pitch_rad: float,
    to_pitch_rad: float,
    timing: tuple[float, float, float],
    t_first_heel_off: float,
    first_side: int,
    rng: np.random.Generator,
    variation: WalkVariation | None = None,
) -> StepPlan:
    """Footsteps and gait events for a walk of ``path.length_m`` (see the module docstring).

    ``step_m`` is the preferred steady step length; it is adjusted so that the nominal steps
    add up to the walk length. The feet stand ``stand_width_m`` apart (sole centres) at the
    start and after the closing step, ``step_width_m`` (± noise) while walking. ``timing`` =
    (stance, foot-flat, heel-off) cycle fractions. ``variation`` changes the speed within the
    walk and makes the steps asymmetric (:class:`WalkVariation`; no extra random draws).
    """
    tm = _Timing(*timing)
    factors, step = _step_factors(path.length_m, step_m)
    n = len(factors)
    noise = 1.0 + step_length_cv * np.clip(rng.normal(size=n), -3, 3)
    lengths = step * factors * noise
    period = step / speed_mps
    durations = period * (1.0 + step_time_cv * np.clip(rng.normal(size=n), -3, 3))
    widths = np.maximum(step_width_m + step_width_std_m * np.clip(rng.normal(size=n), -3, 3), 0.0)
    sides = (first_side + np.arange(n)) % 2
    if variation is not None:
        lengths, durations = _vary(lengths, durations, sides, variation)
    widths[-1] = max(2.0 * stand_width_m - widths[-2], 0.0)  # closing: feet stand_width apart
    arc = np.concatenate([[0.0], np.cumsum(lengths)])
    lead = 1.0 - 2.0 * tm.heel_off
    h = t_first_heel_off + lead * durations[0] + np.concatenate([[0.0], np.cumsum(durations)])
    stances = _build_stances(path, arc, sides, h, durations, widths, stand_width_m, toe_out_rad, tm)
    stances = _with_angles(stances, hs_pitch_rad, to_pitch_rad, step)
    return StepPlan(
        stances=stances,
        step_side=sides,
        step_hs=h,
        step_arc=arc,
        steady_step_m=step,
        steady_step_s=period,
        t_first_move=t_first_heel_off,
        t_last_ff=float(h[-1] + 2.0 * tm.foot_flat * durations[-1]),
    )


def _vary(
    lengths: np.ndarray, durations: np.ndarray, sides: np.ndarray, v: WalkVariation
) -> tuple[np.ndarray, np.ndarray]:
    """Per-step speed factor and left/right asymmetry (:class:`WalkVariation`)."""
    n = len(lengths)
    m = 1.0 + v.speed_change * smoothstep7(np.arange(n) / max(n - 1, 1))
    sign = np.where(sides == LEFT, 1.0, -1.0)
    new_lengths = lengths * np.sqrt(m) * (1.0 + sign * v.step_length_asymmetry)
    new_lengths *= lengths.sum() / new_lengths.sum()  # the walk keeps its length
    new_durations = durations / np.sqrt(m) * (1.0 + sign * v.step_time_asymmetry)
    return new_lengths, new_durations


def _placement(path: WalkPath, s: float, side: int, width: float, toe_out: float) -> tuple:
    sign = SIDE_SIGN[side]
    xy = path.point(s) + path.normal(s) * (0.5 * sign * width)
    return (float(xy[0]), float(xy[1])), float(path.heading(s) + sign * toe_out)


def _build_stances(
    path: WalkPath,
    arc: np.ndarray,
    sides: np.ndarray,
    h: np.ndarray,
    durations: np.ndarray,
    widths: np.ndarray,
    width0: float,
    toe_out: float,
    tm: _Timing,
) -> tuple[tuple[FootStance, ...], tuple[FootStance, ...]]:
    """Stances per foot: the initial one, one per step of that foot (with events)."""
    nan = float("nan")
    per_foot: list[list[dict]] = [[], []]
    for side in (LEFT, RIGHT):
        xy, yaw = _placement(path, 0.0, side, width0, toe_out)
        per_foot[side].append(dict(side=side, xy=xy, yaw=yaw, t_hs=nan, t_ff=nan))
    for k in range(1, len(arc)):
        side, T = int(sides[k - 1]), float(durations[k - 1])
        s = float(arc[k - 1]) if k == len(arc) - 1 else float(arc[k])  # closing step: beside
        prev = per_foot[side][-1]
        prev["t_ho"] = float(h[k - 1] - (1.0 - 2.0 * tm.heel_off) * T)
        prev["t_to"] = float(h[k - 1] + (2.0 * tm.stance - 1.0) * T)
        xy, yaw = _placement(path, s, side, float(widths[k - 1]), toe_out)
        t_ff = float(h[k] + 2.0 * tm.foot_flat * T)
        per_foot[side].append(dict(side=side, xy=xy, yaw=yaw, t_hs=float(h[k]), t_ff=t_ff))
    for foot in per_foot:
        foot[-1].update(t_ho=nan, t_to=nan)
    out = tuple(
        tuple(FootStance(**d, hs_pitch_rad=0.0, to_pitch_rad=0.0) for d in foot)
        for foot in per_foot
    )
    return out[0], out[1]


def _stride_scale(a: FootStance, b: FootStance, step: float) -> float:
    stride = float(np.hypot(b.xy[0] - a.xy[0], b.xy[1] - a.xy[1]))
    return float(np.clip(stride / (2.0 * step), 0.35, 1.0))


def _with_angles(
    stances: tuple[tuple[FootStance, ...], tuple[FootStance, ...]],
    hs_pitch: float,
    to_pitch: float,
    step: float,
) -> tuple[tuple[FootStance, ...], tuple[FootStance, ...]]:
    """Foot pitch at HS / TO scaled by the stride (short strides: flatter foot rolls)."""
    out = []
    for foot in stances:
        new = []
        for i, st in enumerate(foot):
            hs = hs_pitch * _stride_scale(foot[i - 1], st, step) if i > 0 else 0.0
            last = i + 1 == len(foot)
            to = 0.0 if last else to_pitch * _stride_scale(st, foot[i + 1], step)
            new.append(replace(st, hs_pitch_rad=hs, to_pitch_rad=to))
        out.append(tuple(new))
    return out[0], out[1]
