"""Gait parameters from stance landmarks (gaitnet/vio/gait.py): known answers on a scripted walk."""

from __future__ import annotations

import numpy as np
import pytest

from gaitnet.vio.gait import STRIDE_COLUMNS, Stance, strides_from_stances, summarise


def _walk(step_m: float = 0.6, width_m: float = 0.16, step_time_s: float = 0.55, n: int = 8):
    """Standing stances at t = 0, then alternating steps along +x (right foot first)."""
    stances = [
        Stance("left", 0.0, 1.5, np.array([0.0, width_m / 2])),
        Stance("right", 0.0, 1.6, np.array([0.0, -width_m / 2])),
    ]
    for k in range(1, n + 1):
        side = "right" if k % 2 else "left"
        y = -width_m / 2 if side == "right" else width_m / 2
        t = 2.0 + (k - 1) * step_time_s
        stances.append(Stance(side, t, t + 0.3, np.array([k * step_m, y])))
    return stances


def test_steady_strides_have_the_scripted_lengths_times_and_steps() -> None:
    strides = strides_from_stances(_walk())
    steady = [s for s in strides if s.steady]
    assert len(strides) == 8 and len(steady) == 6  # the first stride of each foot is initiation
    for s in steady:
        assert s.length_m == pytest.approx(1.2)
        assert s.time_s == pytest.approx(1.1)
        assert s.step_length_m == pytest.approx(0.6)
        assert s.step_width_m == pytest.approx(0.16)
        assert s.step_time_s == pytest.approx(0.55)
        assert s.cadence_spm == pytest.approx(120 / 1.1)
        assert s.speed_mps == pytest.approx(1.2 / 1.1)
    first_right = next(s for s in strides if s.side == "right")
    assert not first_right.steady and first_right.length_m == pytest.approx(0.6)
    assert set(first_right.row()) == set(STRIDE_COLUMNS)


def test_step_direction_follows_the_stride_not_the_world_axes() -> None:
    R = np.array([[np.cos(0.7), -np.sin(0.7)], [np.sin(0.7), np.cos(0.7)]])
    rotated = [Stance(s.side, s.t_first_s, s.t_last_s, R @ s.xy + [3.0, -2.0]) for s in _walk()]
    for a, b in zip(strides_from_stances(_walk()), strides_from_stances(rotated), strict=True):
        assert b.length_m == pytest.approx(a.length_m)
        if a.steady:
            assert b.step_length_m == pytest.approx(a.step_length_m)
            assert b.step_width_m == pytest.approx(a.step_width_m)


def test_summary_means_and_robinson_index() -> None:
    stances = _walk()
    stances = [  # the right foot lands 5 cm further ahead: right steps longer, left shorter
        Stance(
            s.side,
            s.t_first_s,
            s.t_last_s,
            s.xy + ([0.05, 0] if s.side == "right" and s.t_first_s > 1 else 0),
        )
        for s in stances
    ]
    summary = summarise(strides_from_stances(stances))
    assert summary["right"]["n_strides"] == 3 and summary["left"]["n_strides"] == 3
    assert summary["right"]["step_length_m"]["mean"] == pytest.approx(0.65)
    assert summary["left"]["step_length_m"]["mean"] == pytest.approx(0.55)
    assert summary["robinson_symmetry_index_pct"]["step_length_m"] == pytest.approx(200 * 0.1 / 1.2)
    assert summary["left"]["stride_length_m"]["std"] == pytest.approx(0.0, abs=1e-12)


def test_a_single_stance_per_side_gives_no_strides_and_empty_statistics() -> None:
    strides = strides_from_stances(_walk(n=0))
    assert strides == []
    assert summarise(strides)["left"]["stride_length_m"] == {}


def test_two_stances_of_one_side_at_the_same_time_are_refused() -> None:
    s = Stance("left", 1.0, 1.2, np.zeros(2))
    with pytest.raises(ValueError, match="same time"):
        strides_from_stances([s, Stance("left", 1.0, 1.3, np.ones(2))])


def test_the_steadiness_limits_act() -> None:
    # standing stances count once stances may last 2 s, except the left one's 2.55 s stride
    assert sum(s.steady for s in strides_from_stances(_walk(), max_stance_time_s=2.0)) == 7
    assert sum(s.steady for s in strides_from_stances(_walk(), 3.0, 2.0)) == 8
    assert sum(s.steady for s in strides_from_stances(_walk(), max_stride_time_s=1.0)) == 0


def _split(stance: Stance, gap_s: float, shift: np.ndarray) -> list[Stance]:
    """``stance`` reported as two: observations stop at a third of it, and resume ``gap_s``
    later at a point moved by ``shift`` (a pose jump or a detector jump)."""
    t_cut = stance.t_first_s + (stance.t_last_s - stance.t_first_s) / 3
    return [
        Stance(stance.side, stance.t_first_s, t_cut, stance.xy),
        Stance(stance.side, t_cut + gap_s, stance.t_last_s, stance.xy + shift),
    ]


@pytest.mark.parametrize(
    "gap_s, shift",
    [
        (0.1, [0.006, 0.0]),  # a pose jump between two frames (the end sheet's tag update)
        (-0.1, [-0.06, 0.01]),  # two overlapping stances 6 cm apart (a detector jump)
    ],
)
def test_one_foot_reported_as_two_stances_is_one_stance(gap_s: float, shift: list) -> None:
    walk = _walk()
    expected = strides_from_stances(walk)
    for k in (4, len(walk) - 1):  # a stance in the walk, the last one
        stances = walk[:k] + _split(walk[k], gap_s, np.array(shift)) + walk[k + 1 :]
        strides = strides_from_stances(stances)
        assert len(strides) == len(expected)  # without the merge: one stride of ~0 m more
        for a, b in zip(strides, expected, strict=True):
            assert (a.side, a.start.t_first_s, a.end.t_first_s) == (
                b.side,
                b.start.t_first_s,
                b.end.t_first_s,
            )
            assert a.length_m == pytest.approx(b.length_m, abs=0.061)
            assert a.steady == b.steady


def test_a_foot_set_down_again_after_a_swing_is_a_new_stance() -> None:
    walk = _walk()
    k = len(walk) - 1
    # lifted for 0.3 s (longer than min_swing_time_s) and put down at the same place: a stride
    stepped = walk[:k] + _split(walk[k], 0.3, np.zeros(2)) + walk[k + 1 :]
    assert len(strides_from_stances(stepped)) == len(strides_from_stances(walk)) + 1
    assert len(strides_from_stances(stepped, min_swing_time_s=0.4)) == len(walk) - 2
    # 0.1 s apart but 9 cm away: not one foot at one place (same_place_m)
    jumped = walk[:k] + _split(walk[k], 0.1, np.array([0.09, 0.0])) + walk[k + 1 :]
    assert len(strides_from_stances(jumped)) == len(strides_from_stances(walk)) + 1
    assert len(strides_from_stances(jumped, same_place_m=0.1)) == len(walk) - 2
