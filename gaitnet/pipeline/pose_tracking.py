"""Predict-correct loop over a sequence (thesis sec. 4.2.4): each frame's prior is the motion
predictor's next pose from the last corrected poses, then corrected (eq. 4.7, 4.8).

The predictor works on heading-normalised windows (docs/predictor.md): the last ``n_past``
corrected poses are rotated about the vertical so that the body faces +x at the last one
(:func:`gaitnet.motion.heading.normalise_heading`), the predicted pose's root orientation is
rotated back. The predictor does not predict the root translation: its prior extrapolates
the last corrected velocity. The first ``n_past`` poses are given (e.g. the standing pose).

The predictor was trained on poses ``dt`` apart (30 frames/s: ``gaitnet.motion.amass.
TARGET_FPS``). Given the frames' times, its window is the corrected poses resampled at ``dt``
back from the last corrected frame (the root orientation along the geodesic between the two
poses around each sample time, the joints' axis-angles and the translations linearly), and
the prior is its prediction at the next frame's time (between the last pose and the predicted
frames ``dt``, ``2 dt``, … after it): a session at 15 frames/s, or with a dropped frame, feeds
it what it was trained on. Frames exactly ``dt`` apart give the frame-by-frame window.
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

#: ``predict(past)``: heading-normalised past poses (n_past, 21) → the predicted poses
#: (n_future, 21) ``dt``, ``2 dt``, … after the last (or the next one alone, (21,)), same frame.
Predictor = Callable[[FloatArray], FloatArray]


def denormalise_root(root_orient: FloatArray, yaw: float) -> FloatArray:
    """Undo :func:`~gaitnet.motion.heading.normalise_heading` on a root orientation (3,)."""
    return so3_log(so3_exp(np.array([0.0, 0.0, yaw])) @ so3_exp(root_orient))


def _resample(
    times: FloatArray, poses: FloatArray, trans: FloatArray, at: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Poses (m, 21) and translations (m, 3) at the times ``at`` (within ``times``, sorted)
    from samples at ``times`` (module docstring)."""
    j = np.clip(np.searchsorted(times, at, side="right") - 1, 0, len(times) - 2)
    span = times[j + 1] - times[j]
    a = np.clip((at - times[j]) / np.where(span > 0, span, 1.0), 0.0, 1.0)[:, None]
    out = (1 - a) * poses[j] + a * poses[j + 1]
    out_t = (1 - a) * trans[j] + a * trans[j + 1]
    R0, R1 = so3_exp(poses[j, :3]), so3_exp(poses[j + 1, :3])
    step = so3_log(np.swapaxes(R0, -1, -2) @ R1)
    out[:, :3] = so3_log(R0 @ so3_exp(a * step))
    return out, out_t


def track_poses(
    predict: Predictor,
    start: Sequence[PoseState],
    measurements: Sequence[FrameMeasurements],
    skeleton: LowerBodySkeleton,
    params: PoseCorrectionParams | None = None,
    t_s: Sequence[float] | None = None,
    dt: float | None = None,
) -> tuple[list[PoseState], list[PoseState]]:
    """Corrected poses and their priors, one per measurement, after the ``start`` poses.

    ``start`` holds the ``n_past`` poses before the first measurement (``n_past = len(start)``,
    at least 2). Frame ``i`` predicts from the last ``n_past`` corrected poses and corrects
    towards ``measurements[i]``. With ``t_s`` (the measurements' times, increasing) and the
    predictor's sample interval ``dt``, the window is resampled in time (module docstring;
    the start poses lie ``dt`` apart before the first frame).
    """
    n_past = len(start)
    if n_past < 2:
        raise InputError(f"pose tracking: needs at least 2 start poses, got {n_past}")
    timed = t_s is not None and dt is not None
    if timed:
        t_s = np.asarray(t_s, dtype=np.float64)
        if not (dt > 0 and np.all(np.diff(t_s) > 0)):
            raise InputError("pose tracking: frame times must increase, one per measurement")
        t_first = float(t_s[0]) if len(t_s) else 0.0
        times = [t_first - dt * (n_past - k) for k in range(n_past)]
    poses = [p.pose for p in start]
    trans = [p.trans for p in start]
    first = 0  # the earliest sample the window can still need
    corrected: list[PoseState] = []
    priors: list[PoseState] = []
    for i, m in enumerate(measurements):  # an iterable: a progress bar may wrap it
        if timed and i >= len(t_s):
            raise InputError(f"pose tracking: {len(t_s)} frame times for more measurements")
        if timed:
            at = times[-1] - dt * np.arange(n_past - 1, -1, -1)
            while first + 1 < len(times) and times[first + 1] <= at[0]:
                first += 1  # the window only moves forward
            past, past_t = _resample(
                np.array(times[first:]), np.stack(poses[first:]), np.stack(trans[first:]), at
            )
            ahead = (t_s[i] - times[-1]) / dt  # the next frame, in predicted steps
            velocity = (trans[-1] - trans[-2]) / (times[-1] - times[-2])
            prior_t = trans[-1] + velocity * (t_s[i] - times[-1])
        else:
            past, past_t = np.stack(poses[-n_past:]), np.stack(trans[-n_past:])
            ahead = 1.0
            prior_t = 2.0 * past_t[-1] - past_t[-2]
        root_n, _, yaw = normalise_heading(past[:, :3], past_t, n_past - 1)
        window = np.concatenate([root_n, past[:, 3:]], axis=1)
        future = np.asarray(predict(window), dtype=np.float64)
        future = future[None] if future.ndim == 1 else future
        if future.ndim != 2 or future.shape[1] != 21 or not np.all(np.isfinite(future)):
            raise InputError(
                f"pose tracking: the predictor returned {future.shape}, expected (n_future, 21)"
            )
        if ahead == 1.0:
            pose = future[0].copy()
        else:  # between the window's last pose (step 0) and the predicted steps 1, 2, …
            steps = np.arange(len(future) + 1, dtype=np.float64)
            grid = np.concatenate([window[-1:], future])
            pose, _ = _resample(steps, grid, np.zeros((len(steps), 3)), np.array([ahead]))
            pose = pose[0]
        pose[:3] = denormalise_root(pose[:3], yaw)
        prior = PoseState(pose, prior_t)
        out, _ = correct_pose(prior, m, skeleton, params)
        priors.append(prior)
        corrected.append(out)
        poses.append(out.pose)
        trans.append(out.trans)
        if timed:
            times.append(float(t_s[i]))
    return corrected, priors
