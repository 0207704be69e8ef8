"""A measured foot at the other foot's rest is the other foot (gaitnet.pipeline.foot_sides)."""

from __future__ import annotations

import numpy as np

from gaitnet.pipeline.foot_sides import (
    OTHER_FOOT_MARGIN_S,
    OTHER_FOOT_RADIUS_M,
    UNMEASURED_REST_HEIGHT_M,
    reside_measured_feet,
)
from gaitnet.vio.result import StanceFoot

FPS = 30.0


def _rest(side: str, t0: float, t1: float, x: float, y: float) -> StanceFoot:
    return StanceFoot(0, side, t0, t1, np.array([x, y]), np.full(2, 0.01), 10)


def _scene() -> tuple[np.ndarray, np.ndarray, list[StanceFoot]]:
    """Left foot resting at x = 0 then 1.2 (y = +0.1), right at 0.6 and 1.8 (y = −0.1), each
    measured at its rest 8 cm above the floor; swings not measured."""
    t = np.arange(90) / FPS
    measured = np.full((90, 2, 3), np.nan)
    feet = []
    for side, s, y, rests in (
        ("left", 0, 0.1, [(0.0, 0.5, 0.0), (1.2, 1.7, 1.2)]),
        ("right", 1, -0.1, [(0.6, 1.1, 0.6), (1.8, 2.9, 1.8)]),
    ):
        for t0, t1, x in rests:
            inside = (t >= t0 - 1e-9) & (t <= t1 + 1e-9)
            measured[inside, s] = [x, y, 0.08]
            feet.append(_rest(side, t0, t1, x, y))
    return t, measured, feet


def test_a_point_at_the_other_foots_rest_moves_to_it_or_is_dropped() -> None:
    """Known answer: the left foot resting at x = 1.2 measured as the right foot just before
    its landmark begins (within the margin, the landing) moves to the left where the left has
    no point, and is dropped where it has one; the right foot's own points stay."""
    t, measured, feet = _scene()
    k_free, k_both = int(1.1 * FPS), int(1.15 * FPS)  # within the margin before 1.2 s
    assert 1.2 - OTHER_FOOT_MARGIN_S < t[k_free] < t[k_both] < 1.2
    wrong = np.array([1.2 + 0.01, 0.1, 0.08 + 0.01])
    measured[k_free, 1] = wrong
    measured[k_both, 1] = wrong
    measured[k_both, 0] = [1.25, 0.1, 0.09]
    out, changed = reside_measured_feet(t, measured, feet)
    assert changed == 2
    np.testing.assert_allclose(out[k_free, 0], wrong)
    assert np.isnan(out[k_free, 1]).all() and np.isnan(out[k_both, 1]).all()
    np.testing.assert_allclose(out[k_both, 0], [1.25, 0.1, 0.09])
    keep = np.ones(len(t), bool)
    keep[[k_free, k_both]] = False
    np.testing.assert_array_equal(out[keep], measured[keep])


def test_points_apart_or_outside_the_rest_stay() -> None:
    """A right-foot point a step width from the left's rest, or at the left's rest point
    long after that rest ended, is left as measured (and the input is not modified)."""
    t, measured, feet = _scene()
    k_beside = int(1.3 * FPS)  # the right foot passing the resting left, 12 cm to the side
    measured[k_beside, 1] = [1.2, 0.1 - 0.12, 0.12]
    assert np.linalg.norm(measured[k_beside, 1] - [1.2, 0.1, 0.08]) > OTHER_FOOT_RADIUS_M
    k_late = int(0.5 * FPS) + int(np.ceil((OTHER_FOOT_MARGIN_S + 0.05) * FPS))
    measured[k_late, 1] = [0.0, 0.1, 0.08]  # where the left rested until 0.5 s
    before = measured.copy()
    out, changed = reside_measured_feet(t, measured, feet)
    assert changed == 0
    np.testing.assert_array_equal(out, before)
    np.testing.assert_array_equal(measured, before)


def test_a_point_at_a_rest_never_measured_goes_to_that_foot() -> None:
    """Known answer: the right foot's rest at x = 1.8 was never measured (a stance laid from
    the step rhythm). A point measured as the left foot there while the right rests goes to
    the right foot, compared along the floor with the right's landmark moved by its measured
    rests' offset (here 2 cm forward) at the measured rests' height; one as far off but 10 cm
    higher than that height, or 8 cm to the side, stays the left foot's."""
    t, measured, feet = _scene()
    second_right = int(1.8 * FPS)
    measured[second_right:, 1] = np.nan  # the right foot's second rest is never seen
    measured[int(0.6 * FPS) : int(1.1 * FPS) + 1, 1, 0] += 0.02  # first rest: 2 cm forward
    k_at, k_high, k_beside = int(2.0 * FPS), int(2.1 * FPS), int(2.2 * FPS)
    at_rest = np.array([1.8 + 0.02 + 0.03, -0.1, 0.08 + 0.02])
    measured[k_at, 0] = at_rest
    measured[k_high, 0] = [1.82, -0.1, 0.08 + UNMEASURED_REST_HEIGHT_M + 0.02]
    measured[k_beside, 0] = [1.82, -0.1 + 0.08, 0.08]
    before = measured.copy()
    out, changed = reside_measured_feet(t, measured, feet)
    assert changed == 1
    np.testing.assert_allclose(out[k_at, 1], at_rest)
    assert np.isnan(out[k_at, 0]).all()
    keep = np.ones(len(t), bool)
    keep[k_at] = False
    np.testing.assert_array_equal(out[keep], before[keep])


def test_without_any_measured_rest_nothing_is_resided() -> None:
    """No rest of either foot measured: no height to compare with, nothing moves."""
    t, measured, feet = _scene()
    swing = np.full_like(measured, np.nan)
    swing[int(1.9 * FPS), 0] = [1.8, -0.1, 0.08]
    out, changed = reside_measured_feet(t, swing, feet)
    assert changed == 0
    np.testing.assert_array_equal(out, swing)
