"""Stances laid from the camera's height dips (:mod:`gaitnet.pipeline.hidden_stances`): known
answers on a walk built from its steps, every refusal, and the strides that join them."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from gaitnet.pipeline.hidden_stances import (
    HALF_STEP_WIDTH_M,
    INFERRED_STD_M,
    LATE_S,
    WalkingLine,
    hidden_stances,
    step_dips,
    with_hidden_stances,
)
from gaitnet.vio.result import StanceFoot, VioResult

FPS = 30.0
T0 = 1.5  # standing before the first heel strike [s]
STEP_S = 0.55
STEP_M = 0.66
N_STEPS = 8
DIP_M = 0.03
DELAY_S = 0.08
HALF_WIDTH_M = 0.08
HEADING = np.radians(30.0)


def _walk(
    n_steps: int = N_STEPS,
    dip_m: float = DIP_M,
    sway_m: float = 0.0,
    step_s: float = STEP_S,
    dip_shift_s: dict[int, float] | None = None,
    walk_half_m: float = HALF_WIDTH_M,
):
    """A straight walk at 30° heading: standing 1.5 s, ``n_steps`` steps of 0.66 m every
    ``step_s`` (the first by the right foot), each heel strike at a dip of the camera's height,
    the closing step ``step_s`` after the last, standing 1.5 s. ``dip_shift_s``: the height
    made of one dip per step instead (0.08 s wide), those of the given steps moved by the
    given times. The feet stand ``HALF_WIDTH_M`` either side of the path and walk
    ``walk_half_m`` either side of it. Returns the frame times, camera
    poses, every stance's (side, heel strike time, floor point) and the walk's direction."""
    t_end = T0 + (n_steps + 1) * step_s + 1.5
    t = np.arange(0.0, t_end, 1.0 / FPS)
    u = np.array([np.cos(HEADING), np.sin(HEADING)])
    left = np.array([-u[1], u[0]])
    walking = (t >= T0 - step_s / 2) & (t <= T0 + (n_steps - 0.5) * step_s)
    progress = np.clip(t - T0 + step_s, 0.0, n_steps * step_s) * STEP_M / step_s
    T = np.tile(np.eye(4), (len(t), 1, 1))
    sway = sway_m * np.sin(np.pi * (t - T0) / step_s) * walking
    T[:, :2, 3] = progress[:, None] * u + sway[:, None] * left
    T[:, 2, 3] = 1.0 - dip_m * 0.5 * (1.0 + np.cos(2.0 * np.pi * (t - T0) / step_s)) * walking
    if dip_shift_s is not None:
        at = [T0 + k * step_s + dip_shift_s.get(k, 0.0) for k in range(n_steps)]
        T[:, 2, 3] = 1.0 - dip_m * np.exp(-0.5 * ((t[:, None] - at) / 0.08) ** 2).sum(axis=1)
    stances = [("left", 0.0, HALF_WIDTH_M * left), ("right", 0.0, -HALF_WIDTH_M * left)]
    for k in range(n_steps):
        side = "right" if k % 2 == 0 else "left"
        sign = 1.0 if side == "left" else -1.0
        stances.append((side, T0 + k * step_s, (k + 1) * STEP_M * u + sign * walk_half_m * left))
    side = "right" if n_steps % 2 == 0 else "left"  # the foot that did not take the last step
    sign = 1.0 if side == "left" else -1.0
    stances.append((side, T0 + n_steps * step_s, n_steps * STEP_M * u + sign * walk_half_m * left))
    return t, T, stances


def _landmarks(stances, skip: tuple[int, ...] = ()) -> list[StanceFoot]:
    """The filter's landmarks of ``stances`` but those numbered in ``skip`` (0, 1: standing;
    2 …: the steps), each seen from ``DELAY_S`` after its heel strike for 0.3 s (the standing
    ones from the first frame)."""
    feet = []
    for i, (side, t_hs, xy) in enumerate(stances):
        if i in skip:
            continue
        first = 0.1 if i < 2 else t_hs + DELAY_S
        last = T0 - 0.2 if i < 2 else first + 0.3
        feet.append(StanceFoot(i, side, first, last, np.array(xy), np.full(2, 0.005), 9))
    return feet


def test_the_dips_are_the_heel_strikes_and_their_prominence_key_acts() -> None:
    t, T, stances = _walk()
    dips = step_dips(t, T, 0.008)
    np.testing.assert_allclose(dips, [s[1] for s in stances[2:-1]], atol=0.5 / FPS)
    assert step_dips(t, T, 2 * DIP_M).size == 0
    standing = T.copy()
    standing[:, :2, 3] = 0.0  # the same bobbing without walking: no step
    assert step_dips(t, standing, 0.008).size == 0


def test_missed_stances_are_laid_where_the_steps_put_them() -> None:
    """Steps 2 and 5 (a right and a left stance) unseen: each is laid on its side, at its
    floor point and at its dip plus the walk's delay, with the inferred flags."""
    t, T, stances = _walk(sway_m=0.02)
    feet, note = hidden_stances(_landmarks(stances, skip=(4, 7)), t, T, 0.008, 0.6)
    laid = [f for f in feet if f.inferred]
    assert "2 hidden stances laid" in note
    assert [f.side for f in laid] == [stances[4][0], stances[7][0]] == ["right", "left"]
    for foot, (_, t_hs, xy) in zip(laid, (stances[4], stances[7]), strict=True):
        np.testing.assert_allclose(foot.xy, xy, atol=0.01)
        assert foot.t_first_s == pytest.approx(t_hs + DELAY_S, abs=0.5 / FPS)
        assert foot.t_last_s - foot.t_first_s == pytest.approx(0.3)
        assert foot.inferred and foot.n_observations == 0 and foot.landmark_id < 0
        np.testing.assert_allclose(foot.std_xy, INFERRED_STD_M)


def test_the_closing_steps_neighbour_rests_beside_it() -> None:
    """The last dip's stance unseen: between the step before and the closing foot it lies
    level with the closing foot, not a step short of it."""
    t, T, stances = _walk()
    last = len(stances) - 2
    feet, _ = hidden_stances(_landmarks(stances, skip=(last,)), t, T, 0.008, 0.6)
    laid = [f for f in feet if f.inferred]
    assert len(laid) == 1
    np.testing.assert_allclose(laid[0].xy, stances[last][2], atol=0.01)


@pytest.mark.parametrize("seen_steps", [(1, 3, 5, 7), ()])
def test_a_foot_never_seen_walking_takes_its_width_from_the_other_or_a_typical_step(
    seen_steps: tuple[int, ...],
) -> None:
    """Feet standing 16 cm apart and walking 8 cm apart (the typical step width of
    :data:`HALF_STEP_WIDTH_M`). The right foot never seen walking: its laid stances mirror
    the left's walking offset about the middle of the feet; no foot seen walking (only the
    standing, the last and the closing stances): they lie half a typical step either side."""
    t, T, stances = _walk(walk_half_m=HALF_STEP_WIDTH_M)
    n = len(stances)
    keep = {0, 1, n - 2, n - 1, *(2 + k for k in seen_steps)}
    feet, _ = hidden_stances(
        _landmarks(stances, skip=tuple(set(range(n)) - keep)), t, T, 0.008, 0.6
    )
    laid = {f.landmark_id: f for f in feet if f.inferred}
    assert len(laid) == N_STEPS - len({*seen_steps, N_STEPS - 1})
    for landmark_id, foot in laid.items():  # step k = -1 - id, stance 2 + k
        np.testing.assert_allclose(foot.xy, stances[1 - landmark_id][2], atol=0.01)


def test_a_walk_whose_every_step_is_seen_gets_nothing() -> None:
    t, T, stances = _walk()
    feet, note = hidden_stances(_landmarks(stances), t, T, 0.008, 0.6)
    laid = [f for f in feet if f.inferred]
    assert laid == [] and f"{N_STEPS} step dips, 0 hidden" in note


@pytest.mark.parametrize(("late_s", "retimed"), [(LATE_S + 0.1, True), (LATE_S - 0.05, False)])
def test_a_stance_first_seen_late_starts_at_its_dip(late_s: float, retimed: bool) -> None:
    """Step 3's landmark first seen ``late_s`` after the walk's delay: beyond
    :data:`LATE_S` it starts at its dip plus the delay, keeping everything else; within it,
    it is left as seen (``late_s`` either side of it). Every landmark stays, in time order."""
    t, T, stances = _walk()
    seen = _landmarks(stances)
    late = replace(seen[5], t_first_s=seen[5].t_first_s + late_s)
    feet, note = hidden_stances([*seen[:5], late, *seen[6:]], t, T, 0.008, 0.6)
    assert len(feet) == len(seen) and not any(f.inferred for f in feet)
    assert [f.t_first_s for f in feet] == sorted(f.t_first_s for f in feet)
    out = next(f for f in feet if f.landmark_id == 5)
    expected = stances[5][1] + DELAY_S if retimed else late.t_first_s
    assert out.t_first_s == pytest.approx(expected, abs=1.0 / FPS)  # the dips lie on frames
    assert (out.t_last_s, out.xy.tolist()) == (late.t_last_s, late.xy.tolist())
    assert f"{int(retimed)} seen late re-timed" in note


def test_a_dip_out_of_the_rhythm_times_no_late_stance() -> None:
    """Step 1's dip 0.15 s early (its intervals 0.73 and 1.27 of the rhythm, as in a real
    gait initiation): step 1's landmark 0.25 s past it plus the delay stays as seen; step 5's,
    as late past a dip in the rhythm, is re-timed."""
    t, T, stances = _walk(dip_shift_s={1: -0.15})
    seen = _landmarks(stances)
    late = {3: LATE_S + 0.1 - 0.15, 7: LATE_S + 0.1}  # landmark ids of steps 1 and 5
    feet = [replace(f, t_first_s=f.t_first_s + late.get(f.landmark_id, 0.0)) for f in seen]
    out, note = hidden_stances(feet, t, T, 0.008, 0.6)
    first = {f.landmark_id: f.t_first_s for f in out}
    assert first[3] == pytest.approx(seen[3].t_first_s + late[3])
    assert first[7] == pytest.approx(stances[7][1] + DELAY_S, abs=1.0 / FPS)
    assert "1 seen late re-timed" in note


def test_unseen_stances_at_the_ends_are_not_laid() -> None:
    """A step with no seen stance after it (the last walking steps and the closing one
    unseen) has nothing to lie between: it is left out."""
    t, T, stances = _walk()
    n = len(stances)
    feet, _ = hidden_stances(_landmarks(stances, skip=(n - 2, n - 1)), t, T, 0.008, 0.6)
    laid = [f for f in feet if f.inferred]
    assert laid == []


def _with(feet: list[StanceFoot], i: int, **changes) -> list[StanceFoot]:
    return [replace(f, **changes) if f.landmark_id == i else f for f in feet]


@pytest.mark.parametrize(
    ("change", "reason"),
    [
        ({"side": "left"}, "break the alternation"),  # step 2 (right) labelled left
        ({"t_first_s": T0 + 2 * 0.8 + 0.5}, "1 hidden"),  # between two dips 0.8 s apart
        ({"t_first_s": T0 + 4 * 0.8 + DELAY_S}, "1 hidden"),  # two landmarks on step 4
    ],
)
def test_a_gap_whose_landmarks_do_not_fit_the_dips_is_left(change: dict, reason: str) -> None:
    """Step 3 unseen between steps 2 and 4: nothing is laid there when step 2's landmark
    has the wrong side, lies on no step, or shares step 4 with step 4's own; step 7, unseen
    between steps 6 and 8 that fit, is laid all the same."""
    t, T, stances = _walk(step_s=0.8, n_steps=10)
    feet = _with(_landmarks(stances, skip=(5, 9)), 4, **change)
    feet, note = hidden_stances(feet, t, T, 0.008, 0.6)
    laid = [f for f in feet if f.inferred]
    assert reason in note
    assert [f.t_first_s for f in laid] == pytest.approx([T0 + 7 * 0.8 + DELAY_S], abs=0.02)


def test_the_walking_line_measures_along_and_across() -> None:
    t, T, _ = _walk()
    line = WalkingLine.of(t, T, 0.6)
    u = np.array([np.cos(HEADING), np.sin(HEADING)])
    left = np.array([-u[1], u[0]])
    p = 2.0 * u + 0.1 * left
    along, across = line.along_across(p, 3.0)
    assert along == pytest.approx(2.0, abs=1e-6) and across == pytest.approx(0.1, abs=1e-6)
    np.testing.assert_allclose(line.point(along, across), p, atol=1e-6)
    np.testing.assert_allclose(line.u[0], u, atol=1e-9)  # standing: the walk's heading


def test_strides_through_a_laid_stance_say_so() -> None:
    t, T, stances = _walk()
    feet = _landmarks(stances, skip=(4,))
    vio = VioResult(t, T, T, T, None, T, feet, [], "gravity_floor", "")
    out = with_hidden_stances(vio, 0.008, 0.6, (2.5, 1.2))
    assert len(out.stance_feet) == len(feet) + 1
    rights = sorted((s for s in out.strides if s.side == "right"), key=lambda s: s.index)
    assert [s.row()["inferred"] for s in rights] == ["false", "true", "true", "false", "false"]
    points = [xy for side, _, xy in stances if side == "right"]  # standing, 0, 2, 4, 6, closing
    truth = [np.linalg.norm(b - a) for a, b in zip(points, points[1:], strict=False)]
    np.testing.assert_allclose([s.length_m for s in rights], truth, atol=0.01)
    seen = replace(vio, stance_feet=_landmarks(stances))
    assert with_hidden_stances(seen, 0.008, 0.6, (2.5, 1.2)) is seen


def test_stances_that_would_start_together_are_dropped_with_a_warning(caplog) -> None:
    """A laid stance starting with a landmark of its foot (which the dips cannot give, but a
    stand-in can) leaves the filter's result as it was, with a warning, not an error."""
    import gaitnet.pipeline.hidden_stances as module

    t, T, stances = _walk()
    feet = _landmarks(stances, skip=(4,))
    clash = replace(feet[2], landmark_id=-3, inferred=True, xy=feet[2].xy + 0.5)  # same foot
    vio = VioResult(t, T, T, T, None, T, feet, [], "gravity_floor", "")
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(module, "hidden_stances", lambda *a: ([*feet, clash], "stand-in"))
        assert with_hidden_stances(vio, 0.008, 0.6, (2.5, 1.2)) is vio
    assert "dropped" in caplog.text


@pytest.mark.parametrize("seed", range(5))
def test_the_dip_finder_agrees_with_scipy(seed: int) -> None:
    """The minima and prominences of :func:`_prominent_minima` (written out so that ``gaitnet
    infer`` never imports ``scipy.signal``) are ``scipy.signal.find_peaks`` on the negated
    signal, plateaus included; the distance rule keeps the deepest of close minima."""
    from scipy.signal import find_peaks

    from gaitnet.pipeline.hidden_stances import _prominent_minima

    rng = np.random.default_rng(seed)
    z = np.round(np.cumsum(rng.normal(size=400)), 1)  # rounding makes flat stretches
    for prominence in (0.5, 2.0, 5.0):
        expected, _ = find_peaks(-z, prominence=prominence)
        np.testing.assert_array_equal(_prominent_minima(z, prominence, 1), expected)
    wide = _prominent_minima(z, 2.0, 25)
    assert (np.diff(wide) >= 25).all()
    for k in set(find_peaks(-z, prominence=2.0)[0]) - set(wide):  # dropped for a deeper one
        assert any(abs(k - m) < 25 and z[m] <= z[k] for m in wide)
