"""Whether the filter's landmarks show a missed stance (gaitnet.pipeline.stance_gaps)."""

from __future__ import annotations

import numpy as np

from gaitnet.pipeline.stance_gaps import stance_missed
from gaitnet.vio.result import StanceFoot


def _foot(side: str, t0: float, t1: float, x: float) -> StanceFoot:
    y = 0.08 if side == "left" else -0.08
    return StanceFoot(0, side, t0, t1, np.array([x, y]), np.full(2, 0.01), 10)


def _walk() -> list[StanceFoot]:
    """Standing together (the right foot leaves first), five walking stances 0.55 s apart
    (cycle 1.1 s), standing together at the end."""
    return [
        _foot("left", 0.1, 1.8, 0.0),
        _foot("right", 0.1, 1.6, 0.0),
        _foot("right", 2.2, 2.6, 0.7),
        _foot("left", 2.75, 3.15, 1.4),
        _foot("right", 3.3, 3.7, 2.1),
        _foot("left", 3.85, 4.25, 2.8),
        _foot("right", 4.4, 6.0, 3.5),
        _foot("left", 4.95, 6.0, 3.5),
    ]


def test_a_whole_walk_misses_nothing_in_any_order() -> None:
    """Known answer: alternating feet with steady cycles; the standing pair at the start is
    ordered by which foot left first, whatever order the landmarks come in."""
    walk = _walk()
    assert not stance_missed(walk)
    assert not stance_missed(walk[::-1])
    assert not stance_missed([walk[1], walk[0], *walk[2:]])


def test_a_missed_stance_of_the_other_foot_or_the_same() -> None:
    """Dropping any walking landmark leaves two of one foot in a row (or a doubled cycle)."""
    walk = _walk()
    for k in range(2, 6):
        assert stance_missed(walk[:k] + walk[k + 1 :]), k


def test_a_foot_whose_cycle_doubles_misses_one_even_when_sides_alternate() -> None:
    """Known answer: the left foot's stride from 2.75 to 5.05 s (2.3 s, over 1.5 typical
    cycles of 1.1 s) spans a missed left stance although the sides alternate."""
    walk = [
        *_walk()[:6],
        _foot("right", 4.4, 4.8, 3.5),
        _foot("left", 6.15, 6.5, 4.9),
        _foot("right", 6.6, 8.0, 5.2),
    ]
    assert not stance_missed(walk[:7])
    assert stance_missed(walk)


def test_too_few_walking_stances_to_judge() -> None:
    """Standing alone, or one step, cannot show that nothing was missed."""
    walk = _walk()
    assert stance_missed(walk[:2])
    assert stance_missed(walk[:3])
    assert stance_missed([])
