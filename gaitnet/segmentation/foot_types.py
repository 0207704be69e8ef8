"""The foot post-processing's settings and results (:mod:`gaitnet.segmentation.postprocess`,
which documents each setting's role and re-exports these names).

:class:`FootKeypointParams` holds every setting, each validated on construction (a one-line
error naming it); :class:`FootDetection` is one foot found in a frame; :data:`KEYPOINT_NAMES`
the eq. 4.1 keypoints (thesis sec. 4.1.4).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from gaitnet.checks import check_int_range, check_range
from gaitnet.segmentation.hha import HhaParams

__all__ = ["KEYPOINT_NAMES", "FootDetection", "FootKeypointParams"]

KEYPOINT_NAMES = ("top", "mid", "bottom")


@dataclass(frozen=True)
class FootKeypointParams:
    """Post-processing settings (:mod:`gaitnet.segmentation.postprocess`); checked in
    ``__post_init__``."""

    min_area_fraction: float = 0.0005
    """Smallest foot blob, as a fraction of the image (154 px at 640×480)."""
    min_leg_area_fraction: float = 0.0005
    """Smallest leg blob that can say a foot's side."""
    max_depth_dev_m: float = 0.15
    """Largest distance of a foot pixel's depth from its blob's median depth [m] (a shoe is
    ~0.3 m long; seen from above its depth spans less than half of it)."""
    min_consistent_fraction: float = 0.5
    """Smallest share of a blob's valid depths within ``max_depth_dev_m`` of the median."""
    min_depth_pixels: int = 5
    """Fewest valid depths for a depth check or a 3-D point."""
    use_floor: bool = True
    """Fit the floor when no plane is given (height filter, lateral axis without gravity)."""
    min_foot_height_m: float = 0.01
    """Foot pixels below this height above the floor are floor [m]."""
    max_foot_height_m: float = 0.5
    """A foot blob whose median height is above this is not a foot [m] (swing ≈ 0.2 m)."""
    keypoint_axis: Literal["u", "v"] = "v"
    """Image axis of eq. 4.1 (:mod:`gaitnet.segmentation.postprocess`)."""
    margin_top_px: int = 8
    """``M_t`` of eq. 4.1 [px]."""
    margin_bottom_px: int = 8
    """``M_b`` of eq. 4.1 [px]."""
    depth_radius_px: int = 6
    """Half side of the window whose valid depths give a keypoint's depth [px]. Dark shoes leave
    depth holes: with the committed segmenter on the default simulated session a 3 px radius
    found a depth for the mid keypoint of 27 of 61 feet, 6 px for 47 (10 px: 48)."""
    attach_px: int = 3
    """A leg blob within this many pixels of a foot blob is attached to it."""
    min_separation_m: float = 0.04
    """Two feet closer than this laterally are sided one by one [m]."""
    min_lateral_m: float = 0.0
    """A lone foot within this of the midline is sided by its leg [m]. 0 by default: on 50
    simulated frames (tiny.yaml, seed 900; 35 with one foot in view) the lateral position alone
    sided every foot right, while the leg rule (``min_lateral_m`` 10) got 11 of the 35 lone
    feet wrong: the lone foot's own leg is often out of view and the other leg touches it."""
    lateral_offset_m: float = 0.0
    """The body's midline along the camera's left axis [m] (a camera worn off-centre)."""
    forward_in_camera: tuple[float, float, float] | None = None
    """The body's forward as a direction in the camera frame (x right, y down, z along the
    optical axis; any length), which the left axis is made from
    (:mod:`gaitnet.segmentation.postprocess`); None: the optical axis, until ``gaitnet
    segment`` and ``gaitnet infer`` have estimated it from the first ``midline_frames`` frames
    (:mod:`gaitnet.segmentation.midline`)."""
    midline_frames: int = 30
    """``gaitnet segment`` and ``gaitnet infer`` estimate ``lateral_offset_m`` from the frames
    among the first this many where both feet are sided apart (standing at the start), and
    ``forward_in_camera`` from those with gravity known, and side the later frames with them
    (:mod:`gaitnet.segmentation.midline`); 0: never."""
    max_distance_m: float = 1.0
    """A foot whose mid point lies farther than this from the camera along the floor (measured
    perpendicular to up) is not a foot but something on the floor ahead that the segmenter took
    for one [m]: about one leg length, the most a foot can be from a waist-worn camera's hip;
    on the 30 simulated sessions of the filter's protocol the true shoe markers are at most
    0.58 m from the camera. Needs gravity or a floor; ``inf`` keeps every foot."""
    split_width_m: float = 0.15
    """A foot blob whose pixels spread wider than this along the left axis (5th to 95th
    percentile of their lateral positions) is two feet merged, split at Otsu's threshold of
    those positions [m]; 0: never split. A shoe is 9–11 cm wide and a segmenter's rim adds a
    few centimetres (one foot spreads < 0.13 m), two feet side by side at a step width of 0.1 m
    spread about 0.18 m."""
    min_area_m2: float = 0.0005
    """A foot blob smaller than this at its depth is not a shoe [m²]: its pixels' footprints
    ``z² / (f_x f_y)`` summed (pixels without depth at the blob's median depth). True feet
    labelled on 427 simulated frames (3 sessions, generated and CMU motion) measured
    0.0008–0.023 m², 0.0021 at the 1st percentile (a toe entering the view)."""
    max_area_m2: float = 0.1
    """A foot blob larger than this at its depth is not a shoe [m²] (a shoe's top is about
    0.03 m² and is seen obliquely; 4 times the largest simulated foot)."""
    floor: HhaParams = field(default_factory=HhaParams)
    """Floor fit settings when no plane is given (those of HHA)."""

    def __post_init__(self) -> None:
        check_range("min_area_fraction", self.min_area_fraction, 0.0, 0.5)
        check_range("min_leg_area_fraction", self.min_leg_area_fraction, 0.0, 0.5)
        check_range("max_depth_dev_m", self.max_depth_dev_m, 1e-3, 10.0, " m")
        check_range("min_consistent_fraction", self.min_consistent_fraction, 0.0, 1.0)
        check_int_range("min_depth_pixels", self.min_depth_pixels, 1, 10000)
        check_range("min_foot_height_m", self.min_foot_height_m, -1.0, 1.0, " m")
        check_range("max_foot_height_m", self.max_foot_height_m, self.min_foot_height_m, 5.0)
        if self.keypoint_axis not in ("u", "v"):
            raise ValueError(f"keypoint_axis must be 'u' or 'v', got {self.keypoint_axis!r}")
        for name in ("margin_top_px", "margin_bottom_px", "depth_radius_px", "attach_px"):
            check_int_range(name, getattr(self, name), 0 if name == "attach_px" else 1, 1000)
        check_range("min_separation_m", self.min_separation_m, 0.0, 10.0, " m")
        check_range("min_lateral_m", self.min_lateral_m, 0.0, 10.0, " m")
        check_range("lateral_offset_m", self.lateral_offset_m, -10.0, 10.0, " m")
        check_int_range("midline_frames", self.midline_frames, 0, 100_000)
        if self.forward_in_camera is not None:
            f = np.asarray(self.forward_in_camera, dtype=np.float64)
            if f.shape != (3,) or not np.all(np.isfinite(f)) or np.linalg.norm(f) < 1e-6:
                raise ValueError(
                    "forward_in_camera must be 3 finite numbers, not all 0, or null; got "
                    f"{list(np.ravel(f))}"
                )
            object.__setattr__(self, "forward_in_camera", tuple(float(v) for v in f))
        check_range("split_width_m", self.split_width_m, 0.0, 10.0, " m")
        check_range("min_area_m2", self.min_area_m2, 0.0, 1.0, " m²")
        check_range("max_area_m2", self.max_area_m2, self.min_area_m2, 100.0, " m²")
        if not self.max_distance_m > 0.1:  # also refuses NaN; inf is allowed
            raise ValueError(f"max_distance_m must be > 0.1 m, got {self.max_distance_m!r}")


@dataclass
class FootDetection:
    """One foot: side, eq. 4.1 keypoints in pixels ``(u, v)`` and in the camera frame [m]
    (``None`` where depth is missing), its pixel count, its lateral position [m] along the
    left axis (:mod:`gaitnet.segmentation.postprocess`), and its mask (H, W) bool."""

    side: Literal["left", "right", "unknown"]
    keypoints_px: dict[str, tuple[float, float]]
    keypoints_C: dict[str, np.ndarray | None]
    area_px: int
    lateral_m: float
    mask: np.ndarray

    @property
    def missing(self) -> tuple[str, ...]:
        """Keypoints without a 3-D point."""
        return tuple(k for k, p in self.keypoints_C.items() if p is None)
