"""Swing fill between stance landmarks (gaitnet.pipeline.swing_fill): known answers, the
guards, and the committed template against a fresh derivation from the gait generator."""

from __future__ import annotations

import numpy as np
import pytest

from gaitnet.pipeline.gap_bridge import feet_steadily_seen
from gaitnet.pipeline.swing_fill import (
    MIN_SPAN_S,
    SWING_LIFT,
    SWING_PROGRESS,
    SWING_REST_END_LEAD_S,
    SWING_SIDEWAYS,
    SWING_SPAN_CONTRALATERAL_OFFSET_S,
    SWING_SPAN_OFFSET_S,
    SWING_SPAN_PER_CONTRALATERAL,
    SWING_SPAN_PER_CYCLE,
    SWING_START_DELAY_S,
    SWING_TAU,
    landed_rests,
    plan_swings,
    swing_fill,
)
from gaitnet.vio.result import StanceFoot

FPS = 30.0
H = 1.75


def _line(cycle: float) -> float:
    """The cycle's line for a gait cycle [s], with the default constants."""
    return SWING_SPAN_OFFSET_S + SWING_SPAN_PER_CYCLE * cycle


def _span(cycle: float) -> float:
    """The span the template is laid over (its start to the foot flat) for a gait cycle [s]:
    the line less the start delay."""
    return _line(cycle) - SWING_START_DELAY_S


def _rest(side: str, t0: float, t1: float, x: float) -> StanceFoot:
    return StanceFoot(0, side, t0, t1, np.array([x, 0.1]), np.full(2, 0.01), 10)


def _walk(
    rests: list[tuple[float, float, float]], n: int = 90
) -> tuple[np.ndarray, np.ndarray, list[StanceFoot]]:
    """Frames at 30/s; the left foot measured only while resting at x (1 cm above the floor),
    the right foot never."""
    t = np.arange(n) / FPS
    measured = np.full((n, 2, 3), np.nan)
    feet = []
    for t0, t1, x in rests:
        inside = (t >= t0 - 1e-9) & (t <= t1 + 1e-9)
        measured[inside, 0] = [x, 0.1, 0.01]
        feet.append(_rest("left", t0, t1, x))
    return t, measured, feet


def test_known_answer_at_heel_off_mid_swing_and_landing() -> None:
    # rest 1 at x = 0 from 0 to 0.6 s, rest 2 at x = 1.2 m from 1.2 s: cycle 1.2 s, the swing
    # starts span(1.2) ≈ 0.87 s before the second foot flat → 0.33 s, clamped to the last rest
    # frame 0.6 s (with no lead before it)
    t, measured, feet = _walk([(0.0, 0.6, 0.0), (1.2, 2.0, 1.2)])
    out = swing_fill(t, measured, feet, H, rest_end_lead_s=0.0)
    gap = (t > 0.6 + 1e-9) & (t < 1.2 - 1e-9)
    assert np.isfinite(out[gap, 0]).all()
    assert np.isnan(out[~gap, 0]).all() and np.isnan(out[:, 1]).all()  # right: no landmarks
    # at t = 0.9 s, half-way from heel off (0.6 s) to foot flat (1.2 s): τ = 0.5, a grid point
    k = int(round(0.9 * FPS))
    i = int(np.flatnonzero(np.isclose(SWING_TAU, 0.5))[0])
    # walking along +x the left foot's outwards is +y
    expected = np.array(
        [SWING_PROGRESS[i] * 1.2, 0.1 + SWING_SIDEWAYS[i] * H, 0.01 + SWING_LIFT[i] * H]
    )
    np.testing.assert_allclose(out[k, 0], expected, atol=1e-12)
    # the path moves forward only, and lands: just before foot flat it is within 1 cm
    x = out[gap, 0, 0]
    assert (np.diff(x) >= -1e-12).all()
    assert abs(out[int(round(1.2 * FPS)) - 1, 0, 0] - 1.2) < 0.01


@pytest.mark.parametrize("side", [0, 1])
@pytest.mark.parametrize("heading_deg", [0.0, 90.0, 200.0])
def test_the_swing_bows_away_from_the_midline(side: int, heading_deg: float) -> None:
    # the walk above turned to ``heading_deg`` and given to either foot: mid-swing the fill
    # lies SWING_SIDEWAYS · H from the straight line, to the left of the walking direction
    # for the left foot and to the right for the right foot
    t, measured, feet = _walk([(0.0, 0.6, 0.0), (1.2, 2.0, 1.2)])
    a = np.radians(heading_deg)
    R = np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])
    turned = np.full_like(measured, np.nan)
    turned[:, side] = measured[:, 0] @ R.T
    feet = [
        StanceFoot(f.landmark_id, ("left", "right")[side], f.t_first_s, f.t_last_s,
                   R[:2, :2] @ f.xy, f.std_xy, f.n_observations)
        for f in feet
    ]  # fmt: skip
    out = swing_fill(t, turned, feet, H, rest_end_lead_s=0.0)
    k = int(round(0.9 * FPS))
    i = int(np.flatnonzero(np.isclose(SWING_TAU, 0.5))[0])
    ahead = R[:2, 0]
    left_of_walk = np.array([-ahead[1], ahead[0]])
    offset = (out[k, side, :2] - R[:2, :2] @ [0.0, 0.1]) @ left_of_walk
    assert offset == pytest.approx((1 if side == 0 else -1) * SWING_SIDEWAYS[i] * H, abs=1e-12)
    assert SWING_SIDEWAYS[i] * H > 0.02  # more than 2 cm: the test can tell the sides apart


def test_plan_says_what_set_each_swings_start() -> None:
    # the case above and the one below: the last rest frame (0.6 s, less the lead) after the
    # timed start (1.2 − span(1.2)), and the timed start (1.6 − span(1.6)) after the last rest
    # frame (0.2 s)
    for rests, heel_off, from_rest_end in (
        ([(0.0, 0.6, 0.0), (1.2, 2.0, 1.2)], 0.6 - SWING_REST_END_LEAD_S, True),
        ([(0.0, 0.2, 0.0), (1.6, 2.5, 1.0)], 1.6 - _span(1.6), False),
    ):
        t, measured, feet = _walk(rests)
        (plan,) = plan_swings(t, measured, feet)
        assert (plan.side, plan.first, plan.from_rest_end) == (0, True, from_rest_end)
        assert plan.heel_off_s == pytest.approx(heel_off, abs=1e-12)
        assert plan.landing_s == rests[1][0]
        np.testing.assert_array_equal(
            plan.window, np.isfinite(swing_fill(t, measured, feet, H)[:, 0, 0])
        )


def test_heel_off_from_the_cycle_when_the_foot_is_seen_resting_late() -> None:
    # the first rest is seen until 0.2 s only; cycle 1.6 s: the swing starts span(1.6) before
    # the second foot flat, so the foot still rests (progress 0) then and is half-way (τ = 0.5)
    # half a span later
    t, measured, feet = _walk([(0.0, 0.2, 0.0), (1.6, 2.5, 1.0)])
    out = swing_fill(t, measured, feet, H)
    span = _span(1.6)
    start, mid = 1.6 - span, 1.6 - span / 2
    k0 = int(np.floor(start * FPS))  # the last frame before the swing starts
    np.testing.assert_allclose(out[k0, 0], [0.0, 0.1, 0.01], atol=1e-12)
    k = int(round(mid * FPS))
    expected = np.interp((t[k] - start) / span, SWING_TAU, SWING_PROGRESS)
    np.testing.assert_allclose(out[k, 0, 0], expected, atol=1e-12)
    assert 0.1 < expected < 0.9  # mid-swing
    # a shorter span (here a proportional one) starts the swing later
    later = swing_fill(t, measured, feet, H, span_offset_s=0.0, span_per_cycle=0.6)
    assert later[k, 0, 0] < out[k, 0, 0]
    laid = 0.96 - SWING_START_DELAY_S
    np.testing.assert_allclose(
        later[k, 0, 0],
        np.interp((t[k] - (1.6 - laid)) / laid, SWING_TAU, SWING_PROGRESS),
        atol=1e-12,
    )


def test_the_other_foots_landing_times_the_swing() -> None:
    # left rests from 0, 1.2 and 2.4 s (cycle 1.2 s); the second pair's swing is seen from
    # 1.4 s only; the right foot lands at 1.85 s, 0.55 s before the left's foot flat: the span
    # is c + d · 0.55 s, not the cycle's line
    t, measured, feet = _walk([(0.0, 0.6, 0.0), (1.2, 1.4, 1.2), (2.4, 3.0, 2.4)], n=110)
    right = [_rest("right", 1.85, 2.6, 1.8)]
    out = swing_fill(t, measured, feet + right, H)
    span = SWING_SPAN_CONTRALATERAL_OFFSET_S + SWING_SPAN_PER_CONTRALATERAL * 0.55
    span -= SWING_START_DELAY_S
    assert abs(span - _span(1.2)) > 0.05  # the two lines differ here
    start = 2.4 - span
    k = np.flatnonzero((t > start) & (t < 2.4))
    expected = 1.2 + np.interp((t[k] - start) / span, SWING_TAU, SWING_PROGRESS) * 1.2
    np.testing.assert_allclose(out[k, 0, 0], expected, atol=1e-12)
    # per_contralateral 0: the cycle's line, as without the right foot
    off = swing_fill(t, measured, feet + right, H, span_per_contralateral=0.0)
    np.testing.assert_array_equal(off, swing_fill(t, measured, feet, H))
    assert np.abs(off[k, 0, 0] - out[k, 0, 0]).max() > 0.01
    # the offset acts
    later = swing_fill(t, measured, feet + right, H, span_contralateral_offset_s=0.0)
    assert (later[k, 0, 0] <= out[k, 0, 0] + 1e-12).all()
    assert (later[k, 0, 0] < out[k, 0, 0] - 1e-6).any()
    # and the start delay moves this line's start too
    (_, second) = [p for p in plan_swings(t, measured, feet + right) if p.side == 0]
    (_, delayed) = [
        p for p in plan_swings(t, measured, feet + right, start_delay_s=0.05) if p.side == 0
    ]
    assert delayed.heel_off_s - second.heel_off_s == pytest.approx(0.05, abs=1e-12)


@pytest.mark.parametrize(
    "right_landings",
    [
        [1.25],  # 1.15 s before the foot flat: beyond 0.7 of the cycle
        [2.35],  # 0.05 s before it: below 0.3 of the cycle
        [1.6, 2.0],  # two landings of the other foot (a shuffle), 0.3 m apart
    ],
)
def test_the_cycles_line_where_the_other_foot_does_not_time_the_swing(
    right_landings: list[float],
) -> None:
    t, measured, feet = _walk([(0.0, 0.6, 0.0), (1.2, 1.4, 1.2), (2.4, 3.0, 2.4)], n=110)
    right = [_rest("right", t0, t0 + 0.1, t0) for t0 in right_landings]
    np.testing.assert_array_equal(
        swing_fill(t, measured, feet + right, H), swing_fill(t, measured, feet, H)
    )


def test_a_foots_first_pair_keeps_the_cycles_line() -> None:
    # the step out of standing: the other foot's landing between does not time it
    t, measured, feet = _walk([(0.0, 0.2, 0.0), (1.2, 2.0, 1.2)])
    right = [_rest("right", 0.65, 1.4, 0.6)]
    out = swing_fill(t, measured, feet + right, H)
    assert np.isfinite(out[:, 0, 0]).sum() > 10
    np.testing.assert_array_equal(out, swing_fill(t, measured, feet, H))


def test_the_start_delay_moves_a_timed_start_and_not_a_rest_end() -> None:
    # the first rest seen until 0.2 s only: the cycle's line times the start, and a delay
    # moves it by exactly that much (the landing stays); where the rest's last frame (0.6 s)
    # sets the start, a delay that keeps the line before it changes nothing
    t, measured, feet = _walk([(0.0, 0.2, 0.0), (1.6, 2.5, 1.0)])
    starts = {
        d: plan_swings(t, measured, feet, start_delay_s=d)[0] for d in (0.0, 0.05, 0.12, -0.03)
    }
    for d, plan in starts.items():
        assert plan.heel_off_s == pytest.approx(1.6 - _line(1.6) + d, abs=1e-12)
        assert plan.landing_s == 1.6 and not plan.from_rest_end
    assert not np.array_equal(
        swing_fill(t, measured, feet, H, start_delay_s=0.0),
        swing_fill(t, measured, feet, H, start_delay_s=0.1),
    )
    t, measured, feet = _walk([(0.0, 0.6, 0.0), (1.2, 2.0, 1.2)])
    for d in (0.0, 0.1):
        (plan,) = plan_swings(t, measured, feet, start_delay_s=d)
        assert plan.heel_off_s == pytest.approx(0.6 - SWING_REST_END_LEAD_S, abs=1e-12)
        assert plan.from_rest_end
    # the rest seen until 0.4 s: the line (1.2 − 0.874 = 0.326 s) lies before its bound
    # (0.35 s), delayed by 0.1 s after it, and then the line sets the start
    t, measured, feet = _walk([(0.0, 0.4, 0.0), (1.2, 2.0, 1.2)])
    (plan,) = plan_swings(t, measured, feet, start_delay_s=0.0)
    assert plan.heel_off_s == pytest.approx(0.4 - SWING_REST_END_LEAD_S, abs=1e-12)
    assert plan.from_rest_end
    (plan,) = plan_swings(t, measured, feet, start_delay_s=0.1)
    assert plan.heel_off_s == pytest.approx(1.2 - _line(1.2) + 0.1, abs=1e-12)
    assert not plan.from_rest_end


def test_the_rest_end_lead_bounds_the_start() -> None:
    # the rest's last frame (0.6 s) less the lead bounds the start while that lies after the
    # line's start (1.2 − span(1.2) ≈ 0.33 s); a lead past it leaves the line's start; the key
    # reaches the plan through the config
    from gaitnet.config import load_config
    from gaitnet.pipeline.config import InferConfig

    t, measured, feet = _walk([(0.0, 0.6, 0.0), (1.2, 2.0, 1.2)])
    line = 1.2 - _line(1.2)
    for lead, start, from_rest_end in (
        (0.0, 0.6, True),
        (0.05, 0.55, True),
        (0.2, 0.4, True),
        (0.3, line, False),
    ):
        (plan,) = plan_swings(t, measured, feet, rest_end_lead_s=lead)
        assert plan.heel_off_s == pytest.approx(start, abs=1e-12)
        assert plan.from_rest_end == from_rest_end
    cfg = load_config(InferConfig, None, ["pipeline.swing_rest_end_lead_s=0.2"])
    (plan,) = plan_swings(t, measured, feet, **cfg.pipeline.swing_timing())
    assert plan.heel_off_s == pytest.approx(0.4, abs=1e-12)
    assert load_config(InferConfig, None, []).pipeline.swing_rest_end_lead_s == 0.05
    a = swing_fill(t, measured, feet, H, rest_end_lead_s=0.0)
    b = swing_fill(t, measured, feet, H, rest_end_lead_s=0.2)
    gap = np.isfinite(a[:, 0, 0])
    np.testing.assert_array_equal(gap, np.isfinite(b[:, 0, 0]))  # the same frames, filled
    assert (b[gap, 0, 0] >= a[gap, 0, 0] - 1e-12).all()  # an earlier start: further along
    assert (b[gap, 0, 0] > a[gap, 0, 0] + 1e-3).any()


def test_a_swing_starts_before_it_lands() -> None:
    # keys that lay the shortest line (0.15 s at a 0.5 s cycle) 0.2 s later would start the
    # swing after its landing: it starts MIN_SPAN_S before it
    t, measured, feet = _walk([(0.0, 0.05, 0.0), (0.5, 1.0, 0.6)])
    keys = {"span_offset_s": 0.0, "span_per_cycle": 0.3, "start_delay_s": 0.2}
    (plan,) = plan_swings(t, measured, feet, **keys)
    assert plan.heel_off_s == pytest.approx(0.5 - MIN_SPAN_S, abs=1e-12)
    out = swing_fill(t, measured, feet, H, **keys)
    k = np.flatnonzero(np.isfinite(out[:, 0, 0]))[-1]  # the last frame before the landing
    start = 0.5 - MIN_SPAN_S
    expected = 0.6 * np.interp((t[k] - start) / MIN_SPAN_S, SWING_TAU, SWING_PROGRESS)
    assert out[k, 0, 0] == pytest.approx(expected, abs=1e-12) and expected > 0.01  # it moves


def test_the_span_is_a_smaller_share_of_a_longer_cycle() -> None:
    # the same stride at a 1.0 s and a 1.8 s cycle (the first rest seen only briefly): the
    # swing starts span(T) before the foot flat, a larger share of the short cycle
    assert _span(1.0) / 1.0 > _span(1.8) / 1.8
    for cycle in (1.0, 1.8):
        t, measured, feet = _walk([(0.0, 0.1, 0.0), (cycle, cycle + 0.5, 1.0)], n=90)
        out = swing_fill(t, measured, feet, H)
        start = cycle - _span(cycle)
        k = int(np.ceil((start + 0.6 * _span(cycle)) * FPS))
        expected = np.interp((t[k] - start) / _span(cycle), SWING_TAU, SWING_PROGRESS)
        np.testing.assert_allclose(out[k, 0, 0], expected, atol=1e-12)


def test_a_standing_start_takes_the_feet_median_cycle() -> None:
    # standing until 1.4 s, then a foot flat every 1.2 s: the first pair's 2.5 s "cycle" is
    # replaced by the median 1.2 s, so the swing starts span(1.2) before 2.5 s, not at the
    # last rest frame
    rests = [(0.0, 1.4, 0.0), (2.5, 3.3, 1.2), (3.7, 4.5, 2.4), (4.9, 5.7, 3.6), (6.1, 6.9, 4.8)]
    t, measured, feet = _walk(rests, n=210)
    out = swing_fill(t, measured, feet, H)
    span = _span(1.2)
    start = 2.5 - span
    np.testing.assert_allclose(out[int(round(1.5 * FPS)), 0], [0.0, 0.1, 0.01], atol=1e-12)
    k = int(round(2.0 * FPS))
    expected = np.interp((2.0 - start) / span, SWING_TAU, SWING_PROGRESS) * 1.2
    np.testing.assert_allclose(out[k, 0, 0], expected, atol=1e-12)


def test_a_long_standing_start_is_filled_only_with_a_typical_cycle() -> None:
    # standing for 4 s (a 4.8 s first "cycle", beyond any stride's), then a foot flat every
    # 1.2 s: the first swing is filled with the typical cycle, starting span(1.2) before 4.8 s
    steps = [(4.8 + 1.2 * i, 5.6 + 1.2 * i, 1.2 * (i + 1)) for i in range(4)]
    t, measured, feet = _walk([(0.0, 3.5, 0.0), *steps], n=300)
    out = swing_fill(t, measured, feet, H)
    span = _span(1.2)
    start = 4.8 - span
    np.testing.assert_allclose(out[int(round(3.8 * FPS)), 0], [0.0, 0.1, 0.01], atol=1e-12)
    k = int(round(4.2 * FPS))
    expected = np.interp((4.2 - start) / span, SWING_TAU, SWING_PROGRESS) * 1.2
    np.testing.assert_allclose(out[k, 0, 0], expected, atol=1e-12)
    # with one step after it there is no typical cycle, and the long first pair is not filled
    t, measured, feet = _walk([(0.0, 3.5, 0.0), steps[0]], n=200)
    assert np.isnan(swing_fill(t, measured, feet, H)).all()


def test_too_few_pairs_for_a_typical_cycle() -> None:
    # a standing start and one stride: too few pairs for a typical cycle, so the stride keeps
    # its own (1.2 s) and the standing start, whose own 2.5 s counts the standing, takes the
    # stride's; heel off is then span(1.2) before the landing, and the stride's is clamped to
    # its last rest frame less the lead (3.3 s)
    t, measured, feet = _walk([(0.0, 1.4, 0.0), (2.5, 3.3, 1.2), (3.7, 4.5, 2.4)], n=150)
    out = swing_fill(t, measured, feet, H)
    first_start = 2.5 - _span(1.2)
    assert first_start > 1.4 - SWING_REST_END_LEAD_S
    second_start = 3.3 - SWING_REST_END_LEAD_S
    for k_s, (start, landing, x0) in (
        (2.0, (first_start, 2.5, 0.0)),
        (3.5, (second_start, 3.7, 1.2)),
    ):
        expected = np.interp((k_s - start) / (landing - start), SWING_TAU, SWING_PROGRESS)
        np.testing.assert_allclose(
            out[int(round(k_s * FPS)), 0, 0], x0 + 1.2 * expected, atol=1e-12
        )

    with pytest.raises(ValueError, match="swing_fill"):
        swing_fill(t, measured[:, :, :2], feet, H)


def test_a_missed_rest_leaves_its_two_strides_unfilled() -> None:
    # a foot flat every 1.3 s, 0.9 m apart; the rest at 3.9 s was not seen: the 2.6 s pair
    # across it is one swing over two strides, and is not filled; the others are
    rests = [(1.3 * i, 1.3 * i + 0.6, 0.9 * i) for i in range(7) if i != 3]
    t, measured, feet = _walk(rests, n=280)
    out = swing_fill(t, measured, feet, H)
    across = (t > 2.6 + 0.6 + 1e-9) & (t < 5.2 - 1e-9)
    assert np.isnan(out[across, 0]).all()
    other = (t > 5.2 + 0.6 + 1e-9) & (t < 6.5 - 1e-9)
    assert np.isfinite(out[other, 0]).all()


@pytest.mark.parametrize("case", ["no rests", "overlapping", "never measured", "nan height"])
def test_degenerate_inputs_fill_nothing(case: str) -> None:
    t, measured, feet = _walk([(0.0, 0.6, 0.0), (1.2, 2.0, 1.2)])
    if case == "no rests":
        feet = []
    elif case == "overlapping":
        feet = [_rest("left", 0.0, 1.5, 0.0), _rest("left", 1.2, 2.0, 1.2)]
    elif case == "never measured":
        measured[:, 0] = np.nan
    else:  # x measured, the height not: not a measurement
        measured[:, 0, 2] = np.nan
    out = swing_fill(t, measured, feet, H)
    assert out.shape == measured.shape and np.isnan(out).all()


def test_seen_frames_keep_their_measurement_and_a_blip_is_filled() -> None:
    t, measured, feet = _walk([(0.0, 0.6, 0.0), (1.2, 2.0, 1.2)])
    measured[25, 0] = [0.5, 0.1, 0.05]  # seen once alone (a false detection): filled over
    measured[30:32, 0] = [0.7, 0.1, 0.08]  # seen in two frames: kept
    out = swing_fill(t, measured, feet, H)
    assert np.isfinite(out[25, 0]).all() and not np.allclose(out[25, 0], measured[25, 0])
    assert np.isnan(out[30:32, 0]).all()


@pytest.mark.parametrize(
    "rests",
    [
        [(0.0, 0.2, 0.0), (0.3, 2.0, 0.4)],  # a 0.3 s "cycle": not one stride of one foot
        [(0.0, 0.6, 0.0), (1.2, 2.0, 3.0)],  # a 3 m "stride"
        [(0.0, 0.6, 0.0), (1.2, 2.0, 0.1)],  # a 10 cm shuffle, or one stance seen as two
    ],
)
def test_implausible_landmark_pairs_are_skipped(rests) -> None:
    t, measured, feet = _walk(rests)
    assert np.isnan(swing_fill(t, measured, feet, H)).all()


def test_a_rest_without_a_measured_point_is_skipped_and_shapes_are_checked() -> None:
    t, measured, feet = _walk([(0.0, 0.6, 0.0), (1.2, 2.0, 1.2)])
    measured[: int(0.6 * FPS) + 1, 0] = np.nan
    assert np.isnan(swing_fill(t, measured, feet, H)).all()
    with pytest.raises(ValueError, match="swing_fill"):
        swing_fill(t, measured[:, :, :2], feet, H)


def test_template_shape() -> None:
    assert SWING_PROGRESS[0] == 0 and SWING_PROGRESS[-1] == 1
    assert (np.diff(SWING_PROGRESS) >= 0).all()
    assert SWING_LIFT[0] == 0 and SWING_LIFT[-1] == 0 and (SWING_LIFT >= 0).all()
    assert SWING_SIDEWAYS[0] == 0 and SWING_SIDEWAYS[-1] == 0
    assert len(SWING_TAU) == len(SWING_PROGRESS) == len(SWING_LIFT) == len(SWING_SIDEWAYS)


def _keypoint():
    """The point the committed template follows: the keypoint of ``correction.marker_offset_m``'s
    default, as ``data/derive_swing_template.py`` derives it."""
    from gaitnet.pipeline.config import KEYPOINT_OFFSET_M, REFERENCE_HEIGHT_M
    from gaitnet.sim.swing_profile import ShoePoint

    return ShoePoint.from_smpl_offset(KEYPOINT_OFFSET_M, REFERENCE_HEIGHT_M)


def test_a_shoe_point_is_a_fixed_point_of_the_foot() -> None:
    """A ShoePoint at the instep marker's place gives the generator's marker; one from an SMPL
    offset is the correction's foot point, ankle + G_ank m, on the generator's own pose; bad
    offsets are refused."""
    from gaitnet.geometry.rotation import so3_exp
    from gaitnet.pipeline.config import PipelineParams
    from gaitnet.sim.gait import GaitConfig, generate_walk
    from gaitnet.sim.subject import sample_subject
    from gaitnet.sim.swing_profile import ShoePoint

    rng = np.random.default_rng(3)
    subject = sample_subject(rng)
    walk = generate_walk(subject, GaitConfig(speed_mps=1.2, walk_length_m=4.0), rng)
    t = np.linspace(0.5, 3.0, 40)
    forward, _, up = subject.marker_in_shoe() - subject.ankle_in_shoe()
    marker = ShoePoint(forward, up, subject.height_m).points(walk, t)
    np.testing.assert_allclose(marker, walk.marker_points(t), atol=1e-12)
    # the correction's foot point on the generator's pose: ankle + G_ank · offset (SMPL axes)
    offset = (0.0, -0.019, 0.116)
    point = ShoePoint.from_smpl_offset(offset, subject.height_m).points(walk, t)
    root, _, aa = walk.smpl_pose(t)
    joints = walk.joints(t)
    for s in (0, 1):  # joint_aa: hips, knees, ankles, feet (left, right each)
        G = so3_exp(root) @ so3_exp(aa[:, s]) @ so3_exp(aa[:, 2 + s]) @ so3_exp(aa[:, 4 + s])
        np.testing.assert_allclose(point[:, s], joints[:, 5 + s] + G @ offset, atol=1e-9)
    assert PipelineParams().marker_offset_m[0] == 0  # the reported marker is sagittal too
    with pytest.raises(ValueError, match="sagittal"):
        ShoePoint.from_smpl_offset((0.01, 0.0, 0.1), 1.7)
    with pytest.raises(ValueError, match="positive height"):
        ShoePoint(0.1, 0.0, 0.0)


def test_committed_template_is_the_gait_generators() -> None:
    """A fresh derivation on fewer walks (other subjects) agrees with the committed table
    within a fraction of the swing-to-swing spread."""
    from gaitnet.sim.swing_profile import derive_swing_template

    fresh = derive_swing_template(
        SWING_TAU, speeds_mps=(0.8, 1.2, 1.6), subjects=2, seed=7, point=_keypoint()
    )
    assert fresh["swings"][0] > 40
    spread = np.maximum(fresh["progress_std"], 0.01)
    assert (np.abs(fresh["progress"] - SWING_PROGRESS) < spread).all()
    assert np.abs(fresh["lift"] - SWING_LIFT).max() < 0.005
    assert np.abs(fresh["sideways"] - SWING_SIDEWAYS).max() < 0.005  # outwards, both feet
    assert fresh["sideways"].max() > 0.01
    assert abs(fresh["fraction"][0] - 0.75) < 0.03


def test_committed_span_line_is_the_gait_generators() -> None:
    """A fresh fit on other subjects gives the committed span within a frame at a short and a
    long cycle, and the line fits the swings better than a share of the cycle does."""
    from gaitnet.sim.swing_profile import derive_swing_span

    fresh = derive_swing_span(
        SWING_TAU,
        SWING_PROGRESS,
        speeds_mps=(0.6, 0.9, 1.2, 1.5, 1.7),
        subjects=2,
        seed=7,
        point=_keypoint(),
    )
    assert fresh["swings"] > 60
    for cycle in (1.0, 1.8):
        span = fresh["offset_s"] + fresh["per_cycle"] * cycle
        assert abs(span - _line(cycle)) < 1 / 30
    assert fresh["residual_s"] < fresh["proportional_residual_s"]
    # and the line from the other foot's foot flat, which times the swings more closely
    assert fresh["contralateral_swings"] > 0.9 * fresh["swings"]
    for to_landing in (0.5, 0.9):
        span = fresh["contralateral_offset_s"] + fresh["per_contralateral"] * to_landing
        committed = SWING_SPAN_CONTRALATERAL_OFFSET_S + SWING_SPAN_PER_CONTRALATERAL * to_landing
        assert abs(span - committed) < 1 / 30
    assert fresh["contralateral_residual_s"] < 0.9 * fresh["cycle_residual_same_s"]


@pytest.mark.parametrize(
    ("key", "value", "message"),
    [
        ("swing_span_per_contralateral", "3", r"swing_span_per_contralateral must be within"),
        ("swing_span_per_contralateral", "-1", r"swing_span_per_contralateral must be within"),
        ("swing_span_contralateral_offset_s", "0.6", r"contralateral_offset_s must be within"),
        ("swing_retime_weight", "1.5", r"swing_retime_weight must be within"),
        ("swing_retime_max_shift_s", "-0.1", r"swing_retime_max_shift_s must be within"),
        ("swing_start_delay_s", "0.3", r"swing_start_delay_s must be within"),
        ("swing_start_delay_s", "-0.25", r"swing_start_delay_s must be within"),
        ("swing_rest_end_lead_s", "-0.01", r"swing_rest_end_lead_s must be within"),
        ("swing_rest_end_lead_s", "0.4", r"swing_rest_end_lead_s must be within"),
    ],
)
def test_swing_timing_keys_are_checked(key: str, value: str, message: str) -> None:
    from gaitnet.config import load_config
    from gaitnet.errors import ConfigError
    from gaitnet.pipeline.config import InferConfig

    with pytest.raises(ConfigError, match=message):
        load_config(InferConfig, None, [f"pipeline.{key}={value}"])
    off = load_config(InferConfig, None, ["pipeline.swing_span_per_contralateral=0"])
    assert off.pipeline.swing_span_per_contralateral == 0


def test_the_start_read_where_the_foot_is_seen_again() -> None:
    # the second pair of the case above: the timing line starts the swing at 2.4 − span (its
    # start delay included); the foot is seen again in late swing, on the template laid from a
    # start 40 ms later
    t, measured, feet = _walk([(0.0, 0.6, 0.0), (1.2, 1.4, 1.2), (2.4, 3.0, 2.4)], n=110)
    right = [_rest("right", 1.85, 2.6, 1.8)]
    line = 2.4 - (SWING_SPAN_CONTRALATERAL_OFFSET_S + SWING_SPAN_PER_CONTRALATERAL * 0.55)
    line += SWING_START_DELAY_S
    true_start = line + 0.04
    late = (t > 2.15) & (t < 2.4)
    rho = np.interp((t[late] - true_start) / (2.4 - true_start), SWING_TAU, SWING_PROGRESS)
    measured[late, 0] = np.c_[1.2 + 1.2 * rho, np.full(late.sum(), 0.1), np.full(late.sum(), 0.05)]
    assert ((rho > 0.5) & (rho < 0.97)).sum() >= 3 and (rho > 0.97).any()  # some are not read

    def start(**retime) -> float:
        plans = plan_swings(t, measured, feet + right, **retime)
        (second,) = [p for p in plans if p.side == 0 and not p.first]
        return second.heel_off_s

    assert start(retime_weight=0.0) == pytest.approx(line, abs=1e-12)
    assert start(retime_weight=1.0) == pytest.approx(true_start, abs=1e-9)
    assert start(retime_weight=0.5) == pytest.approx(line + 0.02, abs=1e-9)  # the default
    assert start() == pytest.approx(line + 0.02, abs=1e-9)
    assert start(retime_weight=1.0, retime_max_shift_s=0.01) == pytest.approx(line + 0.01)
    # the fill follows the start it is given
    filled = swing_fill(t, measured, feet + right, H, retime_weight=1.0)
    k = np.flatnonzero(np.isfinite(filled[:, 0, 0]) & (t > 2.0))
    expected = 1.2 + 1.2 * np.interp(
        (t[k] - true_start) / (2.4 - true_start), SWING_TAU, SWING_PROGRESS
    )
    np.testing.assert_allclose(filled[k, 0, 0], expected, atol=1e-9)
    # a foot's first pair (the step out of standing) is re-timed too: seen in its late swing
    # on a template laid from 0.62 s, 0.07 s after its rest-end bound
    (first,) = [
        p
        for p in plan_swings(t, measured, feet + right, retime_weight=1.0)
        if p.first and p.side == 0
    ]
    assert first.heel_off_s == pytest.approx(0.6 - SWING_REST_END_LEAD_S)
    late1 = (t > 1.0) & (t < 1.2)
    rho1 = np.interp((t[late1] - 0.62) / (1.2 - 0.62), SWING_TAU, SWING_PROGRESS)
    measured[late1, 0] = np.c_[1.2 * rho1, np.full(late1.sum(), 0.1), np.full(late1.sum(), 0.05)]
    assert ((rho1 > 0.5) & (rho1 < 0.97)).sum() >= 2
    (first,) = [
        p
        for p in plan_swings(t, measured, feet + right, retime_weight=1.0)
        if p.first and p.side == 0
    ]
    assert first.heel_off_s == pytest.approx(0.62, abs=1e-9)


def _third_rest_unseen(
    third_start_s: float,
) -> tuple[np.ndarray, np.ndarray, list[StanceFoot]]:
    """Four left rests (the third from ``third_start_s`` to 2.8 s at x = 2.4), each but the
    third measured 2 cm ahead of and 1 cm inside its landmark, 8 cm up; 150 frames at 30/s."""
    t = np.arange(150) / FPS
    measured = np.full((150, 2, 3), np.nan)
    rests = [(0.0, 0.6, 0.0), (1.2, 1.6, 1.2), (third_start_s, 2.8, 2.4), (3.6, 4.9, 3.6)]
    feet = []
    for i, (t0, t1, x) in enumerate(rests):
        inside = (t >= t0 - 1e-9) & (t <= t1 + 1e-9)
        if i != 2:
            measured[inside, 0] = [x + 0.02, 0.09, 0.08]
        feet.append(_rest("left", t0, t1, x))
    return t, measured, feet


def test_the_foot_rests_at_its_point_through_its_stances_unseen_frames() -> None:
    """Known answer: the frames of a stance where the segmenter lost the foot (here one frame
    of the standing start and three of a later rest) are filled with the rest's median
    measured point; a rest never seen is not placed (its frames, and the swings either side of
    it, are left to the predictor: the landmark's start, which times the landing, is late
    for such a foot)."""
    t, measured, feet = _third_rest_unseen(2.4)
    lost = [int(0.3 * FPS), int(1.3 * FPS), int(1.4 * FPS), int(1.5 * FPS)]
    measured[lost, 0] = np.nan
    out = swing_fill(t, measured, feet, H, rest_end_lead_s=0.0)
    np.testing.assert_allclose(out[lost[0], 0], [0.02, 0.09, 0.08])
    np.testing.assert_allclose(out[lost[1:], 0], np.tile([1.22, 0.09, 0.08], (3, 1)))
    third = (t >= 2.4 - 1e-9) & (t <= 2.8 + 1e-9)
    assert np.isnan(out[third, 0]).all()
    assert np.isnan(out[(t > 1.6 + 1e-9) & (t < 3.6 - 1e-9), 0]).all()
    assert np.isfinite(out[(t > 0.6 + 1e-9) & (t < 1.2 - 1e-9), 0]).all()  # a laid swing


def test_a_rest_never_seen_lands_where_its_foot_was_seen_arriving() -> None:
    """Known answer (:func:`landed_rests`): the third rest (landmark from 2.5 s at x = 2.4)
    is never measured in its own frames, but the foot was seen arriving from 0.2 s before,
    first 7 cm above its resting height (still in the air), then 3 cm above and 3.6 cm from
    where it rests: the rest begins at the first low sighting and rests at the landmark plus
    the foot's offset (2 cm forward, 1 cm in) at the other rests' height; a sighting 20 cm
    short of it, or more than the lookback before, is not the landing. Without the sightings
    the rest has no point."""
    t, measured, feet = _third_rest_unseen(2.5)
    seen = feet_steadily_seen(measured)
    plain, plain_points = landed_rests(t, measured, seen, feet)
    assert id(plain[2]) not in plain_points
    arriving = (t > 2.3 - 1e-9) & (t < 2.4)  # 2.3, 2.333, 2.367: steadily seen
    measured[arriving, 0] = [2.40, 0.12, 0.11]
    measured[int(round(2.3 * FPS)), 0, 2] = 0.15
    measured[int(round(2.15 * FPS)), 0] = [2.42, 0.09, 0.08]  # before the lookback
    measured[int(round(2.45 * FPS)), 0] = [2.20, 0.09, 0.08]  # 20 cm short
    seen = feet_steadily_seen(measured)
    rests_out, points = landed_rests(t, measured, seen, feet)
    third = rests_out[2]
    assert third.t_first_s == pytest.approx(2.3 + 1 / FPS)
    assert third.t_last_s == pytest.approx(2.8) and third.side == "left"
    np.testing.assert_allclose(points[id(third)], [2.42, 0.09, 0.08], atol=1e-12)
    for r, r0 in zip(rests_out, plain, strict=True):  # the others are as they were
        if r is not third:
            assert (r.side, r.t_first_s, r.t_last_s) == (r0.side, r0.t_first_s, r0.t_last_s)
            np.testing.assert_array_equal(points[id(r)], plain_points[id(r0)])
    out = swing_fill(t, measured, feet, H, rest_end_lead_s=0.0)
    unseen = (t > 2.4) & (t <= 2.8 + 1e-9) & ~seen[:, 0]
    np.testing.assert_allclose(out[unseen, 0], np.tile([2.42, 0.09, 0.08], (unseen.sum(), 1)))
    # the swings either side are laid now: the one before lands at the first low sighting
    assert np.isfinite(out[(t > 1.6 + 1e-9) & (t < 2.3 - 1e-9) & ~seen[:, 0], 0]).all()
    assert np.isfinite(out[(t > 2.8 + 1e-9) & (t < 3.6 - 1e-9), 0]).all()
