"""What one run of the filter and smoother produces (:func:`gaitnet.vio.run.run_vio`)."""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

import numpy as np

from gaitnet.vio.gait import Stride

__all__ = ["StanceFoot", "VioResult"]


@dataclass(frozen=True)
class StanceFoot:
    """One stance-foot landmark: ``side``, the first and last frame time it was observed [s],
    its floor position ``xy`` (world, smoothed when the smoother ran, else the filter's),
    its standard deviations ``std_xy`` [m] and the number of observations; ``inferred``: laid
    from the step rhythm where the camera never saw the foot (no observation, a negative
    ``landmark_id``: :mod:`gaitnet.pipeline.hidden_stances`)."""

    landmark_id: int
    side: str
    t_first_s: float
    t_last_s: float
    xy: np.ndarray
    std_xy: np.ndarray
    n_observations: int
    inferred: bool = False


@dataclass
class VioResult:
    """Trajectories at the times ``t_s`` (n,) [s, session clock] of the frames the filter
    processed (``session_index`` (n,): their frame numbers; frames before the initialising one
    and frames whose time does not advance are not processed, and counted in ``skipped``):
    the filter's IMU and colour-camera poses ``T_WfromI_filter``/``T_WfromC_filter``
    (n, 4, 4) with the filter's IMU-position covariance ``cov_p_IinW_filter`` (n, 3, 3), the
    smoothed ones (None when the smoother is off), the IMU-only dead-reckoning camera poses
    (same initialisation, no visual update); stance feet and strides (smoothed when the
    smoother ran) and the filter's own (``stance_feet_filter``, ``strides_filter``); and what
    happened on the way: ``initialisation`` (``"apriltag"`` or ``"gravity_floor"``) with a
    sentence saying how, per-update counts of used and skipped measurements with reasons,
    CPU seconds of the calling thread per stage ``timings_s`` (the session reader's
    read-ahead thread is not in them), and the smoother's diagnostics ``smoother`` (empty
    when it did not run); ``unreliable``: why the result cannot be trusted (the scene check's
    problems of a run with ``scene.refuse: false``; empty when it passed)."""

    t_s: np.ndarray
    T_WfromI_filter: np.ndarray
    T_WfromC_filter: np.ndarray
    T_WfromC_imu_only: np.ndarray
    T_WfromI_smoothed: np.ndarray | None
    T_WfromC_smoothed: np.ndarray | None
    stance_feet: list[StanceFoot]
    strides: list[Stride]
    initialisation: str
    initialisation_note: str
    session_index: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    cov_p_IinW_filter: np.ndarray = field(default_factory=lambda: np.zeros((0, 3, 3)))
    stance_feet_filter: list[StanceFoot] = field(default_factory=list)
    strides_filter: list[Stride] = field(default_factory=list)
    smoother: dict[str, object] = field(default_factory=dict)
    used: Counter = field(default_factory=Counter)
    skipped: dict[str, Counter] = field(default_factory=dict)
    timings_s: dict[str, float] = field(default_factory=dict)
    unreliable: list[str] = field(default_factory=list)

    def skip(self, kind: str, reason: str) -> None:
        """Count one skipped ``kind`` measurement (``vo``, ``tag``, ``foot``, ``frame``)."""
        self.skipped.setdefault(kind, Counter())[reason] += 1

    @property
    def T_WfromC(self) -> np.ndarray:
        """The best camera trajectory: smoothed when available, else the filter's."""
        return (
            self.T_WfromC_smoothed if self.T_WfromC_smoothed is not None else self.T_WfromC_filter
        )
