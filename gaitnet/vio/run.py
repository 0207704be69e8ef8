"""``run_vio``: the filter over a whole session, then the smoother and the gait parameters.

Per frame (thesis Algorithm 1, with the tag update in the loop as thesis-notes says):

1. IMU propagation to the frame time (:mod:`gaitnet.vio.imu_propagation`);
2. visual-odometry update between the previous and this frame, seeded with the IMU-predicted
   relative pose (:mod:`gaitnet.vio.odometry`, :mod:`gaitnet.vio.vo_model`);
3. AprilTag update when a board is in view (:mod:`gaitnet.vio.apriltags`,
   :mod:`gaitnet.vio.tag_model`);
4. floor plane and stance-foot candidates (:mod:`gaitnet.geometry.floor_plane`,
   :mod:`gaitnet.vio.feet`),
   grouped into stances and sides (:mod:`gaitnet.vio.stance_tracker`); a new stance augments
   the state with a landmark, a continuing one updates it (:mod:`gaitnet.vio.foot_model`), a
   finished one is marginalised;
5. stochastic cloning of the pose for the next frame's odometry; a health check (a NaN or a
   covariance that is not positive semi-definite stops the run with one clear error).

Every accepted measurement, the IMU interval between frames and the initialisation are
recorded (:class:`~gaitnet.vio.records.FilterRecorder`); after the last frame the smoother
(thesis sec. 3.5, :mod:`gaitnet.vio.smoother`) re-estimates all frames, the biases and the
stance-foot landmarks from that record, and the gait parameters are computed from the
smoothed landmarks (the filter's are kept beside them). A smoother that fails (a
non-finite residual, an unconstrained variable) is logged and the filter's estimates are
reported instead, with the reason in the summary.

A measurement that cannot be made or fails its χ² gate is skipped, and counted with its reason
in :class:`~gaitnet.vio.result.VioResult`; so is a frame before the initialising one or one
whose time does not advance. An IMU-only dead-reckoning run from the same initial state is
kept as a baseline.
"""

from __future__ import annotations

import logging
import re
import time
from collections import Counter
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from gaitnet.errors import SessionError
from gaitnet.geometry import make_T
from gaitnet.geometry.floor_plane import fit_floor_depth
from gaitnet.io.types import Frame, SessionSource, require_depth_aligned
from gaitnet.vio import covariance
from gaitnet.vio.config import VioConfig
from gaitnet.vio.errors import FilterDivergedError
from gaitnet.vio.feet import detect_foot_candidates
from gaitnet.vio.feet_segmented import FootMask, segmented_foot_candidates
from gaitnet.vio.gait import Stance, strides_from_stances
from gaitnet.vio.imu_propagation import propagate_to
from gaitnet.vio.initialise import initialise, up_in_camera
from gaitnet.vio.measurement import Measurement
from gaitnet.vio.odometry import FrameOdometry
from gaitnet.vio.records import FilterRecorder
from gaitnet.vio.result import StanceFoot, VioResult
from gaitnet.vio.scene_check import screen_session
from gaitnet.vio.smoother import SmootherOptions, SmootherResult, smooth
from gaitnet.vio.state import FilterState
from gaitnet.vio.tag_refusals import RefusedSheets, within_drift

log = logging.getLogger(__name__)

__all__ = ["run_vio"]

Progress = Callable[[Iterable, int], Iterable]


@dataclass
class _Landmark:
    """Book-keeping of one stance-foot landmark while the filter runs."""

    side: str
    t_first_s: float
    t_last_s: float
    n_obs: int = 1
    xy: np.ndarray = field(default_factory=lambda: np.zeros(2))
    std_xy: np.ndarray = field(default_factory=lambda: np.zeros(2))


def _without_numbers(reason: str) -> str:
    """A reason with its numbers replaced by ``#`` (counts group by reason)."""
    return re.sub(r"[-+]?\d+(\.\d+)?(e[-+]?\d+)?", "#", reason)


def _reason(up: covariance.UpdateResult) -> str:
    """A rejected update's reason without its numbers (counts group by reason)."""
    if np.isfinite(up.chi2) and "chi2" in up.reason:
        return "outside the chi2 gate"
    return _without_numbers(up.reason) or "rejected"


def _freeze(state: FilterState, lm_id: int, lm: _Landmark) -> None:
    """Copy a landmark's estimate and standard deviations out of the state."""
    sl = state.index(("lm", lm_id))
    lm.xy = state.landmarks[lm_id].copy()
    lm.std_xy = np.sqrt(np.diag(state.P[sl, sl]))


def _T_WfromI(state: FilterState) -> np.ndarray:
    return make_T(state.imu.R_WfromI, state.imu.p_IinW)


def camera_forward_W(T_WfromC: np.ndarray) -> np.ndarray:
    """The camera's forward on the floor (world xy, not unit): the horizontal part of its
    optical axis plus its image's up (``z_C − y_C``). For a camera pitched down by θ without
    roll that is ``cos θ + sin θ ≥ 1`` times the walking direction at every pitch from
    horizontal to straight down, where the optical axis alone has almost no horizontal part
    and flips with the body's sway (at 89° it swapped the sides of stance feet)."""
    R = np.asarray(T_WfromC, dtype=np.float64)[:3, :3]
    return R[:2, 2] - R[:2, 1]


def _frames(source: SessionSource, progress: Progress | None) -> Iterator[Frame]:
    it: Iterable = source.frames()
    if progress is not None:
        it = progress(it, len(source))
    yield from it


def run_vio(
    source: SessionSource,
    cfg: VioConfig,
    progress: Progress | None = None,
    on_frame: Callable[[Frame, np.ndarray], None] | None = None,
    foot_masks: Mapping[int, FootMask] | None = None,
) -> VioResult:
    """Run the filter, the smoother and the gait analysis on ``source`` (module docstring).

    ``on_frame(frame, T_WfromC)``: called once per processed frame, in order, with the frame and
    the filter's camera pose after its updates (e.g. to segment the frame while the filter goes
    on: ``gaitnet infer``); the frame is not decoded twice. ``foot_masks``: the segmenter's
    foot pixels by frame time stamp [ns]; feet they show where the depth image has none are
    stance-foot candidates too (:mod:`gaitnet.vio.feet_segmented`).
    """
    from gaitnet.vio.apriltags import detect_board_pose, imu_pose_from_camera
    from gaitnet.vio.foot_model import FootNoise, foot_measurement, landmark_from_observation
    from gaitnet.vio.stance_tracker import StanceTracker
    from gaitnet.vio.tag_model import tag_measurement
    from gaitnet.vio.vo_model import vo_measurement

    calib = source.calibration
    require_depth_aligned(source, "the filter")
    K = calib.color.K
    T_CfromI = calib.T_CfromI
    T_IfromC = np.linalg.inv(T_CfromI)
    imu = source.imu
    if len(imu) < 2:
        raise SessionError("the session has fewer than 2 IMU samples")
    times_ns = source.frame_times_ns
    t_ref_ns = int(times_ns[0])
    noise = cfg.imu_noise(calib)
    clock = Counter()
    tic = time.thread_time()

    screening = screen_session(source, cfg.scene, cfg.init, cfg.floor, cfg.init.max_tag_frames)
    init = initialise(screening.first, imu, calib, t_ref_ns, cfg.init, cfg.tags, cfg.floor)
    state = init.state
    gravity = cfg.filter.gravity_mps2 or init.measured_gravity_mps2
    baseline = state.copy()
    odometry = FrameOdometry(cfg.vo)
    tracker = StanceTracker(cfg.stance)
    foot_noise = FootNoise(cfg.filter.foot_std_m, cfg.filter.partial_foot_noise)
    landmarks: dict[int, _Landmark] = {}
    result_used: Counter = Counter()
    skipped: dict[str, Counter] = {}

    def gated_update(m: Measurement, probability: float) -> covariance.UpdateResult:
        gate = covariance.chi2_gate(m.dim, probability) if probability else None
        return covariance.update(state, m, gate_chi2=gate)

    def skip(kind: str, reason: str) -> None:
        skipped.setdefault(kind, Counter())[reason] += 1

    recorder = FilterRecorder(T_CfromI, gravity)
    recorder.set_prior(state)
    T_WfromI_f: list[np.ndarray] = []
    T_WfromC_b: list[np.ndarray] = []
    cov_p: list[np.ndarray] = []
    processed: list[int] = []
    prev: Frame | None = None
    tags_initialised = init.method == "apriltag"
    boards_seen: set[str] = {init.board} if init.board else set()
    p_last_tag = state.imu.p_IinW.copy()  # where the odometry's drift starts to count
    refused_tags = RefusedSheets(cfg.filter.tag_recovery_frames)
    clock["initialise"] += time.thread_time() - tic

    for frame in _frames(source, progress):
        k = frame.index
        t = (frame.t_ns - t_ref_ns) * 1e-9
        if k < init.frame_index:
            skip("frame", "before the initialising frame")
            continue
        if k > screening.last_index:
            skip("frame", "after the IMU stream's last sample")
            continue
        if k != init.frame_index and t <= state.imu.t_s:
            skip("frame", "time does not advance")
            continue
        tic = time.thread_time()
        if k != init.frame_index:
            before = state.imu.copy()
            info = propagate_to(state, imu, t, noise, gravity_mps2=gravity, t_ref_ns=t_ref_ns)
            propagate_to(baseline, imu, t, noise, gravity_mps2=gravity, t_ref_ns=t_ref_ns)
            covariance.check_healthy(state)  # a corrupt IMU sample stops here, not later
            if info.Phi is None or info.Q is None:  # an interval too short to integrate
                recorder.add_propagation(before, state.imu, np.eye(15), np.zeros((15, 15)))
            else:
                recorder.add_propagation(before, state.imu, info.Phi, info.Q)
        clock["propagation"] += time.thread_time() - tic

        # --- visual odometry between the previous frame and this one (3.11)–(3.21)
        if prev is not None and state.clone is not None and cfg.filter.use_vo:
            tic = time.thread_time()
            T_WfromCprev = make_T(state.clone.R_WfromI, state.clone.p_IinW) @ T_IfromC
            T_WfromCk = _T_WfromI(state) @ T_IfromC
            guess = np.linalg.inv(T_WfromCk) @ T_WfromCprev
            vo = odometry.estimate(prev, frame, K, guess)
            clock["vo_frontend"] += time.thread_time() - tic
            tic = time.thread_time()
            if vo.ok:
                m = vo_measurement(state, T_CfromI, vo.R, vo.t, vo.cov6)
                up = gated_update(m, cfg.filter.vo_gate_probability)
                if up.accepted:
                    result_used["vo"] += 1
                    recorder.add_vo(vo.R, vo.t, vo.cov6)
                else:
                    skip("vo", _reason(up))
            else:
                skip("vo", _without_numbers(vo.reason) or "odometry failed")
            clock["vo_update"] += time.thread_time() - tic

        # --- AprilTag update (3.27)–(3.34); the first pose initialised the state
        if calib.apriltag_boards and cfg.filter.use_tags and k != init.frame_index:
            tic = time.thread_time()
            T_WfromC_guess = _T_WfromI(state) @ T_IfromC
            obs = detect_board_pose(frame, calib, cfg.tags, T_WfromC_guess)
            travelled = float(np.linalg.norm((state.imu.p_IinW - p_last_tag)[:2]))
            drift_m = cfg.filter.odometry_scale_std * travelled
            every = cfg.filter.full_search_every
            if obs is None and every and k % every == 0:
                near = [
                    b for b in calib.apriltag_boards
                    if b.name not in boards_seen
                    and np.linalg.norm(b.T_WfromBoard[:2, 3] - T_WfromC_guess[:2, 3])
                    < 1.0 + drift_m
                ]  # fmt: skip
                if near:  # a sheet is near but not where the prediction puts it: drift
                    obs = detect_board_pose(frame, calib, cfg.tags, None)
            if obs is not None:
                cov_I = imu_pose_from_camera(obs.T_WfromC, obs.cov6, T_CfromI)[1]
                eps2 = cfg.filter.end_sheet_std_m**2 if obs.board != init.board else 0.0
                use_attitude = not tags_initialised
                m = tag_measurement(
                    state,
                    T_CfromI,
                    obs.T_WfromC,
                    cov_I,
                    end_sheet_eps2=eps2,
                    use_attitude=use_attitude,
                )
                up = gated_update(m, cfg.filter.tag_gate_probability)
                if not up.accepted:
                    factor = refused_tags.widen_if_steady(
                        state, k, m, up.chi2, cfg.filter.tag_gate_probability
                    )
                    if np.isfinite(factor):  # drifted beyond its covariance, not a wrong decode
                        up = gated_update(m, cfg.filter.tag_gate_probability)
                        if up.accepted:
                            result_used["tag_recovered"] += 1
                            log.info(
                                "frame %d: sheet '%s' refused steadily in its last %d decodes "
                                "(%.1f cm off): the filter's navigation covariance widened "
                                "×%.3g to take it",
                                k, obs.board, cfg.filter.tag_recovery_frames,
                                100 * float(np.linalg.norm(m.residual)), factor,
                            )  # fmt: skip
                if up.accepted:
                    refused_tags.refused.clear()
                    result_used["tag"] += 1
                    tags_initialised = True
                    boards_seen.add(obs.board)
                    p_last_tag = state.imu.p_IinW.copy()
                    recorder.add_tag(
                        obs.T_WfromC, cov_I, end_sheet_eps2=eps2, use_attitude=use_attitude
                    )
                elif within_drift(m, state, drift_m, cfg.filter.tag_gate_probability):
                    result_used["tag_smoother_only"] += 1  # the filter still misses it
                    recorder.add_tag(
                        obs.T_WfromC, cov_I, end_sheet_eps2=eps2, use_attitude=use_attitude
                    )
                else:
                    skip("tag", _reason(up))
            clock["tags"] += time.thread_time() - tic

        # --- floor, stance-foot candidates, landmarks (3.22)–(3.26), (3.35)–(3.48)
        if cfg.filter.use_feet:
            tic = time.thread_time()
            up_C = up_in_camera(state.imu.R_WfromI, T_CfromI)
            plane = fit_floor_depth(frame.depth_m, K, up_C, cfg.floor)
            candidates = (
                [] if plane is None else detect_foot_candidates(frame.depth_m, K, plane, cfg.feet)
            )
            mask = None if foot_masks is None else foot_masks.get(frame.t_ns)
            if mask is not None and plane is not None:
                candidates += segmented_foot_candidates(
                    mask, frame.depth_m, K, plane, cfg.feet, candidates
                )
            if plane is None:
                skip("frame", "no floor plane")
            T_WfromC = _T_WfromI(state) @ T_IfromC
            p_W = [T_WfromC[:3, :3] @ c.p_FinC + T_WfromC[:3, 3] for c in candidates]
            assignments = tracker.update(
                t,
                [p[:2] for p in p_W],
                heading_W=camera_forward_W(T_WfromC),
                p_CinW=T_WfromC[:3, 3],
                weak=[c.weak for c in candidates],
                segmented=[c.segmented for c in candidates],
            )
            clock["feet_frontend"] += time.thread_time() - tic
            tic = time.thread_time()
            for cand, a in zip(candidates, assignments, strict=True):
                if a is None:
                    continue
                R3 = foot_noise.of(cand.width_m, cand.axis_C, up_C)
                if a.stance_id not in state.landmarks:
                    if a.stance_id in landmarks:  # already marginalised: not reopened
                        skip("foot", "landmark already marginalised")
                        continue
                    aug = landmark_from_observation(state, T_CfromI, cand.p_FinC, R3)
                    covariance.augment_landmark(state, a.stance_id, aug)
                    # the foot was seen at this point on every frame of its track before
                    # the confirmation too (StanceTracker): a short foot flat (0.14 s on a
                    # brisk real walk) leaves too few updates after it to be reported. Not
                    # for a track of weak pieces only (a toe in push-off seen again after
                    # its stance ended, on a simulated walk): those need their updates.
                    stance = tracker.stances[a.stance_id]
                    sightings = len(stance.obs) if stance.strong else 1
                    landmarks[a.stance_id] = _Landmark(a.side, t, t, n_obs=sightings)
                    result_used["foot_new"] += 1
                    recorder.add_foot(a.stance_id, cand.p_FinC, R3, is_first=True)
                    continue
                m = foot_measurement(state, T_CfromI, a.stance_id, cand.p_FinC, R3)
                up = gated_update(m, cfg.filter.foot_gate_probability)
                if up.accepted:
                    lm = landmarks[a.stance_id]
                    lm.t_last_s = t
                    lm.n_obs += 1
                    result_used["foot"] += 1
                    recorder.add_foot(a.stance_id, cand.p_FinC, R3)
                else:
                    skip("foot", _reason(up))
            for lm_id in list(state.landmarks):
                if t - landmarks[lm_id].t_last_s > cfg.filter.marginalise_after_s:
                    _freeze(state, lm_id, landmarks[lm_id])
                    recorder.set_landmark(lm_id, state.landmarks[lm_id])
                    covariance.marginalise_landmark(state, lm_id)
            clock["feet_update"] += time.thread_time() - tic

        covariance.check_healthy(state)
        recorder.add_frame(state, session_index=k)
        covariance.clone(state)
        processed.append(k)
        T_WfromI_f.append(_T_WfromI(state))
        if on_frame is not None:
            on_frame(frame, T_WfromI_f[-1] @ T_IfromC)
        T_WfromC_b.append(_T_WfromI(baseline) @ T_IfromC)
        cov_p.append(state.P[3:6, 3:6].copy())
        prev = frame

    if not processed:
        raise SessionError("no frame could be processed after the initialising one")
    for lm_id in list(state.landmarks):
        _freeze(state, lm_id, landmarks[lm_id])
    tracker.finish()
    # sides from where the stances are in the end, not from the drifting poses of the time
    t_tracker = (times_ns[processed] - t_ref_ns).astype(np.float64) * 1e-9
    sides = tracker.sides_at(
        _reported_xy(landmarks, cfg), _camera_path(t_tracker, T_WfromI_f, T_IfromC)
    )
    feet_filter = _stance_feet(landmarks, sides, cfg, t_ref_ns)
    strides_filter = _strides(feet_filter, cfg)

    smoothed: SmootherResult | None = None
    smoother_info: dict[str, object] = {}
    if cfg.smoother.enabled:
        tic = time.thread_time()
        smoothed, smoother_info = _smooth(recorder, cfg)
        clock["smoother"] += time.thread_time() - tic
    feet, strides = feet_filter, strides_filter
    if smoothed is not None:
        for lm_id, lm in landmarks.items():
            lm.xy = smoothed.landmarks[lm_id].copy()
            cov = smoothed.landmark_cov.get(lm_id)
            lm.std_xy = np.sqrt(np.clip(np.diag(cov), 0.0, None)) if cov is not None else lm.std_xy
        sides = tracker.sides_at(
            _reported_xy(landmarks, cfg), _camera_path(t_tracker, smoothed.T_WfromI, T_IfromC)
        )
        feet = _stance_feet(landmarks, sides, cfg, t_ref_ns)
        strides = _strides(feet, cfg)

    T_WfromI_filter = np.array(T_WfromI_f)
    return VioResult(
        t_s=times_ns[processed].astype(np.float64) * 1e-9,
        T_WfromI_filter=T_WfromI_filter,
        T_WfromC_filter=T_WfromI_filter @ T_IfromC,
        T_WfromC_imu_only=np.array(T_WfromC_b),
        T_WfromI_smoothed=None if smoothed is None else smoothed.T_WfromI,
        T_WfromC_smoothed=None if smoothed is None else smoothed.T_WfromC,
        stance_feet=feet,
        strides=strides,
        initialisation=init.method,
        initialisation_note=init.note,
        session_index=np.array(processed, dtype=np.int64),
        cov_p_IinW_filter=np.array(cov_p),
        stance_feet_filter=feet_filter,
        strides_filter=strides_filter,
        smoother=smoother_info,
        used=result_used,
        skipped=skipped,
        timings_s=dict(clock),
        unreliable=list(screening.problems),
    )


def _camera_path(
    t_s: np.ndarray, T_WfromI: Sequence[np.ndarray] | np.ndarray, T_IfromC: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``(t_s, p_CinW (N, 3))``: the camera positions of the IMU poses ``T_WfromI``."""
    T = np.asarray(T_WfromI)
    return t_s, T[:, :3, :3] @ T_IfromC[:3, 3] + T[:, :3, 3]


def _reported_xy(landmarks: dict[int, _Landmark], cfg: VioConfig) -> dict[int, np.ndarray]:
    """Floor positions of the landmarks that are reported (``min_foot_observations``)."""
    return {i: lm.xy for i, lm in landmarks.items() if lm.n_obs >= cfg.filter.min_foot_observations}


def _stance_feet(
    landmarks: dict[int, _Landmark], sides: dict[int, str], cfg: VioConfig, t_ref_ns: int
) -> list[StanceFoot]:
    """The reported stance feet: landmarks observed at least ``min_foot_observations`` times,
    with the tracker's final side, on the session clock."""
    return [
        StanceFoot(
            i,
            sides.get(i, lm.side),
            lm.t_first_s + t_ref_ns * 1e-9,
            lm.t_last_s + t_ref_ns * 1e-9,
            lm.xy.copy(),
            lm.std_xy.copy(),
            lm.n_obs,
        )
        for i, lm in landmarks.items()
        if lm.n_obs >= cfg.filter.min_foot_observations
    ]


def _strides(feet: list[StanceFoot], cfg: VioConfig) -> list:
    stances = [Stance(f.side, f.t_first_s, f.t_last_s, f.xy) for f in feet]
    return strides_from_stances(stances, cfg.gait.max_stride_time_s, cfg.gait.max_stance_time_s)


def _smooth(
    recorder: FilterRecorder, cfg: VioConfig
) -> tuple[SmootherResult | None, dict[str, object]]:
    """The smoother on the filter's record, and its diagnostics for the summary; a failure is
    logged and reported (``ran: false`` with the reason), and the filter's estimates stand."""
    options = SmootherOptions(
        max_iterations=cfg.smoother.max_iterations, step_tol=cfg.smoother.step_tol
    )
    try:
        record = recorder.finish()
        result = smooth(record, options)
    except (FilterDivergedError, ValueError, np.linalg.LinAlgError, RuntimeError) as err:
        log.warning("the smoother failed (%s); reporting the filter's estimates", err)
        return None, {"ran": False, "reason": str(err)}
    if not (np.all(np.isfinite(result.p_IinW)) and np.all(np.isfinite(result.q))):
        log.warning("the smoother gave non-finite poses; reporting the filter's estimates")
        return None, {"ran": False, "reason": "non-finite smoothed poses"}
    info: dict[str, object] = {
        "ran": True,
        "iterations": result.iterations,
        "converged": result.converged,
        "cost_per_iteration": list(result.cost),
        "chi2_per_term": {k: v for k, v in result.chi2.items()},
        "n_residuals": dict(result.n_residuals),
        "gyro_bias_rad_s": result.b_g.tolist(),
        "accel_bias_mps2": result.b_a.tolist(),
    }
    return result, info
