"""Range checks shared by the simulator's config dataclasses (their ``__post_init__``).

Each raises ``ValueError`` with a one-line message naming the key; :func:`gaitnet.config.
load_config` turns it into a :class:`~gaitnet.errors.ConfigError` naming the file and the
section. Comparisons are written so that NaN fails them (``not lo <= nan <= hi``).
"""

from __future__ import annotations

import numbers
from collections.abc import Iterable


def check_range(name: str, value: float, lo: float, hi: float, unit: str = "") -> None:
    """Require ``lo ≤ value ≤ hi`` (and a finite number)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not lo <= value <= hi:
        raise ValueError(f"{name} must be within [{lo:g}, {hi:g}]{unit}, got {value!r}")


def check_each(name: str, values: Iterable[float], lo: float, hi: float, unit: str = "") -> None:
    """Require every element of ``values`` within ``[lo, hi]``."""
    for i, value in enumerate(values):
        check_range(f"{name}[{i}]", value, lo, hi, unit)


def check_int_range(name: str, value: int, lo: int, hi: int) -> None:
    """Require an integer (not a bool) with ``lo ≤ value ≤ hi``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or not lo <= value <= hi:
        raise ValueError(f"{name} must be an integer within [{lo}, {hi}], got {value!r}")
