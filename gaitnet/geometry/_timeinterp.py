"""Bracketing of query timestamps in a sampled trajectory (shared by quaternion/pose interp)."""

from __future__ import annotations

from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

OutOfRange = Literal["raise", "clamp", "nan"]


def bracket_times(
    times: ArrayLike,
    query_times: ArrayLike,
    n_samples: int,
    out_of_range: OutOfRange,
) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.float64], NDArray[np.bool_]]:
    """Indices ``i0, i1`` and weight ``alpha`` with ``query ≈ (1-alpha) t[i0] + alpha t[i1]``.

    Returns ``(i0, i1, alpha, valid)``, each of the query's shape; ``valid`` is False only for
    out-of-range queries under ``out_of_range="nan"``. ``alpha`` lies in ``[0, 1]``.
    """
    t = np.asarray(times, dtype=np.float64)
    tq = np.asarray(query_times, dtype=np.float64)
    if t.ndim != 1 or t.shape[0] != n_samples:
        raise ValueError(f"times must have shape ({n_samples},), got {t.shape}")
    if n_samples == 0:
        raise ValueError("cannot interpolate an empty trajectory")
    if out_of_range not in ("raise", "clamp", "nan"):
        raise ValueError(f"out_of_range must be 'raise', 'clamp' or 'nan', got {out_of_range!r}")
    if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0.0):
        raise ValueError("times must be finite and strictly increasing")
    if np.any(np.isnan(tq)):
        raise ValueError("query_times contain NaN")
    outside = (tq < t[0]) | (tq > t[-1])
    if out_of_range == "raise" and np.any(outside):
        raise ValueError(
            f"query times outside the trajectory [{t[0]!r}, {t[-1]!r}]: "
            f"min {tq.min()!r}, max {tq.max()!r}"
        )
    valid = ~outside if out_of_range == "nan" else np.ones(tq.shape, dtype=bool)
    if n_samples == 1:
        zeros = np.zeros(tq.shape, dtype=np.intp)
        return zeros, zeros, np.zeros(tq.shape), valid
    i0 = np.clip(np.searchsorted(t, tq, side="right") - 1, 0, n_samples - 2)
    i1 = i0 + 1
    alpha = np.clip((tq - t[i0]) / (t[i1] - t[i0]), 0.0, 1.0)
    return i0, i1, alpha, valid
