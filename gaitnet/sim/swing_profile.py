"""A point of the shoe's path from heel off to the next foot flat, in generated walks.

The pipeline fills a foot's unseen swing from a template of this path
(:mod:`gaitnet.pipeline.swing_fill`); this module measures it on the simulator's walks so the
template's numbers can be re-derived (``data/derive_swing_template.py``, and a test that
checks the committed table against a fresh derivation). The point is a :class:`ShoePoint`
(the pipeline's: the segmenter's keypoint as the pose correction models it, a fixed point of
the foot ahead of and below the ankle) or, without one, the instep marker
(:meth:`gaitnet.sim.gait.Walk.marker_points`).

For one foot between heel off ``HO`` of stance ``i`` and foot flat ``FF'`` of stance
``i + 1``, with ``m(t)`` the point, ``τ = (t − HO) / (FF' − HO)``, ``d = m(FF') − m(HO)`` and
``u`` the horizontal unit vector of ``d``:

- progress ``ρ(τ) = (m(t) − m(HO))·u / |d_xy|`` (0 → 1 along the step);
- lift ``λ(τ) = (m_z(t) − m_z(HO) − ρ(τ) d_z) / H`` (height above the straight line between
  the two rests, as a fraction of the body height ``H``);
- sideways ``μ(τ) = ±(m(t) − m(HO))·n / H`` with ``n`` the horizontal unit vector left of
  ``u``, + for the left foot and − for the right: how far the point strays from the straight
  line away from the body's midline (outwards), as a fraction of ``H``.

The fill also needs the template's time span ``FF' − t₀`` for a gait cycle ``T`` (``FF' − FF``
of one foot): :func:`swing_spans` fits, per swing, the span ``s`` for which the template laid
over ``[FF' − s, FF']`` best matches the point's progress from ``FF`` to ``FF'`` (least
squares), and :func:`derive_swing_span` fits ``s = a + b T`` over walks at all the
generator's speeds (slow walking rolls longer over the forefoot before the swing, so the span
is a smaller share of a long cycle than of a short one). It also fits ``s = c + d C`` with
``C = FF' − FF_c``, ``FF_c`` the other foot's foot flat between ``FF`` and ``FF'``: the foot
leaves the floor at the end of the double support that the other foot's landing begins, so
that interval times each swing more closely than its cycle does (residual 22 against 28 ms
over the generator's swings).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize_scalar

from gaitnet.sim.gait import GaitConfig, Walk, generate_walk
from gaitnet.sim.gait_legs import R_PfromSMPL
from gaitnet.sim.scene import SIDES
from gaitnet.sim.subject import sample_subject

__all__ = [
    "ShoePoint",
    "derive_swing_span",
    "derive_swing_template",
    "swing_profiles",
    "swing_spans",
]


@dataclass(frozen=True)
class ShoePoint:
    """A fixed point of the foot in its sagittal plane: ``forward_m`` ahead of the ankle joint
    along the sole and ``up_m`` above it (negative: below), for a body of ``body_height_m``,
    scaled by each subject's height (the pose correction's foot offsets are given that way,
    :mod:`gaitnet.pipeline.config`)."""

    forward_m: float
    up_m: float
    body_height_m: float

    def __post_init__(self) -> None:
        if not np.isfinite([self.forward_m, self.up_m, self.body_height_m]).all() or not (
            self.body_height_m > 0
        ):
            raise ValueError(f"ShoePoint: finite offsets and a positive height needed, got {self}")

    @classmethod
    def from_smpl_offset(
        cls, offset_m: tuple[float, float, float], body_height_m: float
    ) -> ShoePoint:
        """The point at an ankle-frame offset in SMPL axes (x outwards for the left foot, y up,
        z forward; the pose correction's foot offsets, :mod:`gaitnet.pipeline.config`). The
        point must lie in the foot's sagittal plane (x = 0): the left and right feet then
        share it."""
        outwards, up, forward = offset_m
        if outwards != 0:
            raise ValueError(f"ShoePoint: the offset must have x = 0 (sagittal), got {offset_m}")
        forward_S, _, up_S = R_PfromSMPL @ np.array([outwards, up, forward], dtype=np.float64)
        return cls(forward_m=float(forward_S), up_m=float(up_S), body_height_m=body_height_m)

    def points(self, walk: Walk, t: np.ndarray) -> np.ndarray:
        """The point of both feet of ``walk`` at times ``t``, (len(t), 2, 3)."""
        scale = walk.subject.height_m / self.body_height_m
        offset = scale * np.array([self.forward_m, 0.0, self.up_m])  # shoe frame: x fwd, z up
        return walk.shoe_points(t, walk.subject.ankle_in_shoe() + offset)[:, :, 0]


def _points(walk: Walk, t: np.ndarray, point: ShoePoint | None) -> np.ndarray:
    """Both feet's ``point`` (the instep marker when None) at times ``t``, (len(t), 2, 3)."""
    return walk.marker_points(t) if point is None else point.points(walk, t)


def _swings(walk: Walk, point: ShoePoint | None) -> Iterator[tuple[int, float, float, float]]:
    """``(foot, FF, HO, FF')`` of every swing of ``walk`` between two foot flats of one foot
    whose ``point`` moves at least 0.2 m (a shorter move is a shuffle, not a swing)."""
    for s, side in enumerate(SIDES):
        ev = walk.events[side]
        for i in range(len(ev.ho_s) - 1):
            ff0, ho, ff1 = ev.ff_s[i], ev.ho_s[i], ev.ff_s[i + 1]
            if not np.isfinite([ff0, ho, ff1]).all() or not ff0 < ho < ff1:
                continue
            d = np.diff(_points(walk, np.array([ho, ff1]), point)[:, s], axis=0)[0]
            if np.hypot(d[0], d[1]) >= 0.2:
                yield s, float(ff0), float(ho), float(ff1)


def _progress(
    walk: Walk, foot: int, t: np.ndarray, point: ShoePoint | None
) -> tuple[np.ndarray, np.ndarray]:
    """Progress (len(t),) of ``foot``'s ``point`` at times ``t`` along its move from ``t[0]``
    to ``t[-1]`` (module docstring), and the point's positions (len(t), 3)."""
    m = _points(walk, t, point)[:, foot]
    d = m[-1] - m[0]
    step = float(np.hypot(d[0], d[1]))
    return (m - m[0]) @ (np.array([d[0], d[1], 0.0]) / step) / step, m


def swing_profiles(
    walk: Walk, tau: np.ndarray, point: ShoePoint | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(progress, lift, sideways, fraction)`` of every swing of ``walk`` (module docstring)
    at ``tau``, for ``point`` (None: the instep marker): progress, lift and sideways (m,
    len(tau)); fraction (m,): ``(FF' − HO) / (FF' − FF)``, the share of the gait cycle (foot
    flat to foot flat) that heel off precedes the next foot flat by."""
    tau = np.asarray(tau, dtype=np.float64)
    progress, lift, sideways, fraction = [], [], [], []
    height = walk.subject.height_m
    for s, ff0, ho, ff1 in _swings(walk, point):
        rho, m = _progress(walk, s, ho + tau * (ff1 - ho), point)
        z = m[:, 2]
        d = m[-1, :2] - m[0, :2]
        outwards = np.array([-d[1], d[0]]) / np.hypot(d[0], d[1]) * (1.0 if s == 0 else -1.0)
        progress.append(rho)
        lift.append((z - z[0] - rho * (z[-1] - z[0])) / height)
        sideways.append((m[:, :2] - m[0, :2]) @ outwards / height)
        fraction.append((ff1 - ho) / (ff1 - ff0))
    if not progress:
        empty = np.empty((0, len(tau)))
        return empty, empty.copy(), empty.copy(), np.empty(0)
    return np.array(progress), np.array(lift), np.array(sideways), np.array(fraction)


def derive_swing_template(
    tau: np.ndarray,
    speeds_mps: tuple[float, ...] = (0.8, 1.0, 1.2, 1.4, 1.6),
    subjects: int = 6,
    seed: int = 0,
    walk_length_m: float = 10.0,
    point: ShoePoint | None = None,
) -> dict[str, np.ndarray]:
    """Mean and spread of :func:`swing_profiles` of ``point`` (None: the instep marker) over
    ``subjects`` random subjects walking ``walk_length_m`` at each of ``speeds_mps`` (the
    simulator's default gait otherwise): ``progress``, ``lift``, ``sideways`` (len(tau)), their
    standard deviations ``progress_std``, ``lift_std``, ``sideways_std``, and ``fraction``
    (mean, std)."""
    rng = np.random.default_rng(seed)
    parts: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = []
    for speed in speeds_mps:
        cfg = GaitConfig(speed_mps=float(speed), walk_length_m=float(walk_length_m))
        for _ in range(subjects):
            walk = generate_walk(sample_subject(rng), cfg, rng)
            parts.append(swing_profiles(walk, tau, point))
    progress, lift, sideways, fraction = (np.concatenate(part) for part in zip(*parts, strict=True))
    return {
        "progress": progress.mean(axis=0),
        "progress_std": progress.std(axis=0),
        "lift": lift.mean(axis=0),
        "lift_std": lift.std(axis=0),
        "sideways": sideways.mean(axis=0),
        "sideways_std": sideways.std(axis=0),
        "fraction": np.array([fraction.mean(), fraction.std()]),
        "swings": np.array([len(progress)]),
    }


def _other_foot_flat(walk: Walk, foot: int, ff0: float, ff1: float) -> float:
    """The other foot's foot flat between ``ff0`` and ``ff1`` when there is exactly one, else
    NaN."""
    other = walk.events[SIDES[1 - foot]].ff_s
    inside = other[np.isfinite(other) & (other > ff0) & (other < ff1)]
    return float(inside[0]) if len(inside) == 1 else float("nan")


def swing_spans(
    walk: Walk,
    tau: np.ndarray,
    progress: np.ndarray,
    samples: int = 100,
    point: ShoePoint | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(cycles, spans, contralateral)`` (m,) of every swing of ``walk`` (the progress of
    ``point``, None: the instep marker): the cycle
    ``FF' − FF``, the span ``s`` in ``[0.3, 1] · cycle`` minimising ``Σ (ρ̂(τ_k) − ρ(t_k))²``
    over ``samples`` times ``t_k`` from ``FF`` to ``FF'``, with ``ρ̂`` the template
    ``progress`` at ``tau`` and ``τ_k = clip((t_k − FF' + s) / s, 0, 1)``, and ``FF' − FF_c``
    (NaN where the other foot has no single foot flat between ``FF`` and ``FF'``; module
    docstring)."""
    cycles, spans, contralateral = [], [], []
    for s, ff0, _, ff1 in _swings(walk, point):
        t = np.linspace(ff0, ff1, samples)
        rho, _ = _progress(walk, s, t, point)

        def cost(span: float, t: np.ndarray = t, rho: np.ndarray = rho, ff1: float = ff1) -> float:
            fit = np.interp(np.clip((t - ff1 + span) / span, 0.0, 1.0), tau, progress)
            return float(np.sum((fit - rho) ** 2))

        cycle = ff1 - ff0
        best = minimize_scalar(cost, bounds=(0.3 * cycle, cycle), method="bounded")
        cycles.append(cycle)
        spans.append(float(best.x))
        contralateral.append(ff1 - _other_foot_flat(walk, s, ff0, ff1))
    return np.array(cycles), np.array(spans), np.array(contralateral)


def derive_swing_span(
    tau: np.ndarray,
    progress: np.ndarray,
    speeds_mps: tuple[float, ...] = (0.6, 0.7, 0.8, 0.9, 1.0, 1.1, 1.2, 1.3, 1.4, 1.5, 1.6, 1.7),
    subjects: int = 5,
    seed: int = 0,
    walk_length_m: float = 10.0,
    point: ShoePoint | None = None,
) -> dict[str, float]:
    """The line ``span = offset_s + per_cycle · cycle`` fitted (least squares) to
    :func:`swing_spans` of ``point`` (None: the instep marker), with the template
    ``progress`` at ``tau``, over ``subjects`` random subjects walking ``walk_length_m`` at each of
    ``speeds_mps`` (the generator's whole range by default): ``offset_s``, ``per_cycle``, the
    residual's standard deviation ``residual_s`` and, for comparison, that of the best line
    through the origin (``span = c · cycle``) ``proportional_residual_s``, and ``swings``; and
    the line ``span = contralateral_offset_s + per_contralateral · (FF' − FF_c)`` over the
    swings that have one ``FF_c`` (module docstring), its ``contralateral_residual_s`` and the
    cycle line's over the same swings, ``cycle_residual_same_s`` (NaN without such swings)."""
    rng = np.random.default_rng(seed)
    cycles, spans, others = [], [], []
    for speed in speeds_mps:
        cfg = GaitConfig(speed_mps=float(speed), walk_length_m=float(walk_length_m))
        for _ in range(subjects):
            walk = generate_walk(sample_subject(rng), cfg, rng)
            c, s, o = swing_spans(walk, tau, progress, point=point)
            cycles.append(c)
            spans.append(s)
            others.append(o)
    cycle, span, other = np.concatenate(cycles), np.concatenate(spans), np.concatenate(others)
    per_cycle, offset = np.polyfit(cycle, span, 1)
    c = float(cycle @ span / (cycle @ cycle))
    has = np.isfinite(other)
    per_other = offset_other = float("nan")  # no swing with one foot flat of the other foot
    if has.sum() >= 2:
        per_other, offset_other = np.polyfit(other[has], span[has], 1)
    cycle_residual = span - offset - per_cycle * cycle
    return {
        "offset_s": float(offset),
        "per_cycle": float(per_cycle),
        "residual_s": float(np.std(cycle_residual)),
        "proportional_residual_s": float(np.std(span - c * cycle)),
        "contralateral_offset_s": float(offset_other),
        "per_contralateral": float(per_other),
        "contralateral_residual_s": float(
            np.std(span[has] - offset_other - per_other * other[has]) if has.any() else np.nan
        ),
        "cycle_residual_same_s": float(np.std(cycle_residual[has]) if has.any() else np.nan),
        "swings": float(len(cycle)),
        "contralateral_swings": float(has.sum()),
    }
