"""Value checks for the ``__post_init__`` of every typed config and file schema.

Each check raises ``ValueError`` with a one-line message naming the key;
:func:`gaitnet.config.load_config` and :func:`gaitnet.config.parse_config` turn it into a
:class:`~gaitnet.errors.ConfigError` naming the file and the section (session readers into a
:class:`~gaitnet.errors.SessionError`). Every check refuses NaN, infinities and bools, and
returns the value as a plain Python ``float`` / ``int`` (numpy scalars included), so a type can
store what it checked; real numbers beyond :data:`MAX_MAGNITUDE` are refused too. This module
imports nothing of gaitnet (layer 1, docs/design.md).
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Iterable
from typing import Any

MAX_MAGNITUDE = 1e30
"""Largest magnitude any checked number may have: beyond every physical value of a config or
a file, and small enough that squares and products of a few of them stay finite (a noise
density of 1e308 squared raised ``OverflowError`` deep inside the filter)."""


def _real(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ValueError(f"{name} must be a number, got {value!r}")
    number = float(value)
    if not math.isfinite(number):
        raise ValueError(f"{name} must be a finite number, got {value!r}")
    if abs(number) > MAX_MAGNITUDE:
        raise ValueError(f"{name} must be a number of magnitude at most 1e30, got {value!r}")
    return number


def check_range(
    name: str, value: Any, lo: float = -math.inf, hi: float = math.inf, unit: str = ""
) -> float:
    """A finite number with ``lo ≤ value ≤ hi``."""
    number = _real(name, value)
    if not lo <= number <= hi:
        if math.isinf(hi):
            raise ValueError(f"{name} must be at least {lo:g}{unit}, got {value!r}")
        raise ValueError(f"{name} must be within [{lo:g}, {hi:g}]{unit}, got {value!r}")
    return number


def check_positive(name: str, value: Any, unit: str = "") -> float:
    """A finite number ``> 0``."""
    number = _real(name, value)
    if not number > 0:
        raise ValueError(f"{name} must be positive{unit}, got {value!r}")
    return number


def check_each(name: str, values: Iterable[Any], lo: float, hi: float, unit: str = "") -> None:
    """Every element of ``values`` within ``[lo, hi]`` (named ``name[i]``)."""
    for i, value in enumerate(values):
        check_range(f"{name}[{i}]", value, lo, hi, unit)


def check_int_range(name: str, value: Any, lo: int | None = None, hi: int | None = None) -> int:
    """An integer (not a bool) with ``lo ≤ value ≤ hi`` (either bound may be open)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise ValueError(f"{name} must be an integer, got {value!r}")
    number = int(value)
    if (lo is not None and number < lo) or (hi is not None and number > hi):
        if hi is None:
            raise ValueError(f"{name} must be an integer of at least {lo}, got {value!r}")
        raise ValueError(f"{name} must be an integer within [{lo}, {hi}], got {value!r}")
    return number
