"""What the filter does with a sheet pose its tag gate refuses (:mod:`gaitnet.vio.run`).

Two cases, both position-only tag measurements (``H = I`` on ``pos``):

- :func:`within_drift`: the pose lies within the odometry's possible drift of the prediction
  (``filter.odometry_scale_std``): it goes to the smoother, not the filter;
- :class:`RefusedSheets`: the gate refuses a sheet steadily, decode after decode
  (``filter.tag_recovery_frames``): the filter has drifted beyond its covariance, whose
  navigation block is widened until the pose passes
  (:func:`gaitnet.vio.covariance.inflate_to_pass`); the caller then updates with it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from gaitnet.vio import covariance
from gaitnet.vio.measurement import Measurement
from gaitnet.vio.state import FilterState

__all__ = ["RECOVERY_STEP_M", "RefusedSheets", "within_drift"]

RECOVERY_STEP_M = 0.03
"""Largest change of a refused sheet pose's position residual from one refused decode to the
next for the refusals to count as steady (``filter.tag_recovery_frames``): a drifted filter's
residual grows by millimetres per frame; a wrong decode jumps."""


def within_drift(m: Measurement, state: FilterState, drift_m: float, probability: float) -> bool:
    """Whether the tag measurement ``m`` (position residual, ``H = I`` on ``pos``) passes the
    χ² gate once the odometry's possible drift ``drift_m`` (standard deviation, horizontal) is
    added to its covariance (``filter.odometry_scale_std``); False without a drift, a gate, or
    for a measurement that is not the position-only one."""
    if drift_m <= 0 or not probability or set(m.H) != {"pos"}:
        return False
    S = state.P[3:6, 3:6] + m.R + np.diag([drift_m**2, drift_m**2, 0.0])
    chi2 = covariance.mahalanobis2(S, np.asarray(m.residual, dtype=np.float64))
    return np.isfinite(chi2) and chi2 <= covariance.chi2_gate(m.dim, probability)


@dataclass
class RefusedSheets:
    """The sheet poses the gate refused since the filter last took one: ``(frame index,
    position residual)``."""

    frames: int  # ``filter.tag_recovery_frames``: 0 never recovers, else at least 2
    refused: list[tuple[int, np.ndarray]] = field(default_factory=list)

    def steady(self) -> bool:
        """Whether the last ``frames`` refusals come from decodes in a row (a frame without a
        decode between two allowed) and change by at most :data:`RECOVERY_STEP_M` from one to
        the next."""
        n = self.frames
        if n < 2 or len(self.refused) < n:
            return False
        last = self.refused[-n:]
        gaps = np.diff([k for k, _ in last])
        steps = np.linalg.norm(np.diff(np.array([r for _, r in last]), axis=0), axis=1)
        return bool(np.all(gaps <= 2) and np.all(steps <= RECOVERY_STEP_M))

    def widen_if_steady(
        self, state: FilterState, k: int, m: Measurement, chi2: float, probability: float
    ) -> float:
        """Record the refusal of ``m`` in frame ``k`` (its χ² ``chi2``); when the refusals are
        steady, widen ``state``'s navigation covariance until ``m``'s χ² is half the gate and
        return the factor (:func:`gaitnet.vio.covariance.inflate_to_pass`), else NaN (also for
        a measurement that is not position-only, or a non-finite χ²)."""
        if set(m.H) != {"pos"} or not np.isfinite(chi2):
            return float("nan")
        self.refused.append((k, np.asarray(m.residual, dtype=np.float64)))
        if not self.steady():
            return float("nan")
        gate = covariance.chi2_gate(m.dim, probability)
        factor = covariance.inflate_to_pass(state, m, 0.5 * gate)
        return factor if np.isfinite(factor) else float("nan")
