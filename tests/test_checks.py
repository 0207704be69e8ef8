"""The value checks every config type uses (gaitnet/checks.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gaitnet.checks import check_each, check_int_range, check_positive, check_range


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf, True, "1", None, [1.0]])
def test_non_numbers_and_non_finite_values_are_refused(bad: object) -> None:
    with pytest.raises(ValueError, match="^speed must be a"):
        check_range("speed", bad)
    with pytest.raises(ValueError, match="^speed must be a"):
        check_positive("speed", bad)


def test_bounds_are_inclusive_and_values_come_back_plain() -> None:
    assert check_range("x", np.float32(0.5), 0.5, 1.0) == 0.5
    assert type(check_range("x", np.float32(0.5), 0.5, 1.0)) is float
    assert check_range("x", 1, 0.5, 1.0) == 1.0
    with pytest.raises(ValueError, match=r"^x must be within \[0.5, 1\] m, got 1.5$"):
        check_range("x", 1.5, 0.5, 1.0, " m")
    with pytest.raises(ValueError, match="^x must be at least 0, got -1"):
        check_range("x", -1, 0.0)
    with pytest.raises(ValueError, match="^x must be positive"):
        check_positive("x", 0.0)
    assert check_positive("x", 1e-300) == 1e-300


def test_numbers_too_large_to_compute_with_are_refused() -> None:
    """1e308 is finite, but its square is not: a noise density or standard deviation that
    large raised OverflowError inside the filter. Beyond 1e30 every check refuses it."""
    for bad in (1e308, -1e31, np.float64(2e30)):
        with pytest.raises(ValueError, match="^speed must be a number of magnitude at most 1e30"):
            check_range("speed", bad)
        with pytest.raises(ValueError, match="^speed must be a number of magnitude at most 1e30"):
            check_positive("speed", abs(bad))
    assert check_positive("speed", 1e30) == 1e30


def test_integers() -> None:
    assert check_int_range("n", np.int64(3), 1, 5) == 3
    assert type(check_int_range("n", np.int64(3), 1, 5)) is int
    assert check_int_range("n", 10**30, 0) == 10**30  # no upper bound given
    for bad in (2.0, True, "3", None):
        with pytest.raises(ValueError, match="^n must be an integer, got"):
            check_int_range("n", bad, 1, 5)
    with pytest.raises(ValueError, match=r"^n must be an integer within \[1, 5\], got 6$"):
        check_int_range("n", 6, 1, 5)
    with pytest.raises(ValueError, match="^n must be an integer of at least 1, got 0$"):
        check_int_range("n", 0, 1)


def test_each_element_is_named() -> None:
    check_each("band", (0.6, 1.0), 0.5, 2.0)
    with pytest.raises(ValueError, match=r"^band\[1\] must be a finite number"):
        check_each("band", (0.6, math.nan), 0.5, 2.0)
