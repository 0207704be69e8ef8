"""Predict-correct loop over a sequence (thesis sec. 4.2.4): each frame's prior is the motion
predictor's next pose from the last corrected poses, then corrected (eq. 4.7, 4.8).

The predictor works on heading-normalised windows (docs/predictor.md): the last ``n_past``
corrected poses are rotated about the vertical so that the body faces +x at the last one
(:func:`gaitnet.motion.heading.normalise_heading`), the predicted pose's root orientation is
rotated back. The predictor does not predict the root translation: its prior extrapolates
the last corrected velocity. The first ``n_past`` poses are given (e.g. the standing pose).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import NDArray

from gaitnet.errors import InputError
from gaitnet.geometry import so3_exp, so3_log
from gaitnet.motion.heading import normalise_heading
from gaitnet.motion.skeleton import LowerBodySkeleton
from gaitnet.pipeline.pose_correction import correct_pose
from gaitnet.pipeline.pose_types import FrameMeasurements, PoseCorrectionParams, PoseState

FloatArray = NDArray[np.float64]

__all__ = ["Predictor", "denormalise_root", "track_poses"]

#: ``predict(past)``: heading-normalised past poses (n_past, 21) → the next pose (21,), same frame.
Predictor = Callable[[FloatArray], FloatArray]


def denormalise_root(root_orient: FloatArray, yaw: float) -> FloatArray:
    """Undo :func:`~gaitnet.motion.heading.normalise_heading` on a root orientation (3,)."""
    return so3_log(so3_exp(np.array([0.0, 0.0, yaw])) @ so3_exp(root_orient))


def track_poses(
    predict: Predictor,
    start: Sequence[PoseState],
    measurements: Sequence[FrameMeasurements],
    skeleton: LowerBodySkeleton,
    params: PoseCorrectionParams | None = None,
) -> tuple[list[PoseState], list[PoseState]]:
    """Corrected poses and their priors, one per measurement, after the ``start`` poses.

    ``start`` holds the ``n_past`` poses before the first measurement (``n_past = len(start)``,
    at least 2). Frame ``i`` predicts from the last ``n_past`` corrected poses and corrects
    towards ``measurements[i]``.
    """
    n_past = len(start)
    if n_past < 2:
        raise InputError(f"pose tracking: needs at least 2 start poses, got {n_past}")
    poses = [p.pose for p in start]
    trans = [p.trans for p in start]
    corrected: list[PoseState] = []
    priors: list[PoseState] = []
    for m in measurements:
        past = np.stack(poses[-n_past:])
        past_t = np.stack(trans[-n_past:])
        root_n, _, yaw = normalise_heading(past[:, :3], past_t, n_past - 1)
        window = np.concatenate([root_n, past[:, 3:]], axis=1)
        nxt = np.asarray(predict(window), dtype=np.float64)
        if nxt.shape != (21,) or not np.all(np.isfinite(nxt)):
            raise InputError(f"pose tracking: the predictor returned {nxt.shape}, expected (21,)")
        pose = nxt.copy()
        pose[:3] = denormalise_root(nxt[:3], yaw)
        prior = PoseState(pose, 2.0 * past_t[-1] - past_t[-2])
        out, _ = correct_pose(prior, m, skeleton, params)
        priors.append(prior)
        corrected.append(out)
        poses.append(out.pose)
        trans.append(out.trans)
    return corrected, priors
