"""A foot's measured point where the leg hides the back of the shoe: laid from the toe.

The measured foot point of ``gaitnet infer`` is the ``mid`` keypoint of eq. 4.1, the middle of
the visible shoe (``pipeline.foot_keypoint``). From the waist, a knee flexed 25–30° through
early stance (real walkers; the simulator's gait generator flexes about 14°) puts the thigh and
shin over the heel and instep of the planted foot: only the front of the shoe shows and its
middle lies 5–6 cm ahead of the shoe's (CMU walking_03: the mid keypoint 16.3 cm ahead of the
ankle in walking stance against 10.4 cm standing; the ``top`` keypoint, the toe, 19.1 against
18.9 cm; docs/pipeline.md, *Feet under the knee*). The toe is the end of the shoe farthest from
the camera and the last the leg covers.

With ``pipeline.toe_anchor`` a foot's mid point is laid from its toe wherever the two lie
closer together along the floor than on the standing shoe:

- ``d₀``, per foot, the median over the standing frames at the start (``pipeline.standing_s``)
  of ``R_z(−ψ) (p_mid − p_top)``: the toe → mid vector of the whole shoe in the body's heading
  frame, for this subject's shoes and this camera;
- ``ψ`` the heading: the yaw of the camera's optical axis plus its image-up axis projected on
  the floor (defined at every pitch down to straight down), averaged over
  ``pipeline.toe_anchor_window_s`` so that the pelvis's rotation within a stride cancels;
- where the horizontal length of ``p_mid − p_top`` is shorter than that of ``d₀`` by more than
  ``pipeline.toe_anchor_tolerance_m``, the shoe's back is hidden and the mid point becomes
  ``p_top + R_z(ψ) d₀``. Elsewhere, and where either keypoint has no depth, it stays.

A foot turned out of the heading by an angle ``α`` in the anchored frames gets an error of about
``α |d₀|`` across (1.5 cm at 10°), well under the 5–6 cm the hidden heel costs.
"""

from __future__ import annotations

import logging

import numpy as np
from scipy.ndimage import uniform_filter1d

__all__ = ["MIN_STANDING_PAIRS", "heading_angles", "toe_anchored_points"]

log = logging.getLogger(__name__)

MIN_STANDING_PAIRS = 5
"""Standing frames with both keypoints of a foot needed for its standing toe → mid vector."""


def heading_angles(T_WfromC: np.ndarray, t_s: np.ndarray, window_s: float) -> np.ndarray:
    """The body's heading ``ψ`` (n,) [rad, unwrapped] from the camera poses (module docstring),
    a moving average over ``window_s``."""
    R = np.asarray(T_WfromC, dtype=np.float64)[:, :3, :3]
    forward = R[:, :, 2] - R[:, :, 1]  # optical axis plus image up: forward-down to forward-up
    psi = np.unwrap(np.arctan2(forward[:, 1], forward[:, 0]))
    if len(psi) < 2:
        return psi
    rate = 1.0 / float(np.median(np.diff(t_s)))
    size = max(1, int(round(window_s * rate)))
    return uniform_filter1d(psi, size, mode="nearest")


def _rotate(psi: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``R_z(ψ) v`` row by row: ``psi`` (n,), ``v`` (n, 3)."""
    c, s = np.cos(psi), np.sin(psi)
    return np.stack([c * v[:, 0] - s * v[:, 1], s * v[:, 0] + c * v[:, 1], v[:, 2]], axis=1)


def toe_anchored_points(
    mid_W: np.ndarray,
    top_W: np.ndarray,
    psi: np.ndarray,
    n_standing: int,
    tolerance_m: float,
) -> tuple[np.ndarray, int]:
    """``mid_W`` (n, 2, 3) with each mid point whose shoe back is hidden laid from the toe
    ``top_W`` (n, 2, 3) (module docstring; NaN rows: not seen), and the number of points laid.
    ``psi`` (n,) is the heading, the first ``n_standing`` frames are standing. A foot with
    fewer than :data:`MIN_STANDING_PAIRS` standing frames with both keypoints keeps its mid
    points."""
    out = np.array(mid_W, dtype=np.float64, copy=True)
    top = np.asarray(top_W, dtype=np.float64)
    laid = 0
    for side in range(2):
        d = out[:, side] - top[:, side]
        both = np.isfinite(d).all(axis=1)
        standing = both & (np.arange(len(d)) < n_standing)
        if standing.sum() < MIN_STANDING_PAIRS:
            log.info(
                "foot %d: %d standing frames with toe and mid; its mid points stay",
                side, int(standing.sum()),
            )  # fmt: skip
            continue
        d0 = np.median(_rotate(-psi[standing], d[standing]), axis=0)
        short = np.linalg.norm(d[:, :2], axis=1) < np.linalg.norm(d0[:2]) - tolerance_m
        hidden = both & short
        k = np.flatnonzero(hidden)
        out[k, side] = top[k, side] + _rotate(psi[k], np.broadcast_to(d0, (len(k), 3)))
        laid += len(k)
    return out, laid
