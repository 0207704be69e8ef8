"""Gait parameters (gaitnet/pipeline/gait_parameters.py): known answers from hand-made
stances and events, agreement with gaitnet.vio.gait.summarise, the CSV table, bad input."""

from __future__ import annotations

import csv
import io

import numpy as np
import pytest

from gaitnet.errors import InputError
from gaitnet.pipeline.gait_events import FootContact
from gaitnet.pipeline.gait_parameters import (
    KEYS,
    STRIDE_TABLE_COLUMNS,
    robinson_index_pct,
    stride_parameters,
    stride_table_csv,
    summarise,
    table_cycles,
)
from gaitnet.vio.gait import Stance, strides_from_stances
from gaitnet.vio.gait import summarise as vio_summarise

CYCLE = 1.1  # s; stance 0.66 (60 %), swing 0.44; right half a cycle after left
STANCE = 0.66


def hand_walk(right_x_offset: float = 0.6, n: int = 5):
    """Left lands at x = 0, 1.2, 2.4, ... at t = 1.1 k; right at x = offset + 1.2 k at
    t = 0.55 + 1.1 k. Foot flat (the filter's stance) from IC + 0.1 s to TO − 0.2 s."""
    stances, contacts = [], []
    for k in range(n):
        for side, t0, x, y in (
            ("left", CYCLE * k, 1.2 * k, 0.1),
            ("right", CYCLE * k + CYCLE / 2, 1.2 * k + right_x_offset, -0.1),
        ):
            ic, to = t0, t0 + STANCE
            stances.append(Stance(side, ic + 0.1, to - 0.2, np.array([x, y])))
            pos = np.array([x, y, 0.07])
            contacts.append(FootContact(side, ic, to, ic + 0.1, to - 0.2, pos))
    return stances, contacts


def test_known_answers_of_a_symmetric_walk() -> None:
    stances, contacts = hand_walk()
    rows = stride_parameters(strides_from_stances(stances), contacts)
    assert len(rows) == 8
    expected = {
        "stride_length_m": 1.2,
        "stride_time_s": 1.1,
        "step_length_m": 0.6,
        "step_width_m": 0.2,
        "step_time_s": 0.55,
        "cadence_spm": 120 / 1.1,
        "walking_speed_mps": 1.2 / 1.1,
        "stance_time_s": 0.66,
        "swing_time_s": 0.44,
        "stance_pct": 60.0,
        "swing_pct": 40.0,
        # the other foot's TO 0.55 + 0.66 − 1.1 = 0.11 s after IC; its IC 0.55 s after IC,
        # 0.11 s before TO: 10 % of the cycle each
        "initial_double_support_pct": 10.0,
        "terminal_double_support_pct": 10.0,
        "double_support_pct": 20.0,
    }
    for r in rows:
        if r.side == "left" and r.index == 0:
            # left's first stance: the right foot has no stance before t = 0
            assert r.values["initial_double_support_pct"] is None
            assert r.values["terminal_double_support_pct"] == pytest.approx(10.0)
            continue
        for key, value in expected.items():
            assert r.values[key] == pytest.approx(value), (r.side, r.index, key)
    summary = summarise(rows)
    assert summary["left"]["n_strides"] == 4 and summary["right"]["n_strides"] == 4
    assert summary["left"]["stance_pct"] == {
        "mean": pytest.approx(60.0),
        "sd": pytest.approx(0.0),
        "n": 4,
    }
    assert summary["left"]["initial_double_support_pct"]["n"] == 3
    assert all(abs(v) < 1e-9 for v in summary["symmetry_index_pct"].values())


def test_robinson_index_of_unequal_steps() -> None:
    """Right lands 0.7 m ahead of the left foot, left 0.5 m ahead of the right foot:
    SI of the step length = 200 (0.7 − 0.5) / (0.7 + 0.5) = 33.3 %; strides are equal."""
    stances, contacts = hand_walk(right_x_offset=0.7)
    summary = summarise(stride_parameters(strides_from_stances(stances), contacts))
    assert summary["left"]["step_length_m"]["mean"] == pytest.approx(0.5)
    assert summary["right"]["step_length_m"]["mean"] == pytest.approx(0.7)
    assert summary["symmetry_index_pct"]["step_length_m"] == pytest.approx(200 * 0.2 / 1.2)
    assert summary["symmetry_index_pct"]["stride_length_m"] == pytest.approx(0.0)
    assert robinson_index_pct(1.0, 3.0) == pytest.approx(100.0)
    assert robinson_index_pct(0.0, 0.0) is None


def test_agrees_with_the_filter_summary() -> None:
    """Means and SDs of the shared keys equal gaitnet.vio.gait.summarise's (an independent
    computation) on jittered stances, and the Robinson index of the stride length too."""
    rng = np.random.default_rng(3)
    stances, contacts = hand_walk(n=7)
    stances = [
        Stance(s.side, s.t_first_s + rng.normal(0, 0.02), s.t_last_s, s.xy + rng.normal(0, 0.03, 2))
        for s in stances
    ]
    strides = strides_from_stances(stances)
    mine = summarise(stride_parameters(strides, contacts))
    theirs = vio_summarise(strides)
    for side in ("left", "right"):
        for key in ("stride_length_m", "step_width_m", "cadence_spm", "walking_speed_mps"):
            assert mine[side][key]["mean"] == pytest.approx(theirs[side][key]["mean"])
            assert mine[side][key]["sd"] == pytest.approx(theirs[side][key]["std"])
    assert mine["symmetry_index_pct"]["stride_length_m"] == pytest.approx(
        theirs["robinson_symmetry_index_pct"]["stride_length_m"]
    )


def test_missing_events_leave_empty_cells_and_csv() -> None:
    """Without a toe off the phases are None (empty cells), the distances stay; the CSV has
    the columns and one row per stride."""
    stances, contacts = hand_walk(n=3)
    contacts = [
        FootContact(c.side, c.initial_contact_s, None, c.still_start_s, c.still_end_s, c.position)
        if c.side == "left"
        else c
        for c in contacts
    ]
    rows = stride_parameters(strides_from_stances(stances), contacts)
    left = [r for r in rows if r.side == "left"]
    assert all(r.values["stance_pct"] is None for r in left)
    assert all(r.values["stride_length_m"] == pytest.approx(1.2) for r in left)
    table = list(csv.DictReader(io.StringIO(stride_table_csv(rows))))
    assert tuple(table[0]) == STRIDE_TABLE_COLUMNS and len(table) == len(rows)
    assert {t["stance_pct"] for t in table if t["side"] == "left"} == {""}
    assert set(KEYS) <= set(table[0])


def test_table_cycles_are_the_strides_with_stance_and_swing() -> None:
    """Known answer: the joint-angle figure's cycles are the table's (stance_pct n): every
    steady stride of the hand walk as (IC, TO, next IC); without the left toe offs, none on
    the left and the right's unchanged."""
    stances, contacts = hand_walk(n=3)
    rows = stride_parameters(strides_from_stances(stances), contacts)
    cycles = table_cycles(rows)
    summary = summarise(rows)
    for side, t0 in (("left", 0.0), ("right", CYCLE / 2)):
        assert len(cycles[side]) == summary[side]["stance_pct"]["n"] == 2
        for k, (ic, to, nxt) in enumerate(cycles[side]):
            assert (ic, to, nxt) == pytest.approx((t0 + CYCLE * k, t0 + CYCLE * k + STANCE,
                                                   t0 + CYCLE * (k + 1)))  # fmt: skip
    no_left_to = [
        FootContact(c.side, c.initial_contact_s, None, c.still_start_s, c.still_end_s, c.position)
        if c.side == "left"
        else c
        for c in contacts
    ]
    cycles = table_cycles(stride_parameters(strides_from_stances(stances), no_left_to))
    assert cycles["left"] == [] and len(cycles["right"]) == 2


def test_contacts_far_from_the_stances_are_not_used() -> None:
    stances, contacts = hand_walk(n=3)
    shifted = [
        FootContact(
            c.side,
            c.initial_contact_s,
            c.toe_off_s,
            c.still_start_s + 5.0,
            c.still_end_s + 5.0,
            c.position,
        )
        for c in contacts
    ]
    rows = stride_parameters(strides_from_stances(stances), shifted)
    assert all(r.values["stance_time_s"] is None for r in rows)
    with pytest.raises(InputError, match="tolerance_s"):
        stride_parameters([], contacts, tolerance_s=-1.0)
