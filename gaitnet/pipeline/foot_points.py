"""Step 2 of ``gaitnet infer``: the measured foot points of one frame in the world frame.

With the filter's camera pose ``T_WfromC`` the floor is known in the camera frame (the world
floor ``z = 0``: normal ``n_C = R_WfromCᵀ e_z``, camera height ``h = z`` of the camera centre,
thesis (3.22)) and so is gravity (``R_WfromCᵀ (0, 0, −1)``): HHA is encoded with both
(:func:`~gaitnet.segmentation.hha.hha_encode`, at the resolution the model's streams see), the
segmenter labels the frame, the post-processing finds each foot's keypoints of eq. 4.1 with
their camera-frame points (:func:`~gaitnet.segmentation.postprocess.foot_keypoints`), and the
chosen keypoint of each sided foot is moved to the world. Feet whose side the post-processing
could not tell are given the side of the nearer predicted foot when one is given, else dropped.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

import numpy as np

from gaitnet.geometry.floor_plane import FloorPlane
from gaitnet.io.types import Frame
from gaitnet.segmentation.hha import HhaParams, hha_encode, hha_stride
from gaitnet.segmentation.midline import pair_midpoint
from gaitnet.segmentation.onnx_runtime import OnnxSegmenter
from gaitnet.segmentation.postprocess import (
    FootKeypointParams,
    foot_keypoints,
    kept_feet_labels,
)
from gaitnet.vio.feet_segmented import FootMask

__all__ = ["FrameFeet", "floor_in_camera", "measure_feet"]

SIDES = ("left", "right")


@dataclass
class FrameFeet:
    """One frame's measured feet: ``foot_W`` (2, 3) world points of the left and right foot
    (a row of NaN where not seen), the label map after the post-processing (foot pixels only
    where a foot was kept: :func:`~gaitnet.segmentation.postprocess.kept_feet_labels`) and the
    number of foot blobs, the midpoint of the two feet along the camera's left axis where
    they were sided apart (:func:`gaitnet.segmentation.midline.pair_midpoint`; else None),
    the segmenter's foot pixels before the post-processing (for the filter's second run,
    ``pipeline.segmented_stances``; None: no foot pixel), the foot blobs dropped as no foot,
    by reason (:data:`gaitnet.segmentation.postprocess.DROP_REASONS`), and ``top_W`` (2, 3)
    the ``top`` keypoint (the toe) of the same feet, for :mod:`gaitnet.pipeline.toe_anchor`
    (NaN where it has no depth)."""

    foot_W: np.ndarray
    labels: np.ndarray
    n_blobs: int
    pair_midpoint_m: float | None = None
    foot_mask: FootMask | None = None
    dropped: Counter = field(default_factory=Counter)
    top_W: np.ndarray = field(default_factory=lambda: np.full((2, 3), np.nan))


def floor_in_camera(T_WfromC: np.ndarray) -> FloorPlane:
    """The world floor ``z = 0`` as the camera-frame plane ``n_C·p + h = 0`` (3.22)."""
    T = np.asarray(T_WfromC, dtype=np.float64)
    return FloorPlane(n_C=T[:3, :3].T @ np.array([0.0, 0.0, 1.0]), h=float(T[2, 3]))


def measure_feet(
    frame: Frame,
    K: np.ndarray,
    T_WfromC: np.ndarray,
    segmenter: OnnxSegmenter,
    keypoint: str,
    hha_params: HhaParams,
    feet_params: FootKeypointParams,
    predicted_W: np.ndarray | None = None,
) -> FrameFeet:
    """Segment ``frame`` and return its world foot points (module docstring).

    ``predicted_W`` (2, 3): where the pose predicts the left and right foot points; it sides
    feet the post-processing left as ``unknown``.
    """
    T = np.asarray(T_WfromC, dtype=np.float64)
    plane = floor_in_camera(T)
    gravity_C = -plane.n_C
    stride = hha_stride(segmenter.input_scale)
    hha = hha_encode(frame.depth_m, K, gravity_C, hha_params, plane=plane, stride=stride)
    labels = segmenter.labels(frame.rgb, hha)
    dropped: Counter = Counter()
    feet = foot_keypoints(
        labels, frame.depth_m, K, feet_params, gravity_C=gravity_C, plane=plane, dropped=dropped
    )
    foot_W = np.full((2, 3), np.nan)
    top_W = np.full((2, 3), np.nan)
    for foot in feet:  # largest first: a side keeps its largest blob
        p_C = foot.keypoints_C.get(keypoint)
        if p_C is None:
            continue
        p_W = T[:3, :3] @ p_C + T[:3, 3]
        side = foot.side
        if side == "unknown" and predicted_W is not None:
            side = SIDES[int(np.argmin(np.linalg.norm(predicted_W - p_W, axis=1)))]
        if side in SIDES and np.isnan(foot_W[SIDES.index(side), 0]):
            foot_W[SIDES.index(side)] = p_W
            top_C = foot.keypoints_C.get("top")
            if top_C is not None:
                top_W[SIDES.index(side)] = T[:3, :3] @ top_C + T[:3, 3]
    return FrameFeet(
        foot_W,
        kept_feet_labels(labels, feet),
        len(feet),
        pair_midpoint(feet, feet_params),
        FootMask.from_labels(labels),  # label 1: foot
        dropped,
        top_W,
    )
