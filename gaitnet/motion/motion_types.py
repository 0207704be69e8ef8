"""Motion type of an evaluation window: standing, steady walking, starting/stopping, turning.

The predictor's evaluation by motion type (``benchmarks/bench_predictor_motion.py``,
docs/predictor.md) labels each window of ``n_past + n_future`` frames from the pelvis
translation and the root orientation over the WHOLE window (observed and future frames: what
matters is the motion the predictor has to continue). Rule, in this order:

1. ``standing``: the pelvis's horizontal speed, averaged over :data:`SPEED_SMOOTH_FRAMES`
   consecutive frames, stays below :data:`STANDING_SPEED_MPS` (0.15 m/s) throughout;
2. ``start_stop``: else, when the smallest of those speeds is below :data:`START_STOP_RATIO`
   (0.5) times the largest: the body speeds up from (or slows down to) near rest within the
   window (gait initiation or termination, or a sudden change of pace);
3. ``turning``: else, when the heading (:func:`gaitnet.motion.heading.heading_angle`: the
   body's forward axis on the floor) averaged over the first ``n_past`` frames and over the
   last ``n_future`` frames differs by at least :data:`TURN_DEG` (15°); the pelvis's own
   rotation in gait (about ±3–5°) stays well below;
4. ``steady_walking``: everything else.

The rule only looks at speeds and heading changes, so it is the same before and after heading
normalisation (a rotation about the vertical and a horizontal shift).
"""

from __future__ import annotations

import numpy as np

from gaitnet.evaluation.metrics import joint_distances
from gaitnet.motion.gcn import joint_positions
from gaitnet.motion.heading import heading_angle
from gaitnet.motion.skeleton import LowerBodySkeleton
from gaitnet.motion.windows import WalkingWindows

__all__ = [
    "MOTION_TYPES",
    "SPEED_SMOOTH_FRAMES",
    "STANDING_SPEED_MPS",
    "START_STOP_RATIO",
    "TURN_DEG",
    "label_window",
    "labelled_windows",
    "per_window_mpjpe",
]

#: Labels, in the order tables list them.
MOTION_TYPES: tuple[str, ...] = ("standing", "steady_walking", "start_stop", "turning")
STANDING_SPEED_MPS = 0.15
START_STOP_RATIO = 0.5
TURN_DEG = 15.0
SPEED_SMOOTH_FRAMES = 5


def label_window(root_orient: np.ndarray, trans: np.ndarray, fps: float, n_past: int) -> str:
    """The motion type of one window: ``root_orient`` and ``trans`` (W, 3) (module docstring)."""
    trans = np.asarray(trans, dtype=np.float64)
    W = trans.shape[0]
    if W < SPEED_SMOOTH_FRAMES + 1 or not 0 < n_past < W or root_orient.shape != (W, 3):
        raise ValueError(f"label_window needs (W, 3) arrays with 0 < n_past < W, got {W}")
    step = np.linalg.norm(np.diff(trans[:, :2], axis=0), axis=1) * fps  # (W − 1,) m/s
    kernel = np.ones(SPEED_SMOOTH_FRAMES) / SPEED_SMOOTH_FRAMES
    speed = np.convolve(step, kernel, mode="valid")
    if speed.max() < STANDING_SPEED_MPS:
        return "standing"
    if speed.min() < START_STOP_RATIO * speed.max():
        return "start_stop"
    yaw = heading_angle(root_orient)
    first = np.angle(np.mean(np.exp(1j * yaw[:n_past])))
    last = np.angle(np.mean(np.exp(1j * yaw[n_past:])))
    change = abs(np.angle(np.exp(1j * (last - first))))
    if np.degrees(change) >= TURN_DEG:
        return "turning"
    return "steady_walking"


def labelled_windows(windows: WalkingWindows) -> tuple[np.ndarray, np.ndarray]:
    """All windows of ``windows`` as (N, W, 21) float64 poses and their (N,) motion types."""
    poses, labels = [], []
    for i in range(len(windows)):
        item = windows[i]
        p = item["poses"].numpy().astype(np.float64)
        labels.append(label_window(p[:, :3], item["trans"].numpy(), windows.fps, windows.n_past))
        poses.append(p)
    return np.stack(poses), np.array(labels, dtype=str)


def per_window_mpjpe(
    pred: np.ndarray, truth: np.ndarray, skeleton: LowerBodySkeleton
) -> np.ndarray:
    """Mean MPJPE [m] of each window over its horizons and the 7 joints: (N,) from (N, K, 21)."""
    d = joint_distances(joint_positions(pred, skeleton), joint_positions(truth, skeleton))
    return np.asarray(d).mean(axis=(1, 2))
