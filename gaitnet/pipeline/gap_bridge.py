"""Bridging a foot's swing gap to the frame where the foot is seen again
(``pipeline.gap_fill: bridge``, and with ``swing`` where no two stance landmarks bound a gap).

A foot is out of view or hidden for 0.5–0.8 s of every stride (thesis Fig. 5.10); frame by frame
the pose correction can only follow the motion predictor there, and the predicted foot lags the
true one in the fast part of the swing, so the corrected foot jumps forward by 10–30 cm when the
foot is seen again. :func:`bridge_gaps` keeps the predicted path's shape but ends it at the first
pass's (corrected) foot in the frame where the foot is seen again: over a gap ``a … b−1``
between measured frames ``a−1`` and ``b``, with ``f_k`` the first pass's foot point and
``f̂_b = 2 f_{b−1} − f_{b−2}`` where the prediction would have been at ``b``, the bridged point
is

    g_k = f_k + w_k (f_b − f̂_b),   w_k = L(a−1 … k) / L(a−1 … b)

with ``L`` the horizontal length of the predicted path (``f_{a−1} … f_{b−1}, f̂_b``): the
discrepancy is spread where the predicted foot moves, not evenly in time (spreading it evenly
in time measured worse: docs/pipeline.md). :func:`gaitnet.pipeline.infer.reconstruct` then runs
the correction a second time with the bridged points as the feet's measurements in the gaps.
Gaps at the start or end of the session (not bounded on both sides) are left alone; a foot
seen in a single frame between frames where it is not does not end a gap (:func:`gaps`), and
the bridge replaces that frame's measurement in the second pass.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["bridge_gaps", "feet_steadily_seen", "frames_to_bridge", "gaps", "steadily_seen"]


def steadily_seen(measured: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """``measured`` (n,) without the frames measured alone between frames that are not: one
    frame's detection between misses is as likely a false one, and a gap must not end on it."""
    m = np.asarray(measured, dtype=bool)
    return m & (np.r_[False, m[:-1]] | np.r_[m[1:], False])


def feet_steadily_seen(points: np.ndarray) -> NDArray[np.bool_]:
    """(n, 2) per frame and foot, whether ``points`` (n, 2, 3; NaN where not seen) holds a
    whole point for that foot steadily (:func:`steadily_seen`)."""
    p = np.asarray(points, dtype=np.float64)
    return np.stack([steadily_seen(np.isfinite(p[:, s]).all(axis=1)) for s in range(2)], axis=1)


def gaps(measured: NDArray[np.bool_]) -> list[tuple[int, int]]:
    """``(a, b)`` of every run of frames ``a … b−1`` where the foot is not seen, with frames
    where it is seen at both ``a − 1`` and ``b``, in order. A foot measured in one frame only,
    between frames where it is not, counts as not seen (:func:`steadily_seen`)."""
    m = steadily_seen(measured)
    out = []
    k, n = 0, len(m)
    while k < n:
        if m[k]:
            k += 1
            continue
        a = k
        while k < n and not m[k]:
            k += 1
        if a > 0 and k < n:
            out.append((a, k))
    return out


def bridge_gaps(points: np.ndarray, measured: NDArray[np.bool_]) -> np.ndarray:
    """Bridged foot points (n, S, 3) of the first pass's ``points`` (n, S, 3) for the ``S`` feet
    whose frames are ``measured`` (n, S) (module docstring); NaN outside the bridged gaps."""
    points = np.asarray(points, dtype=np.float64)
    measured = np.asarray(measured, dtype=bool)
    if points.ndim != 3 or points.shape[2] != 3 or measured.shape != points.shape[:2]:
        raise ValueError(
            f"bridge_gaps: points (n, S, 3) and measured (n, S), got {points.shape} and "
            f"{measured.shape}"
        )
    out = np.full(points.shape, np.nan)
    for s in range(points.shape[1]):
        for a, b in gaps(measured[:, s]):
            path = points[a - 1 : b, s]  # the last measured frame and the gap
            expected = 2.0 * points[b - 1, s] - points[b - 2, s]  # the prediction at b (a ≥ 1)
            steps = np.diff(np.vstack([path, expected]), axis=0)
            length = np.cumsum(np.hypot(steps[:, 0], steps[:, 1]))
            if length[-1] > 1e-9:
                w = length / length[-1]
            else:  # the predicted foot stands still: spread evenly in time
                w = np.arange(1, len(steps) + 1) / len(steps)
            out[a:b, s] = path[1:] + w[:-1, None] * (points[b, s] - expected)
    return out


def frames_to_bridge(measured: NDArray[np.bool_], covered: NDArray[np.bool_] | None = None) -> int:
    """How many leading frames of the first pass :func:`bridge_gaps` needs for the gaps that
    ``covered`` (n, S; e.g. the swing fill's frames) leaves a frame of: through the frame after
    the frame ``b`` where the last such gap ends (that frame tells whether ``b`` is steadily
    seen: :func:`steadily_seen`), at most all ``n``; 0 if there is no such gap. Over those
    ``m`` frames, ``bridge_gaps(points[:m], measured[:m])`` equals ``bridge_gaps(points,
    measured)`` at every frame of such a gap, so a caller that takes the ``covered`` frames
    from elsewhere can stop the first pass there."""
    measured = np.asarray(measured, dtype=bool)
    covered = np.zeros(measured.shape, bool) if covered is None else np.asarray(covered, bool)
    if covered.shape != measured.shape or measured.ndim != 2:
        raise ValueError(
            f"frames_to_bridge: measured and covered (n, S), got {measured.shape} and "
            f"{covered.shape}"
        )
    ends = [
        b
        for s in range(measured.shape[1])
        for a, b in gaps(measured[:, s])
        if not covered[a:b, s].all()
    ]
    # a gap's end b is steadily seen, so frame b − 1 is not and b + 1 is: b + 2 ≤ n
    return min(max(ends) + 2, len(measured)) if ends else 0
