"""``gaitnet infer``: the filter, the segmenter, the predictor and the pose correction joined
(thesis sec. 4.1.4, 4.2.4, 5.2.2–5.2.3; docs/pipeline.md).

1. The filter and smoother (:func:`gaitnet.vio.run.run_vio`): camera trajectory, stance feet,
   strides.
2. Per processed frame, while the filter goes on (:func:`observe`), the measured foot points
   in the world (:func:`gaitnet.pipeline.foot_points.measure_feet`, HHA with the filter's
   gravity and floor), moved to the smoothed camera pose once the smoother has run.
3. The standing phase at the start (the camera still, at most ``pipeline.standing_s``) gives the
   subject's skeleton (body height from the camera height unless configured) and the
   camera-to-pelvis extrinsic (:mod:`gaitnet.pipeline.pelvis_extrinsic`): the standing skeleton
   is placed on the measured feet, facing the camera's direction.
4. Predict and correct, frame by frame: the motion predictor (ONNX, 10 past poses → the next,
   heading-normalised as in training) gives the prior, which the correction (eq. 4.7–4.8,
   :func:`gaitnet.pipeline.pose_correction.correct_pose`) pulls towards the pelvis pose from the
   filter, the measured feet and, with ``correction.contact_weighting``, the stance intervals of
   the filter's stance feet. The first 10 poses are the standing pose. Unless
   ``pipeline.gap_fill`` is ``none`` the correction runs a second time with each foot's unseen
   frames measured: between two stance landmarks of the foot at a template swing from one
   rest to the next (``swing``, :mod:`gaitnet.pipeline.swing_fill`), elsewhere (and
   everywhere with ``bridge``) at the first pass's foot path bridged to where the foot is seen
   again (:mod:`gaitnet.pipeline.gap_bridge`); the first pass runs only as far as those
   bridges need it (:func:`gaitnet.pipeline.gap_bridge.frames_to_bridge`).
5. Forward kinematics give the joints, and the shoe markers (ankle plus the correction's marker
   offset) the gap-free foot trajectories: measured frames and frames filled in
   are flagged.
"""

from __future__ import annotations

import logging
import time
from collections import Counter, deque
from collections.abc import Callable, Iterable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import cast

import numpy as np

from gaitnet.errors import InputError, SessionError
from gaitnet.geometry import so3_log
from gaitnet.io.types import Frame, SessionSource
from gaitnet.motion.amass import TARGET_FPS
from gaitnet.motion.onnx_runtime import OnnxPredictor
from gaitnet.motion.skeleton import LowerBodySkeleton, builtin_skeleton, forward_kinematics
from gaitnet.pipeline.config import REFERENCE_HEIGHT_M, InferConfig, PipelineParams
from gaitnet.pipeline.foot_points import FrameFeet, measure_feet
from gaitnet.pipeline.foot_sides import reside_measured_feet
from gaitnet.pipeline.gap_bridge import bridge_gaps, frames_to_bridge
from gaitnet.pipeline.hidden_stances import with_hidden_stances
from gaitnet.pipeline.pelvis_extrinsic import (
    PelvisExtrinsic,
    complete_standing_feet,
    estimate_T_PfromC,
    pelvis_from_camera,
    standing_feet,
    standing_frames,
    standing_T_WfromP,
)
from gaitnet.pipeline.pose_residuals import ChainGeometry, foot_points
from gaitnet.pipeline.pose_tracking import track_poses
from gaitnet.pipeline.pose_types import FrameMeasurements, PoseState, R_PfromSMPL
from gaitnet.pipeline.stance_gaps import stance_missed
from gaitnet.pipeline.swing_fill import swing_fill
from gaitnet.pipeline.toe_anchor import heading_angles, toe_anchored_points
from gaitnet.segmentation.midline import MidlineEstimate
from gaitnet.segmentation.onnx_runtime import OnnxSegmenter
from gaitnet.segmentation.postprocess import FootKeypointParams
from gaitnet.vio.errors import FilterDivergedError
from gaitnet.vio.feet_segmented import FootMask
from gaitnet.vio.result import VioResult
from gaitnet.vio.run import run_vio

log = logging.getLogger(__name__)

__all__ = [
    "DEFAULT_PREDICTOR",
    "InferResult",
    "Observations",
    "default_predictor_path",
    "observe",
    "reconstruct",
    "run_infer",
]

Progress = Callable[[Iterable, int], Iterable]
SIDES = ("left", "right")

DEFAULT_PREDICTOR = "dctgcn_walk_small.onnx"
"""File name of the committed small motion predictor in the repository's ``models/predictor/``."""


HEIGHT_RANGE_M = (1.2, 2.1)
"""Body heights the standing camera's height may give (adults and teenagers); outside it the
camera is not where ``pipeline.camera_height_fraction`` assumes (a simulated camera worn 25 cm
above the waist gave 2.18 m, clipped to 2.10: MPJPE 9.8 cm; with ``pipeline.subject_height_m``
3.4 cm)."""


def default_predictor_path() -> Path:
    """The committed small predictor (docs/predictor.md); an :class:`InputError` naming the path
    when it is missing (an install without the repository's ``models/``)."""
    path = Path(__file__).resolve().parents[2] / "models" / "predictor" / DEFAULT_PREDICTOR
    if not path.is_file():
        raise InputError(f"{path}: the default motion predictor is missing; give --predictor")
    return path


@dataclass
class InferResult:
    """Everything ``gaitnet infer`` computed, at the frames the filter processed.

    ``t_s`` (n,) frame times, ``poses`` (n, 21) in the predictor's node layout and ``trans``
    (n, 3) the corrected SMPL poses; ``joints_W`` (n, 9, 3) SMPL joints [0, 1, 2, 4, 5, 7, 8,
    10, 11] (the layout of ``groundtruth/joints.npz``); ``feet_W`` (n, 2, 3) the shoe markers
    of the corrected pose (left, right), ``foot_measured`` (n, 2) whether the segmenter saw
    each foot, ``foot_measured_W`` (n, 2, 3) the measured points (NaN where not seen);
    ``contact`` (n, 2) the filter's stance flags; ``feet_dropped`` the foot blobs dropped as
    no foot, by reason; ``unreliable`` why the result cannot be trusted (the scene check's
    problems under ``--force``, a foot seen in fewer than ``pipeline.min_foot_seen_fraction``
    of the frames; empty: nothing known).
    """

    vio: VioResult
    t_s: np.ndarray
    t_ns: np.ndarray
    poses: np.ndarray
    trans: np.ndarray
    joints_W: np.ndarray
    feet_W: np.ndarray
    foot_measured: np.ndarray
    foot_measured_W: np.ndarray
    contact: np.ndarray
    skeleton: LowerBodySkeleton
    subject_height_m: float
    extrinsic: PelvisExtrinsic
    standing_frames: int
    segmenter_path: str
    predictor_path: str
    timings_s: dict[str, float] = field(default_factory=dict)
    feet_dropped: dict[str, int] = field(default_factory=dict)
    unreliable: list[str] = field(default_factory=list)


def _contact(vio: VioResult, t_s: np.ndarray) -> np.ndarray:
    """(n, 2) 1 where the filter saw that foot resting on the floor (a stance landmark)."""
    c = np.zeros((len(t_s), 2))
    for foot in vio.stance_feet:
        if foot.side in SIDES:
            inside = (t_s >= foot.t_first_s - 1e-6) & (t_s <= foot.t_last_s + 1e-6)
            c[inside, SIDES.index(foot.side)] = 1.0
    return c


def _initial_pose(T_WfromP: np.ndarray, skeleton: LowerBodySkeleton) -> PoseState:
    root = so3_log(T_WfromP[:3, :3] @ R_PfromSMPL)
    return PoseState(
        pose=np.concatenate([root, np.zeros(18)]),
        trans=T_WfromP[:3, 3] - skeleton.rest_joints[0],
    )


@dataclass
class Observations:
    """Steps 1–2 of :func:`run_infer`: the filter's result and, per processed frame, the frame
    time ``t_ns`` (n,) and the measured world foot points ``foot_W`` (n, 2, 3) (NaN where not
    seen), with the wall-clock seconds of each stage and the foot blobs the post-processing
    dropped as no foot, by reason."""

    vio: VioResult
    t_ns: np.ndarray
    foot_W: np.ndarray
    segmenter_path: str
    timings_s: dict[str, float] = field(default_factory=dict)
    feet_dropped: Counter = field(default_factory=Counter)
    toe_W: np.ndarray | None = None


def observe(
    session: SessionSource,
    cfg: InferConfig,
    segmenter: OnnxSegmenter,
    progress: Callable[[str], Progress] | None = None,
    keep_labels: Callable[[int, np.ndarray], None] | None = None,
) -> Observations:
    """Steps 1–2 (module docstring), side by side: the filter hands each frame it has processed,
    with its camera pose, to ``pipeline.workers`` segmentation threads (onnxruntime, OpenCV and
    most of numpy release the GIL) and goes on; HHA takes the filter's gravity and floor. At
    most ``2 × workers`` frames wait, so the filter is held back when the segmenter lags. With
    ``pipeline.segmented_stances`` the filter then runs again where its landmarks show a
    missed stance (:mod:`gaitnet.pipeline.stance_gaps`; on every session with
    ``pipeline.segmented_stances_always``), handed the segmenter's foot pixels of every frame
    (:func:`gaitnet.vio.run.run_vio` ``foot_masks``), and its second result is the one kept.
    Each measured foot point is moved from the first run's filter camera pose to the result's
    (smoothed) one (``T_s T_f⁻¹``: the point stays where it is in the camera frame).

    ``timings_s``: ``filter`` (wall seconds of the filter and smoother, the segmentation
    running beside it), ``segmenter_wait`` (wall seconds spent on the last frames after the
    filter), ``segmenter_cpu`` (CPU seconds of the segmentation threads, summed),
    ``filter_segmented`` (wall seconds of the second run, when there is one).
    """
    timings: dict[str, float] = {"segmenter_cpu": 0.0}
    masks: dict[int, FootMask] = {}
    dropped: Counter = Counter()

    def bar(stage: str) -> Progress | None:
        return progress(stage) if progress is not None else None

    K = session.calibration.color.K
    workers = cfg.pipeline.workers
    T_filter: list[np.ndarray] = []
    feet_f: list[np.ndarray] = []
    toes_f: list[np.ndarray] = []
    frame_ns: list[int] = []
    pending: deque[Future] = deque()

    midline = MidlineEstimate(cfg.feet)
    feet_params = [cfg.feet]  # the later frames': once the first have given the midline

    def one(
        frame: Frame, T_WfromC: np.ndarray, params: FootKeypointParams
    ) -> tuple[int, FrameFeet, float]:
        tic = time.thread_time()
        feet = measure_feet(
            frame, K, T_WfromC, segmenter, cfg.pipeline.foot_keypoint, cfg.hha, params
        )
        return frame.t_ns, feet, time.thread_time() - tic

    def take_until(n_left: int) -> None:
        while len(pending) > n_left:
            t_ns, feet, cpu_s = pending.popleft().result()
            midline.add(feet.pair_midpoint_m, up_C=T_filter[len(feet_f)][2, :3])
            feet_f.append(feet.foot_W)
            toes_f.append(feet.top_W)
            frame_ns.append(t_ns)
            dropped.update(feet.dropped)
            if feet.foot_mask is not None and cfg.pipeline.segmented_stances:
                masks[t_ns] = feet.foot_mask
            timings["segmenter_cpu"] += cpu_s
            if keep_labels is not None:
                keep_labels(t_ns, feet.labels)

    pool = ThreadPoolExecutor(max_workers=workers)
    try:

        def on_frame(frame: Frame, T_WfromC: np.ndarray) -> None:
            if len(T_filter) == cfg.feet.midline_frames:  # the first frames are all in
                take_until(0)
                feet_params[0] = midline.params()
                if midline.offset_m is not None:
                    log.info(
                        "body midline %.3f m left of the camera (from %d frames with both feet)",
                        midline.offset_m, len(midline.midpoints),
                    )  # fmt: skip
                if feet_params[0].forward_in_camera is not None:
                    log.info(
                        "body forward in the camera frame %s",
                        np.round(feet_params[0].forward_in_camera, 3).tolist(),
                    )
            T_filter.append(T_WfromC.copy())
            pending.append(pool.submit(one, frame, T_WfromC.copy(), feet_params[0]))
            take_until(2 * workers)

        t0 = time.perf_counter()
        vio = run_vio(session, cfg.vio, progress=bar("filter"), on_frame=on_frame)
        timings["filter"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        take_until(0)
        timings["segmenter_wait"] = time.perf_counter() - t0
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
    n = len(vio.t_s)
    if n < 2:
        raise SessionError(f"the filter processed {n} frame(s); need at least 2")
    if len(feet_f) != n:  # run_vio calls on_frame once per processed frame
        raise RuntimeError(f"segmented {len(feet_f)} frames, the filter processed {n}")
    if masks and (cfg.pipeline.segmented_stances_always or stance_missed(vio.stance_feet)):
        t0 = time.perf_counter()
        vio = _run_with_masks(session, cfg, vio, masks, bar("filter, segmented feet"))
        timings["filter_segmented"] = time.perf_counter() - t0
    elif masks:
        log.info("the filter's landmarks miss no stance: no second run with the segmented feet")
    if cfg.pipeline.hidden_stances:
        vio = with_hidden_stances(
            vio, cfg.pipeline.step_dip_m, cfg.vio.stance.line_window_s,
            (cfg.vio.gait.max_stride_time_s, cfg.vio.gait.max_stance_time_s),
        )  # fmt: skip
    T_f = np.array(T_filter)
    T_move = vio.T_WfromC @ np.linalg.inv(T_f)  # filter pose → smoothed pose, per frame
    measured, toes = (
        np.einsum("kij,ksj->ksi", T_move[:, :3, :3], np.array(points)) + T_move[:, None, :3, 3]
        for points in (feet_f, toes_f)
    )
    return Observations(
        vio, np.array(frame_ns, np.int64), measured, str(segmenter.path), timings, dropped,
        toes,
    )  # fmt: skip


def _run_with_masks(
    session: SessionSource,
    cfg: InferConfig,
    first: VioResult,
    masks: dict[int, FootMask],
    progress: Progress | None,
) -> VioResult:
    """The filter's run handed the segmenter's foot pixels ``masks``
    (``pipeline.segmented_stances``), or ``first`` with a warning when that run fails or
    processes other frames."""
    try:
        again = run_vio(session, cfg.vio, progress=progress, foot_masks=masks)
    except (FilterDivergedError, SessionError) as exc:
        log.warning("the filter's run with the segmented feet failed (%s); the first is kept", exc)
        return first
    if not np.array_equal(again.t_s, first.t_s):  # both refuse the same frames: never seen
        log.warning(
            "the filter's run with the segmented feet processed other frames than the first "
            "(%d against %d); the first is kept",
            len(again.t_s), len(first.t_s),
        )  # fmt: skip
        return first
    return again


def run_infer(
    session: SessionSource,
    cfg: InferConfig,
    segmenter: OnnxSegmenter,
    predictor: OnnxPredictor,
    progress: Callable[[str], Progress] | None = None,
    keep_labels: Callable[[int, np.ndarray], None] | None = None,
) -> InferResult:
    """Run the whole pipeline on ``session`` (module docstring).

    ``progress(stage)`` returns a progress wrapper for the stage's iterable (``"filter"``,
    ``"segmenter"``, ``"pose"``); ``keep_labels(t_ns, labels)`` receives each label map.
    """
    obs = observe(session, cfg, segmenter, progress, keep_labels)
    return reconstruct(obs, cfg, predictor, progress)


def _toe_anchored(obs: Observations, params: PipelineParams, n_standing: int) -> np.ndarray:
    """The measured foot points with those whose shoe back the leg hides laid from the toe
    (``pipeline.toe_anchor``, :mod:`gaitnet.pipeline.toe_anchor`)."""
    if not params.toe_anchor or params.foot_keypoint != "mid" or obs.toe_W is None:
        return obs.foot_W
    vio = obs.vio
    psi = heading_angles(vio.T_WfromC, vio.t_s, params.toe_anchor_window_s)
    points, laid = toe_anchored_points(
        obs.foot_W, obs.toe_W, psi, n_standing, params.toe_anchor_tolerance_m
    )
    log.info("%d measured foot points laid from the toe (the shoe's back hidden)", laid)
    return points


def reconstruct(
    obs: Observations,
    cfg: InferConfig,
    predictor: OnnxPredictor,
    progress: Callable[[str], Progress] | None = None,
) -> InferResult:
    """Steps 3–5 (module docstring) from the observations of :func:`observe`."""
    vio, t_ns = obs.vio, obs.t_ns
    T_WfromC = vio.T_WfromC
    n_standing = standing_frames(
        vio.t_s, T_WfromC, cfg.pipeline.standing_s, cfg.pipeline.standing_max_speed_mps
    )
    measured, resided = reside_measured_feet(
        vio.t_s, _toe_anchored(obs, cfg.pipeline, n_standing), vio.stance_feet
    )
    if resided:
        log.info("%d measured foot points lay at the other foot's rest: given to it", resided)
    timings = dict(obs.timings_s)
    n = len(vio.t_s)

    def bar(stage: str) -> Progress | None:
        return progress(stage) if progress is not None else None

    height = cfg.pipeline.subject_height_m
    if height == 0:
        camera_height = float(np.median(T_WfromC[:n_standing, 2, 3]))
        estimate = camera_height / cfg.pipeline.camera_height_fraction
        height = float(np.clip(estimate, *HEIGHT_RANGE_M))
        if height != estimate:
            log.warning(
                "the camera stands %.2f m above the floor: worn at the waist that is a body of "
                "%.2f m, taken as %.2f m; a camera worn higher or lower (chest, hip) needs "
                "pipeline.subject_height_m",
                camera_height, estimate, height,
            )  # fmt: skip
    skeleton = builtin_skeleton(height)
    scale = height / REFERENCE_HEIGHT_M
    correction = replace(
        cfg.correction, marker_offset_m=tuple(scale * np.array(cfg.correction.marker_offset_m))
    )
    marker_height = 0.039 * height + correction.marker_offset_m[1]  # ankle height + offset
    foot0 = standing_feet(measured, vio, marker_height, n_standing)
    foot0, note = complete_standing_feet(
        foot0, skeleton, T_WfromC[0], marker_height,
        cfg.pipeline.standing_feet_behind_camera_m, correction,
    )  # fmt: skip
    if note is not None:
        log.warning("%s", note)
    T_WfromP0 = standing_T_WfromP(skeleton, foot0, T_WfromC[0], params=correction)
    extrinsic = estimate_T_PfromC(T_WfromC[:n_standing], T_WfromP0)
    T_WfromP = pelvis_from_camera(T_WfromC, extrinsic.T_PfromC)
    contact = _contact(vio, vio.t_s)

    t0 = time.perf_counter()
    n_past = predictor.n_past or 10
    start = [_initial_pose(T_WfromP[0], skeleton)] * n_past
    frames = [
        FrameMeasurements(
            R_WfromP=T_WfromP[k, :3, :3],
            p_PinW=T_WfromP[k, :3, 3],
            foot_W=measured[k],
            contact=contact[k],
        )
        for k in range(n)
    ]

    def predict(window: np.ndarray) -> np.ndarray:
        return predictor.predict_future(window[None].astype(np.float32))[0].astype(np.float64)

    dt = 1.0 / TARGET_FPS  # the predictor's training rate: its window is resampled to it

    def track(stage: str, measurements: list[FrameMeasurements]) -> tuple[np.ndarray, ...]:
        m = len(measurements)
        wrap = bar(stage)
        # track_poses only iterates over its measurements, so a progress bar may wrap them
        shown = measurements if wrap is None else cast(list, wrap(measurements, m))
        corrected, _ = track_poses(predict, start, shown, skeleton, correction, vio.t_s[:m], dt)
        return np.stack([c.pose for c in corrected]), np.stack([c.trans for c in corrected])

    fill = cfg.pipeline.gap_fill
    seen = ~np.isnan(measured[:, :, 0])
    swing = np.full(measured.shape, np.nan)
    if fill == "swing":
        swing = swing_fill(
            vio.t_s, measured, vio.stance_feet, height, **cfg.pipeline.swing_timing()
        )
    by_swing = ~np.isnan(swing[:, :, 0])
    # the first pass only as far as the bridges of the second need it (none: it is the result)
    m = frames_to_bridge(seen, by_swing) if fill != "none" else n
    if m == 0 and not by_swing.any():
        m = n  # nothing to fill in
    if m > 0:
        poses, trans = track("pose", frames[:m])
    if fill != "none":
        filled = swing.copy()
        if m > 0:
            # the measured points' geometry, with the skeleton's lengths as the outputs use
            geometry = ChainGeometry.build(skeleton, correction)
            bridged = bridge_gaps(foot_points(geometry, poses, trans), seen[:m])
            filled[:m] = np.where(by_swing[:m, :, None], swing[:m], bridged)
        use = ~np.isnan(filled[:, :, 0])
        if use.any():
            feet = np.where(use[:, :, None], filled, measured)
            poses, trans = track(
                "pose, gaps filled", [replace(f, foot_W=feet[k]) for k, f in enumerate(frames)]
            )
    timings["pose"] = time.perf_counter() - t0
    assert len(poses) == n, "a first pass cut short is always followed by the second"

    aa = np.concatenate([poses[:, 3:].reshape(n, 6, 3), np.zeros((n, 2, 3))], axis=1)
    joints = forward_kinematics(skeleton, poses[:, :3], trans, aa)
    marker = replace(
        correction,
        marker_offset=True,
        marker_offset_m=tuple(scale * np.array(cfg.pipeline.marker_offset_m)),
    )
    feet_W = foot_points(ChainGeometry.build(skeleton, marker), poses, trans)
    log.info(
        "standing phase %d frames; body height %.2f m; extrinsic spread %.1f mm / %.2f°; "
        "first correction pass over %d of %d frames",
        n_standing,
        height,
        1e3 * extrinsic.spread_pos_m,
        np.degrees(extrinsic.spread_rot_rad),
        m,
        n,
    )
    return InferResult(
        vio=vio,
        t_s=vio.t_s.copy(),
        t_ns=t_ns,
        poses=poses,
        trans=trans,
        joints_W=joints,
        feet_W=feet_W,
        foot_measured=~np.isnan(measured[:, :, 0]),
        foot_measured_W=measured,
        contact=contact,
        skeleton=skeleton,
        subject_height_m=height,
        extrinsic=extrinsic,
        standing_frames=n_standing,
        segmenter_path=obs.segmenter_path,
        predictor_path=str(predictor.path),
        timings_s=timings,
        feet_dropped=dict(sorted(obs.feet_dropped.items())),
        unreliable=vio.unreliable + _too_few_feet(measured, cfg.pipeline.min_foot_seen_fraction),
    )


def _too_few_feet(measured: np.ndarray, min_fraction: float) -> list[str]:
    """A reason to distrust the result when a foot was measured in fewer than
    ``min_fraction`` of the frames (``measured`` (n, 2, 3), NaN where not seen)."""
    seen = np.mean(np.isfinite(measured[:, :, 0]), axis=0)
    low = [f"{side} {100 * f:.0f} %" for side, f in zip(SIDES, seen, strict=True)]
    if np.all(seen >= min_fraction):
        return []
    return [f"feet measured in too few frames ({', '.join(low)}; need {100 * min_fraction:.0f} %)"]
