"""Filling a foot's unseen swing from the filter's stance landmarks (``pipeline.gap_fill: swing``).

A waist camera loses each foot for 0.5–0.8 s of every stride (thesis Fig. 5.10): from about
heel off, when the foot is behind the body, to late swing. The motion predictor alone moves the
foot there too early and too evenly (the true foot rests, rolls over the toes, then swings with
its peak speed late), which left 8–10 cm errors in those frames (docs/pipeline.md). The filter
knows more than the frames do: where the foot stood before the gap and where it lands after
it (two consecutive stance landmarks of that foot, :class:`gaitnet.vio.result.StanceFoot`), and
when it lands (the next landmark's first frame, when its stance was confirmed, at foot
flat). Between them the swing of a walking foot has a stereotyped
shape, which this module lays between the two rests:

    f(t) = p₀ + ρ(τ) (p₁ − p₀) + μ(τ) H n̂ + λ(τ) H ẑ,   τ = clip((t − t_HO) / (t_FF′ − t_HO), 0, 1)

- ``p₀``, ``p₁``: the median measured foot point over the frames of each stance (the points
  the correction is given, so the fill is the same kind of point);
- ``t_FF′``: the next landmark's first frame time; ``t_HO``, where the swing starts,
  ``t_FF′ − (a + b T)`` with ``T`` the landmarks' foot-flat to foot-flat time (one gait
  cycle; the typical cycle — the median over both feet's pairs but each foot's first, given
  :data:`MIN_REFERENCES` of them — where the pair's differs from it by more than
  :data:`CYCLE_TOLERANCE`: a standing start, where the first landmark began long before the
  foot flat, or a landmark first seen late; with fewer pairs than that, a foot's first pair
  takes the median of those there are: on a 3 s CMU walk its own "cycle" of 2.8 s, standing
  included, started the first swing 0.5 s early), ``a`` = ``pipeline.swing_span_offset_s``
  (:data:`SWING_SPAN_OFFSET_S`) and ``b`` = ``pipeline.swing_span_per_cycle``
  (:data:`SWING_SPAN_PER_CYCLE`): the line through the span that best lays the template over
  each generated swing, against its cycle, at 0.6–1.7 m/s (960 swings,
  :func:`gaitnet.sim.swing_profile.derive_swing_span`; 0.74 of a 1.1 s cycle, 0.69 of a 1.8 s
  one: a slow foot rolls longer over its toes before it swings); where the other foot has
  one landmark between the two, first seen at ``t_FFc``, instead ``c + d (t_FF′ − t_FFc)``,
  ``c`` = ``pipeline.swing_span_contralateral_offset_s``
  (:data:`SWING_SPAN_CONTRALATERAL_OFFSET_S`) and ``d`` =
  ``pipeline.swing_span_per_contralateral`` (:data:`SWING_SPAN_PER_CONTRALATERAL`; 0: the
  cycle's line everywhere): the foot leaves the floor at the end of the double support that
  the other foot's landing begins, so that interval times the swing more closely than the
  cycle does (fitted the same way: residual 22 against 28 ms), used while it lies within
  :data:`CONTRALATERAL_SHARE` of the cycle (else the other foot's landmark is a standing
  start or a missed one) and not for a foot's first pair (a step out of standing, whose
  timing the steady swings of the fit do not describe); then laid ``δ`` =
  ``pipeline.swing_start_delay_s`` (:data:`SWING_START_DELAY_S`, 0) later: 0.05 s raises the
  filled frames' error on real walks (the CMU walks of ``benchmarks/bench_swing_fill.py``),
  whose swings start earlier against the next foot flat than the generator's, and with this
  template on the 7 held-out simulated sessions too (docs/pipeline.md, *The start delay*);
  never earlier than ``pipeline.swing_rest_end_lead_s`` (:data:`SWING_REST_END_LEAD_S`, 0.05 s)
  before the last frame the filter saw the foot resting (the right foot's landmark outlasts
  heel off: the rising heel still gives it a stationary point), and at least
  :data:`MIN_SPAN_S` before the landing;
- ``ρ`` (0 → 1, :data:`SWING_PROGRESS`), ``λ`` (:data:`SWING_LIFT`) and ``μ``
  (:data:`SWING_SIDEWAYS`; ``λ``, ``μ`` fractions of the body height ``H``): the mean path
  from heel off to the next foot flat, over the simulator's walks at 0.8–1.6 m/s (458 swings
  of 30 subjects), of the point the pose correction is given for a foot: the segmenter's
  keypoint as the correction models it, ``correction.marker_offset_m``'s default
  (:data:`gaitnet.pipeline.config.KEYPOINT_OFFSET_M`) from the ankle. Until 2026-11-28 it was
  the instep marker's path, which lies up to 0.017 H higher at τ 0.3–0.6: the correction then
  put the keypoint there and the foot too high (docs/pipeline.md). Derived by
  ``data/derive_swing_template.py`` with
  :func:`gaitnet.sim.swing_profile.derive_swing_template`, and checked against a fresh
  derivation by a test: forward, up, and outwards along ``n̂``, the horizontal unit vector
  square to ``p₁ − p₀`` away from the body's midline (to the left of the walking direction
  for the left foot, to the right for the right); the foot bows outwards by up to 0.018 H
  (3.2 cm at 1.8 m) in mid-swing, on the CMU walks of ``benchmarks/bench_swing_fill.py`` by
  about half that (docs/pipeline.md); on real walks the template fits less well than on
  simulated ones (docs/pipeline.md, *Limits*).

Where the foot is seen again before it lands (a foot's first pair too: the step out of
standing), its measured points time the swing too: at each steadily seen frame after the start
whose progress along ``p₀ → p₁`` is :data:`RETIME_PROGRESS` (0.5–0.97; the first points back in
view lie a few cm ahead of the foot, and near the landing the template hardly moves), the
template's τ at that progress gives the start for the landing fixed; the start moves
``pipeline.swing_retime_weight`` (:data:`SWING_RETIME_WEIGHT`) of the way to their median, at
most ``pipeline.swing_retime_max_shift_s`` (:data:`SWING_RETIME_MAX_SHIFT_S`), also to before
the bound that the foot's last resting frame sets. Averaging the two estimates lowered the
filled frames' error on the 7 held-out and the 23 other sessions of the filter's protocol alike
(docs/pipeline.md); trusting the points alone raised it.

Only frames where the foot is not steadily seen (:func:`gaitnet.pipeline.gap_bridge.steadily_seen`)
between the two landmarks are filled, and, through each landmark's own frames where the foot
is not steadily seen, the foot rests at that landmark's point (:func:`rest_points`). A
landmark whose foot was never steadily seen in its own frames (confirmed from a few sightings
of a toe under a flexed knee) has no such point, and its start, which times the landing, is
late: where the foot was seen arriving within :data:`LANDING_LOOKBACK_S` before that start,
within :data:`LANDING_RADIUS_M` of where it rests and :data:`LANDING_HEIGHT_M` above its
resting height, the rest begins at that sighting and its point is the landmark moved by the
foot's median offset of rest point from landmark (:func:`landed_rests`; CMU walking_06
mirrored: the left foot's NMATE 8.8 → 2.1 cm). Placed from the landmark without such a
sighting, the swings were laid 0.2–0.4 s late on CMU walks: such a landmark is still skipped.

A pair of landmarks is skipped when it cannot be one stride of one foot
(:data:`CYCLE_RANGE_S`, except a foot's first pair, which may start with standing of any
length and then only needs the typical cycle; :data:`MIN_STRIDE_M`, :data:`MAX_STRIDE_M`),
when it spans a missed landmark (a stride over :data:`STRIDE_OUTLIER`
times the typical one, or a cycle longer than the typical one by more than the tolerance, but
for a foot's first pair), or when either stance has no measured point.
:func:`gaitnet.pipeline.infer.reconstruct` runs the pose correction a second time with the
filled points as that foot's measurements.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from gaitnet.pipeline.gap_bridge import feet_steadily_seen
from gaitnet.vio.gait import SIDES, Stance, merge_split_stances
from gaitnet.vio.result import StanceFoot

__all__ = [
    "CYCLE_RANGE_S",
    "CONTRALATERAL_SHARE",
    "CYCLE_TOLERANCE",
    "MAX_STRIDE_M",
    "MIN_REFERENCES",
    "MIN_SPAN_S",
    "MIN_STRIDE_M",
    "STRIDE_OUTLIER",
    "SWING_LIFT",
    "SWING_PROGRESS",
    "SWING_REST_END_LEAD_S",
    "SWING_RETIME_MAX_SHIFT_S",
    "SWING_RETIME_WEIGHT",
    "SWING_SIDEWAYS",
    "SWING_SPAN_CONTRALATERAL_OFFSET_S",
    "SWING_SPAN_OFFSET_S",
    "SWING_SPAN_PER_CONTRALATERAL",
    "SWING_SPAN_PER_CYCLE",
    "SWING_START_DELAY_S",
    "LANDING_HEIGHT_M",
    "LANDING_LOOKBACK_S",
    "LANDING_RADIUS_M",
    "landed_rests",
    "SWING_TAU",
    "SwingPlan",
    "plan_swings",
    "rest_points",
    "rests_of",
    "swing_fill",
]

SWING_TAU = np.linspace(0.0, 1.0, 21)
# fmt: off
SWING_PROGRESS = np.array([
    0.0, 0.0003, 0.0023, 0.0075, 0.0173, 0.0326, 0.0528, 0.0784, 0.1168, 0.1741, 0.2607,
    0.3792, 0.5200, 0.6654, 0.7944, 0.8901, 0.9477, 0.9760, 0.9902, 0.9983, 1.0,
])
SWING_LIFT = np.array([
    0.0, 0.0003, 0.0023, 0.0067, 0.0131, 0.0198, 0.0243, 0.0263, 0.0294, 0.0332, 0.0369,
    0.0390, 0.0394, 0.0402, 0.0423, 0.0429, 0.0386, 0.0287, 0.0147, 0.0030, 0.0,
])
SWING_SIDEWAYS = np.array([
    0.0, 0.0, 0.0001, 0.0005, 0.0011, 0.0021, 0.0034, 0.0050, 0.0073, 0.0102, 0.0136,
    0.0166, 0.0176, 0.0157, 0.0111, 0.0053, 0.0006, -0.0011, -0.0006, -0.0001, 0.0,
])
# fmt: on
SWING_SPAN_OFFSET_S = 0.146  # span = a + b · cycle [s] (derive_swing_span, seed 0)
SWING_SPAN_PER_CYCLE = 0.607
# span = c + d · (FF' − the other foot's FF between) [s] (derive_swing_span, seed 0)
SWING_SPAN_CONTRALATERAL_OFFSET_S = 0.147
SWING_SPAN_PER_CONTRALATERAL = 1.212
SWING_START_DELAY_S = 0.0  # the timing lines' start laid this much later [s] (docstring)
SWING_REST_END_LEAD_S = 0.05  # the start at most this long before the rest's last frame [s]
SWING_RETIME_WEIGHT = 0.5  # share of the start read where the foot is seen again (0: off)
SWING_RETIME_MAX_SHIFT_S = 0.1  # that start kept within this of the timing line's [s]
RETIME_PROGRESS = (0.5, 0.97)  # measured progress the template's time is read at
CONTRALATERAL_SHARE = (0.3, 0.7)  # FF' − FF_c as a share of the cycle (0.5 in even walking)
CYCLE_RANGE_S = (0.5, 3.0)  # foot flat to foot flat of one foot, slow to fast walking
CYCLE_TOLERANCE = 0.25  # a cycle further than this from the typical one is not the pair's own
STRIDE_OUTLIER = 1.5  # a stride this many times the typical one spans a missed landmark
MIN_REFERENCES = 3  # pairs (other than each foot's first) needed for a typical cycle
MIN_STRIDE_M = 0.2  # shorter: a shuffle or one stance seen as two, not a swing
MIN_SPAN_S = 0.05  # a swing's start lies at least this long before its landing [s]
LANDING_LOOKBACK_S = 0.3
"""How long before a landmark never seen in its own frames its foot may have been seen
arriving at it [s] (:func:`landed_rests`): a landmark confirmed from weak sightings of a toe
starts 0.1–0.3 s after the landing."""
LANDING_RADIUS_M = 0.08
"""How close along the floor to where the foot rests a point seen before the landmark's first
frame must lie to be the foot arriving there [m] (:func:`landed_rests`)."""
LANDING_HEIGHT_M = 0.04
"""How far above its resting height that point may lie [m] (:func:`landed_rests`): the heel
down and the forefoot lowering, not the foot still in the air ahead of its rest."""
MAX_STRIDE_M = 2.2  # longer than any walking stride


@dataclass(frozen=True)
class _Swing:
    """One foot's candidate swing between two of its rests."""

    side: int
    before: Stance
    after: Stance
    cycle_s: float
    first: bool  # the foot's first pair (its first rest may be a standing start)
    p0: np.ndarray
    p1: np.ndarray

    @property
    def stride_m(self) -> float:
        return _step_xy(self.p0, self.p1)[1]


@dataclass(frozen=True)
class SwingPlan:
    """Where and when one unseen swing is laid (module docstring): ``side`` (0 left, 1 right),
    the rest points ``p0``, ``p1`` (3,), the swing's start ``heel_off_s`` and its landing
    ``landing_s`` (the next landmark's first frame), whether it is the foot's first pair and
    whether the bound that the filter's last sight of the foot resting sets (that frame less
    ``rest_end_lead_s``) set the start (``from_rest_end``: the timing line put it earlier),
    and the frames it fills (``window`` (n,) bool)."""

    side: int
    p0: np.ndarray
    p1: np.ndarray
    heel_off_s: float
    landing_s: float
    first: bool
    from_rest_end: bool
    window: np.ndarray


def plan_swings(
    t_s: np.ndarray,
    measured: np.ndarray,
    stance_feet: Sequence[StanceFoot],
    span_offset_s: float = SWING_SPAN_OFFSET_S,
    span_per_cycle: float = SWING_SPAN_PER_CYCLE,
    span_contralateral_offset_s: float = SWING_SPAN_CONTRALATERAL_OFFSET_S,
    span_per_contralateral: float = SWING_SPAN_PER_CONTRALATERAL,
    retime_weight: float = SWING_RETIME_WEIGHT,
    retime_max_shift_s: float = SWING_RETIME_MAX_SHIFT_S,
    start_delay_s: float = SWING_START_DELAY_S,
    rest_end_lead_s: float = SWING_REST_END_LEAD_S,
) -> list[SwingPlan]:
    """The swings :func:`swing_fill` fills: the left foot's in time order, then the right
    foot's. ``t_s`` (n,) frame times, ``measured`` (n, 2, 3) the measured foot points (left,
    right; NaN where not seen), ``stance_feet`` the filter's landmarks (a stance reported
    twice is made one first, :func:`gaitnet.vio.gait.merge_split_stances`); the timing keys
    as in the module docstring (``pipeline.swing_*``), ``span_per_contralateral`` 0 timing
    every swing by its cycle alone."""
    t_s = np.asarray(t_s, dtype=np.float64)
    measured = np.asarray(measured, dtype=np.float64)
    if measured.shape != (len(t_s), 2, 3):
        raise ValueError(
            f"swing_fill: measured must be (n, 2, 3) for n = {len(t_s)} frames, "
            f"got {measured.shape}"
        )
    seen = feet_steadily_seen(measured)
    rests, points = landed_rests(t_s, measured, seen, stance_feet)
    swings = _candidate_swings(rests, points)
    cycles = _swing_cycles(swings)
    plans = []
    for w in swings:
        cycle = cycles.get(id(w))
        if cycle is None:
            continue
        span_s = span_offset_s + span_per_cycle * cycle
        to_landing = _after_other_landing(w, rests)
        if (
            span_per_contralateral > 0
            and not w.first
            and CONTRALATERAL_SHARE[0] * cycle <= to_landing <= CONTRALATERAL_SHARE[1] * cycle
        ):
            span_s = span_contralateral_offset_s + span_per_contralateral * to_landing
        landing = w.after.t_first_s
        timed = min(landing - span_s + start_delay_s, landing - MIN_SPAN_S)
        window = (t_s > w.before.t_last_s) & (t_s < w.after.t_first_s) & ~seen[:, w.side]
        if not window.any():
            continue
        rest_bound = w.before.t_last_s - rest_end_lead_s
        heel_off = max(timed, rest_bound)
        if retime_weight > 0:
            seen_again = _seen_again_start(t_s, measured[:, w.side], seen[:, w.side], w, heel_off)
            if np.isfinite(seen_again):
                shift = np.clip(seen_again - heel_off, -retime_max_shift_s, retime_max_shift_s)
                heel_off += retime_weight * float(shift)
        heel_off = min(heel_off, landing - MIN_SPAN_S)
        plans.append(
            SwingPlan(
                side=w.side,
                p0=w.p0,
                p1=w.p1,
                heel_off_s=heel_off,
                landing_s=landing,
                first=w.first,
                from_rest_end=rest_bound > timed,
                window=window,
            )
        )
    return plans


def _swing_cycles(swings: Sequence[_Swing]) -> dict[int, float]:
    """The gait cycle each swing is timed by (module docstring), by ``id`` of the swing; a
    swing that spans a missed rest, or a long standing start with no typical cycle to stand
    in for it, has none."""
    # the typical cycle and stride, from the pairs that are not a foot's first
    reference = [w for w in swings if not w.first]
    typical_cycle = typical_stride = np.nan
    if len(reference) >= MIN_REFERENCES:
        typical_cycle = float(np.median([w.cycle_s for w in reference]))
        typical_stride = float(np.median([w.stride_m for w in reference]))
    # with fewer references than a typical cycle needs (a short walk), a foot's first pair
    # takes their median: its own "cycle" counts the standing before the step
    few = float(np.median([w.cycle_s for w in reference])) if reference else np.nan
    out: dict[int, float] = {}
    for w in swings:
        cycle = w.cycle_s
        if not np.isfinite(typical_cycle):
            if w.first and np.isfinite(few):
                cycle = few
            elif cycle > CYCLE_RANGE_S[1]:
                continue  # a long standing start, and no typical cycle to stand in for it
        else:
            if w.stride_m > STRIDE_OUTLIER * typical_stride:
                continue  # two strides: a rest between them was missed
            if abs(cycle - typical_cycle) > CYCLE_TOLERANCE * typical_cycle:
                if cycle > typical_cycle and not w.first:
                    continue  # likewise
                cycle = typical_cycle  # a standing start, or a rest first seen late
        out[id(w)] = cycle
    return out


def swing_fill(
    t_s: np.ndarray,
    measured: np.ndarray,
    stance_feet: Sequence[StanceFoot],
    body_height_m: float,
    **timing: float,
) -> np.ndarray:
    """Foot points (n, 2, 3) for the unseen frames of each foot's swings (module docstring),
    NaN elsewhere. ``t_s`` (n,) frame times, ``measured`` (n, 2, 3) the measured foot points
    (left, right; NaN where not seen), ``stance_feet`` the filter's landmarks, ``timing`` the
    keyword arguments of :func:`plan_swings`, which lays each swing."""
    t_s = np.asarray(t_s, dtype=np.float64)
    plans = plan_swings(t_s, measured, stance_feet, **timing)
    out = np.full((len(t_s), 2, 3), np.nan)
    # the foot rests at its point through each stance's unseen frames
    measured = np.asarray(measured, dtype=np.float64)
    seen = feet_steadily_seen(measured)
    rests, points = landed_rests(t_s, measured, seen, stance_feet)
    for r in rests:
        overlapping = any(
            o is not r
            and o.side == r.side
            and o.t_first_s <= r.t_last_s
            and r.t_first_s <= o.t_last_s
            for o in rests
        )
        if id(r) in points and not overlapping:  # one foot cannot rest twice at once
            s = SIDES.index(r.side)
            out[_inside(t_s, r) & ~seen[:, s], s] = points[id(r)]
    for w in plans:
        span = max(w.landing_s - w.heel_off_s, 1e-6)
        tau = np.clip((t_s[w.window] - w.heel_off_s) / span, 0.0, 1.0)
        rho = np.interp(tau, SWING_TAU, SWING_PROGRESS)
        ahead, _ = _step_xy(w.p0, w.p1)
        outwards = np.array([-ahead[1], ahead[0], 0.0]) * (1.0 if w.side == 0 else -1.0)
        sideways = np.interp(tau, SWING_TAU, SWING_SIDEWAYS) * body_height_m
        out[w.window, w.side] = w.p0 + rho[:, None] * (w.p1 - w.p0) + sideways[:, None] * outwards
        out[w.window, w.side, 2] += np.interp(tau, SWING_TAU, SWING_LIFT) * body_height_m
    return out


def rests_of(stance_feet: Sequence[StanceFoot]) -> list[Stance]:
    """The landmarks as rests, a stance reported twice made one
    (:func:`gaitnet.vio.gait.merge_split_stances`)."""
    return merge_split_stances(
        [Stance(f.side, f.t_first_s, f.t_last_s, np.asarray(f.xy)) for f in stance_feet]
    )


def _seen_again_start(
    t_s: np.ndarray, points: np.ndarray, seen: np.ndarray, swing: _Swing, heel_off_s: float
) -> float:
    """The swing's start as the frames where the foot is seen again before it lands tell it
    (module docstring): at each steadily seen frame after ``heel_off_s`` whose measured
    progress along ``p₀ → p₁`` lies in :data:`RETIME_PROGRESS`, the template's τ at that
    progress gives the start for the landing fixed; their median (NaN where there is none)."""
    ahead, length = _step_xy(swing.p0, swing.p1)
    landing = swing.after.t_first_s
    frames = np.flatnonzero(seen & (t_s > heel_off_s) & (t_s < landing))
    progress = (points[frames, :2] - swing.p0[:2]) @ ahead / length
    use = (progress >= RETIME_PROGRESS[0]) & (progress <= RETIME_PROGRESS[1])
    if not use.any():
        return float("nan")
    tau = np.interp(progress[use], SWING_PROGRESS, SWING_TAU)
    return float(np.median((t_s[frames[use]] - tau * landing) / (1.0 - tau)))


def _step_xy(p0: np.ndarray, p1: np.ndarray) -> tuple[np.ndarray, float]:
    """The horizontal unit vector (2,) from ``p0`` to ``p1`` and the horizontal distance [m]
    (a swing's stride: at least :data:`MIN_STRIDE_M`)."""
    d = (p1 - p0)[:2]
    length = float(np.hypot(d[0], d[1]))
    return d / length, length


def _after_other_landing(swing: _Swing, rests: Sequence[Stance]) -> float:
    """Seconds from the other foot's landmark between the swing's two rests (its first frame)
    to the second rest's first frame; NaN unless the other foot has exactly one there."""
    other_side = SIDES[1 - swing.side]
    t0, t1 = swing.before.t_first_s, swing.after.t_first_s
    other = [r.t_first_s for r in rests if r.side == other_side and t0 < r.t_first_s < t1]
    return t1 - other[0] if len(other) == 1 else float("nan")


def _candidate_swings(rests: Sequence[Stance], points: dict[int, np.ndarray]) -> list[_Swing]:
    """Consecutive rests of each foot that can be one stride (:data:`CYCLE_RANGE_S`, but any
    length for a foot's first pair; :data:`MIN_STRIDE_M`, :data:`MAX_STRIDE_M`) and have
    points (``points``, by ``id`` of the rest)."""
    out = []
    for s, side in enumerate(SIDES):
        own = sorted((r for r in rests if r.side == side), key=lambda r: r.t_first_s)
        for i, (before, after) in enumerate(zip(own, own[1:], strict=False)):
            cycle = after.t_first_s - before.t_first_s
            # a foot's first rest may be a standing start of any length (its cycle is then
            # replaced by the typical one, below)
            if cycle < CYCLE_RANGE_S[0] or (cycle > CYCLE_RANGE_S[1] and i > 0):
                continue
            p0, p1 = points.get(id(before)), points.get(id(after))
            if p0 is None or p1 is None:
                continue
            swing = _Swing(s, before, after, cycle, i == 0, p0, p1)
            if MIN_STRIDE_M <= swing.stride_m <= MAX_STRIDE_M:
                out.append(swing)
    return out


def _inside(t_s: np.ndarray, rest: Stance) -> np.ndarray:
    return (t_s >= rest.t_first_s - 1e-6) & (t_s <= rest.t_last_s + 1e-6)


def _rest_point(
    t_s: np.ndarray, points: np.ndarray, seen: np.ndarray, rest: Stance
) -> np.ndarray | None:
    """Median measured point (3,) over the frames of one stance, None when none is measured."""
    inside = seen & _inside(t_s, rest)
    if not inside.any():
        return None
    return np.median(points[inside], axis=0)


def rest_points(
    t_s: np.ndarray, measured: np.ndarray, seen: np.ndarray, rests: Sequence[Stance]
) -> dict[int, np.ndarray]:
    """Each rest's point (3,), by ``id`` of the rest: the median measured point of its foot
    over its frames (:func:`_rest_point`); none for a rest whose foot was never steadily
    seen."""
    out: dict[int, np.ndarray] = {}
    for r in rests:
        s = SIDES.index(r.side)
        p = _rest_point(t_s, measured[:, s], seen[:, s], r)
        if p is not None:
            out[id(r)] = p
    return out


def landed_rests(
    t_s: np.ndarray, measured: np.ndarray, seen: np.ndarray, stance_feet: Sequence[StanceFoot]
) -> tuple[list[Stance], dict[int, np.ndarray]]:
    """The rests (:func:`rests_of`) and their points (by ``id`` of the rest), with each rest
    whose foot was never steadily seen in its own frames landed where its foot was seen
    arriving (module docstring): where steadily seen points of that foot lie within
    :data:`LANDING_RADIUS_M` (along the floor) of the landmark moved by the foot's median
    offset of rest point from landmark and less than :data:`LANDING_HEIGHT_M` above the foot's
    median rest height, up to :data:`LANDING_LOOKBACK_S` before the landmark's first frame,
    the rest begins at the first of them and its point is the landmark
    moved by that offset, at the foot's median rest height. A foot without a measured rest
    lands none."""
    rests = rests_of(stance_feet)
    points = rest_points(t_s, measured, seen, rests)
    for s, side in enumerate(SIDES):
        own = [r for r in rests if r.side == side]
        measured_rests = [r for r in own if id(r) in points]
        if not measured_rests:
            continue
        offset = np.median([points[id(r)][:2] - r.xy for r in measured_rests], axis=0)
        height = float(np.median([points[id(r)][2] for r in measured_rests]))
        for r in own:
            if id(r) in points:
                continue
            guess = np.asarray(r.xy, dtype=np.float64) + offset
            before = seen[:, s] & (t_s >= r.t_first_s - LANDING_LOOKBACK_S) & (t_s < r.t_first_s)
            near = (
                before
                & (np.linalg.norm(measured[:, s, :2] - guess, axis=1) < LANDING_RADIUS_M)
                & (measured[:, s, 2] - height < LANDING_HEIGHT_M)
            )
            if not near.any():
                continue
            landed = replace(r, t_first_s=float(t_s[np.flatnonzero(near)[0]]))
            rests[rests.index(r)] = landed
            points[id(landed)] = np.array([guess[0], guess[1], height])
    return rests, points
