"""The ``gaitnet infer`` config (docs/configs.md, *Inference*): one YAML tree over every stage.

``vio`` is the filter and smoother's whole config (:class:`~gaitnet.vio.config.VioConfig`),
``hha``, ``edge_refine`` and ``feet`` the segmenter's input encoding, the refinement of its
label maps and their post-processing (:class:`~gaitnet.segmentation.hha.HhaParams`,
:class:`~gaitnet.segmentation.edge_refine.EdgeRefineParams`,
:class:`~gaitnet.segmentation.postprocess.FootKeypointParams`), ``correction`` the pose
correction (:class:`~gaitnet.pipeline.pose_types.PoseCorrectionParams`), ``models`` the ONNX
files and ``pipeline`` how the stages are joined (:class:`PipelineParams`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar, Literal

from gaitnet.checks import check_int_range, check_range
from gaitnet.pipeline.pose_types import PoseCorrectionParams
from gaitnet.pipeline.swing_fill import (
    SWING_REST_END_LEAD_S,
    SWING_RETIME_MAX_SHIFT_S,
    SWING_RETIME_WEIGHT,
    SWING_SPAN_CONTRALATERAL_OFFSET_S,
    SWING_SPAN_OFFSET_S,
    SWING_SPAN_PER_CONTRALATERAL,
    SWING_SPAN_PER_CYCLE,
    SWING_START_DELAY_S,
)
from gaitnet.segmentation.edge_refine import EdgeRefineParams
from gaitnet.segmentation.hha import HhaParams
from gaitnet.segmentation.postprocess import FootKeypointParams
from gaitnet.vio.config import VioConfig

__all__ = [
    "KEYPOINT_OFFSET_M",
    "REFERENCE_HEIGHT_M",
    "InferConfig",
    "InferCorrectionParams",
    "ModelParams",
    "PipelineParams",
    "UNUSED_KEYS",
]

REFERENCE_HEIGHT_M = 1.70
"""Body height [m] for which the foot offsets (``correction.marker_offset_m``,
``pipeline.marker_offset_m``) are given; they scale with the subject's height (a shoe is about
0.15 of stature)."""

KEYPOINT_OFFSET_M = (0.0, -0.019, 0.116)
"""Where the segmenter's ``mid`` keypoint lies on a standing shoe, from the ankle (SMPL ankle
axes, at :data:`REFERENCE_HEIGHT_M`): measured with true label maps on the tuning session
S1_5m_t1 (seed 1000), stance frames: 10.6 cm forward and 1.8 cm below the ankle for its 1.54 m
subject."""


UNUSED_KEYS = (
    "hha.floor",
    "hha.no_imu_pitch_deg",
    "hha.no_imu_max_angle_deg",
    "hha.lowest_point_percentile",
    "feet.use_floor",
    "feet.floor",
)
"""Keys of the shared sections that mean nothing in ``gaitnet infer``: the floor fit and the
no-IMU fallbacks (the filter gives every frame's floor and gravity); refused unless at their
defaults."""


@dataclass(frozen=True)
class ModelParams:
    """The two networks (``None``: the committed small models, docs/segmenter.md and
    docs/predictor.md) and onnxruntime's threads."""

    segmenter: str | None = None
    """Segmenter ONNX file (``export/to_onnx.py segmenter``)."""
    predictor: str | None = None
    """Motion predictor ONNX file (``export/to_onnx.py predictor``)."""
    threads: int = 1
    """onnxruntime intra-op threads of each network (0: onnxruntime's default)."""
    segmenter_flip_average: bool = False
    """Average the segmenter's logits over each frame and its mirror image (twice the
    network's work; docs/segmenter.md, *Mirror averaging*)."""

    def __post_init__(self) -> None:
        check_int_range("models.threads", self.threads, 0, 64)


@dataclass(frozen=True)
class PipelineParams:
    """How the filter, the segmenter, the predictor and the correction are joined."""

    # keys of older configs (an ``infer_config.yaml`` of an earlier result) and what took
    # their place: named in the error instead of "unknown key"
    REPLACED_KEYS: ClassVar[dict[str, str]] = {
        "bridge_gaps": "gap_fill (swing | bridge | none; bridge_gaps: false was none)",
        "swing_heel_off_fraction": (
            "swing_span_offset_s: 0 and swing_span_per_cycle: <the old fraction> "
            "(the swing's span is offset + per_cycle · cycle)"
        ),
    }

    foot_keypoint: Literal["top", "mid", "bottom"] = "mid"
    """Which keypoint of eq. 4.1 is a foot's measured point (``mid``: the middle of the visible
    shoe, nearest the instep marker the pose correction's offset points to)."""
    toe_anchor: bool = True
    """With ``foot_keypoint: mid``, lay a foot's mid point from its toe (the ``top`` keypoint)
    where the leg hides the back of the shoe (:mod:`gaitnet.pipeline.toe_anchor`): a real
    walker's knee flexed through early stance moves the middle of the visible shoe 5–6 cm
    forward."""
    toe_anchor_window_s: float = 1.0
    """The moving average of the camera's heading that turns the standing toe → mid vector
    (about one stride, so the pelvis's rotation cancels) [s]."""
    toe_anchor_tolerance_m: float = 0.02
    """How much shorter along the floor than on the standing shoe the toe → mid vector must be
    before the mid point is laid from the toe [m]."""
    workers: int = 2
    """Threads that segment frames at once (HHA, the network and the post-processing of
    different frames overlap; each network call uses ``models.threads``)."""
    segmented_stances: bool = True
    """Run the filter a second time with the segmenter's foot pixels, so that a planted foot
    the depth image does not show (a toe in the stereo shadow of the near thigh, under a knee
    flexed in early stance) is a stance landmark too (:mod:`gaitnet.vio.feet_segmented`);
    false: the filter's first run, from depth alone, is the result."""
    segmented_stances_always: bool = False
    """With ``segmented_stances``: run the second pass on every session; false: only where
    the first run's landmarks show a missed stance (:mod:`gaitnet.pipeline.stance_gaps`),
    since where they hold every stance it has nothing to find."""
    hidden_stances: bool = True
    """Lay the stances the camera never saw from the rhythm of the steps: each dip of the
    camera's height while walking is a step, and a step with no landmark between two with one
    gets a stance of the alternating side, between theirs along the walking line
    (:mod:`gaitnet.pipeline.hidden_stances`; ``inferred`` in ``strides.csv``); false: the
    filter's landmarks only."""
    step_dip_m: float = 0.008
    """With ``hidden_stances``: the least prominence of a dip of the camera's height that
    marks a step [m] (a walk's dips: 2–5 cm; the height's noise after the smoother: ~1 mm)."""
    min_foot_seen_fraction: float = 0.2
    """A result where a foot was measured in fewer of the frames than this (either side) is
    marked unreliable (``"reliable": false`` in ``summary.json``): too few plausible feet to
    measure the gait (simulated walks: 0.59–0.80 per side); 0: never."""
    subject_height_m: float = 0.0
    """Body height for the anthropometric skeleton [m]; 0: from the standing camera height
    (``camera_height_fraction``)."""
    camera_height_fraction: float = 0.62
    """Height of a waist-worn camera above the floor as a fraction of body height (a belt at
    the waist, above the hip joints' 0.53 of stature in Winter's tables; the simulator's mounts
    give 0.60–0.65 over the 30 sessions of the filter's protocol)."""
    standing_s: float = 1.0
    """At most this long at the start is used as the standing phase for the camera-to-pelvis
    extrinsic [s]."""
    standing_max_speed_mps: float = 0.05
    """Frames whose camera moves faster than this end the standing phase [m/s]."""
    standing_feet_behind_camera_m: float = 0.10
    """Only when neither foot is seen while standing (by the segmenter, or by the filter as a
    stance landmark then): the standing feet's midpoint lies this far behind the camera along
    its horizontal viewing direction [m] (a belly-worn camera ahead of the insteps; the
    simulator's subjects give 0.09–0.11 m where the feet are seen)."""
    gap_fill: Literal["swing", "bridge", "none"] = "swing"
    """Correct the poses a second time with the frames where a foot is not seen filled in:
    ``swing``: between two stance landmarks of that foot, the template swing from one rest to
    the next (:mod:`gaitnet.pipeline.swing_fill`), elsewhere as ``bridge``; ``bridge``: the
    first pass's foot, bridged to the frame where the foot is seen again
    (:mod:`gaitnet.pipeline.gap_bridge`); ``none``: the first pass only."""
    swing_span_offset_s: float = SWING_SPAN_OFFSET_S
    """For ``gap_fill: swing``: the template swing starts ``swing_span_offset_s +
    swing_span_per_cycle · T`` before the next foot flat, ``T`` the gait cycle [s] (the gait
    generator's swings, ``data/derive_swing_template.py``: 0.74 of a 1.1 s cycle, 0.69 of a
    1.8 s one)."""
    swing_span_per_cycle: float = SWING_SPAN_PER_CYCLE
    """See ``swing_span_offset_s``."""
    swing_span_contralateral_offset_s: float = SWING_SPAN_CONTRALATERAL_OFFSET_S
    """For ``gap_fill: swing``, where the other foot has one stance landmark between the
    swing's two rests, first seen ``C`` seconds before the next foot flat (0.3–0.7 of the
    cycle): the span is ``swing_span_contralateral_offset_s + swing_span_per_contralateral · C``
    instead (the foot leaves the floor as the double support the other foot's landing begins
    ends; the gait generator's swings, ``data/derive_swing_template.py``)."""
    swing_span_per_contralateral: float = SWING_SPAN_PER_CONTRALATERAL
    """See ``swing_span_contralateral_offset_s``; 0: every swing's span from its cycle."""
    swing_start_delay_s: float = SWING_START_DELAY_S
    """For ``gap_fill: swing``: the start that ``swing_span_*`` give is laid this much later
    [s]; 0 by default: 0.05 s fills real walks worse, and with the keypoint's template the 7
    held-out simulated sessions too (:mod:`gaitnet.pipeline.swing_fill`, docs/pipeline.md)."""
    swing_rest_end_lead_s: float = SWING_REST_END_LEAD_S
    """For ``gap_fill: swing``: the timing lines' start is never earlier than this before the
    last frame the filter saw the foot resting [s] (the right foot's landmark outlasts heel off,
    the rising heel still giving a stationary point; the re-timing may move the start earlier;
    :mod:`gaitnet.pipeline.swing_fill`, docs/pipeline.md)."""
    swing_retime_weight: float = SWING_RETIME_WEIGHT
    """For ``gap_fill: swing`` (a foot's first pair too): where the foot is seen again before it
    lands, the template's time at its measured progress (0.5–0.97 of the way) gives the swing's
    start too (their median); the start moves this share of the way to it (0: off; 0.5: the
    two estimates averaged; :mod:`gaitnet.pipeline.swing_fill`)."""
    swing_retime_max_shift_s: float = SWING_RETIME_MAX_SHIFT_S
    """The start read where the foot is seen again is kept within this of the timing line's
    (or of the bound the rest's last frame sets) [s]."""
    marker_offset_m: tuple[float, float, float] = (0.0, -0.011, 0.079)
    """The reported foot point (``feet.csv``, the foot trajectories): the shoe marker over the
    instep, in the ankle frame (SMPL axes: x left, y up, z forward; mirrored for the right
    foot) for a body of :data:`REFERENCE_HEIGHT_M`, scaled by the body height [m]. The
    default is the simulator's instep marker (tuning session S1_5m_t1, seed 1000)."""

    def __post_init__(self) -> None:
        if self.foot_keypoint not in ("top", "mid", "bottom"):
            raise ValueError(
                f"pipeline.foot_keypoint must be top, mid or bottom, got {self.foot_keypoint!r}"
            )
        check_int_range("pipeline.workers", self.workers, 1, 64)
        check_range("pipeline.toe_anchor_window_s", self.toe_anchor_window_s, 0.0, 10.0, " s")
        check_range("pipeline.toe_anchor_tolerance_m", self.toe_anchor_tolerance_m, 0.0, 0.2, " m")
        check_range("pipeline.step_dip_m", self.step_dip_m, 0.001, 0.1, " m")
        check_range("pipeline.min_foot_seen_fraction", self.min_foot_seen_fraction, 0.0, 1.0)
        if self.gap_fill not in ("swing", "bridge", "none"):
            raise ValueError(
                f"pipeline.gap_fill must be swing, bridge or none, got {self.gap_fill!r}"
            )
        check_range("pipeline.swing_span_offset_s", self.swing_span_offset_s, 0.0, 0.5, " s")
        check_range("pipeline.swing_span_per_cycle", self.swing_span_per_cycle, 0.3, 0.95)
        check_range(
            "pipeline.swing_span_contralateral_offset_s",
            self.swing_span_contralateral_offset_s, 0.0, 0.5, " s",
        )  # fmt: skip
        if self.swing_span_per_contralateral != 0:
            check_range(
                "pipeline.swing_span_per_contralateral",
                self.swing_span_per_contralateral, 0.5, 2.5, " (or 0: off)",
            )  # fmt: skip
        check_range("pipeline.swing_start_delay_s", self.swing_start_delay_s, -0.2, 0.2, " s")
        check_range("pipeline.swing_rest_end_lead_s", self.swing_rest_end_lead_s, 0.0, 0.3, " s")
        check_range("pipeline.swing_retime_weight", self.swing_retime_weight, 0.0, 1.0)
        check_range(
            "pipeline.swing_retime_max_shift_s", self.swing_retime_max_shift_s, 0.0, 0.5, " s"
        )
        if self.subject_height_m != 0:
            check_range("pipeline.subject_height_m", self.subject_height_m, 0.8, 2.3, " m")
        check_range("pipeline.camera_height_fraction", self.camera_height_fraction, 0.3, 0.8)
        check_range("pipeline.standing_s", self.standing_s, 0.1, 10.0, " s")
        check_range("pipeline.standing_max_speed_mps", self.standing_max_speed_mps, 0.0, 1.0)
        check_range(
            "pipeline.standing_feet_behind_camera_m",
            self.standing_feet_behind_camera_m, -0.5, 0.5, " m",
        )  # fmt: skip
        if len(self.marker_offset_m) != 3:
            raise ValueError("pipeline.marker_offset_m must be three numbers [m]")
        for value in self.marker_offset_m:
            check_range("pipeline.marker_offset_m", value, -0.3, 0.3, " m")

    def swing_timing(self) -> dict[str, float]:
        """The ``swing_*`` keys as the keyword arguments of
        :func:`~gaitnet.pipeline.swing_fill.swing_fill` and
        :func:`~gaitnet.pipeline.swing_fill.plan_swings`."""
        return {
            "span_offset_s": self.swing_span_offset_s,
            "span_per_cycle": self.swing_span_per_cycle,
            "span_contralateral_offset_s": self.swing_span_contralateral_offset_s,
            "span_per_contralateral": self.swing_span_per_contralateral,
            "retime_weight": self.swing_retime_weight,
            "retime_max_shift_s": self.swing_retime_max_shift_s,
            "start_delay_s": self.swing_start_delay_s,
            "rest_end_lead_s": self.swing_rest_end_lead_s,
        }


@dataclass(frozen=True)
class InferCorrectionParams(PoseCorrectionParams):
    """The pose correction's settings in ``gaitnet infer``: those of
    :class:`~gaitnet.pipeline.pose_types.PoseCorrectionParams`, but the foot point is the
    segmenter's keypoint, so ``marker_offset_m`` defaults to :data:`KEYPOINT_OFFSET_M` and is
    given for a body of :data:`REFERENCE_HEIGHT_M` (scaled by the subject's height)."""

    marker_offset_m: tuple[float, float, float] = KEYPOINT_OFFSET_M


@dataclass(frozen=True)
class InferConfig:
    """The whole ``gaitnet infer`` config (module docstring)."""

    vio: VioConfig = field(default_factory=VioConfig)
    models: ModelParams = field(default_factory=ModelParams)
    hha: HhaParams = field(default_factory=HhaParams)
    edge_refine: EdgeRefineParams = field(default_factory=EdgeRefineParams)
    feet: FootKeypointParams = field(default_factory=FootKeypointParams)
    correction: InferCorrectionParams = field(default_factory=lambda: InferCorrectionParams())
    """The correction (eq. 4.7–4.8)."""
    pipeline: PipelineParams = field(default_factory=PipelineParams)

    def __post_init__(self) -> None:
        defaults = {"hha": HhaParams(), "feet": FootKeypointParams()}
        for key in UNUSED_KEYS:
            section, name = key.split(".")
            if getattr(getattr(self, section), name) != getattr(defaults[section], name):
                raise ValueError(
                    f"{key} has no effect in gaitnet infer (the filter gives the floor and "
                    "gravity); leave it at its default"
                )
