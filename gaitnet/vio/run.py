"""``run_vio``: the filter over a whole session, then the smoother and the gait parameters.

Per frame (thesis Algorithm 1, with the tag update in the loop as thesis-notes says):

1. IMU propagation to the frame time (:mod:`gaitnet.vio.imu_propagation`);
2. visual-odometry update between the previous and this frame, seeded with the IMU-predicted
   relative pose (:mod:`gaitnet.vio.odometry`, :mod:`gaitnet.vio.vo_model`);
3. AprilTag update when a board is in view (:mod:`gaitnet.vio.apriltags`,
   :mod:`gaitnet.vio.tag_model`);
4. floor plane and stance-foot candidates (:mod:`gaitnet.vio.floor`, :mod:`gaitnet.vio.feet`),
   grouped into stances and sides (:mod:`gaitnet.vio.stance_tracker`); a new stance augments
   the state with a landmark, a continuing one updates it (:mod:`gaitnet.vio.foot_model`), a
   finished one is marginalised;
5. stochastic cloning of the pose for the next frame's odometry; a health check (a NaN or a
   covariance that is not positive semi-definite stops the run with one clear error).

A measurement that cannot be made or fails its χ² gate is skipped, and counted with its reason
in :class:`~gaitnet.vio.result.VioResult`. An IMU-only dead-reckoning run from the same
initial state is kept as a baseline.
"""

from __future__ import annotations

import logging
import re
import time
from collections import Counter
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field

import numpy as np

from gaitnet.errors import SessionError
from gaitnet.geometry import make_T
from gaitnet.io.types import Frame, SessionSource
from gaitnet.vio import covariance
from gaitnet.vio.config import VioConfig
from gaitnet.vio.feet import detect_foot_candidates
from gaitnet.vio.floor import fit_floor_depth
from gaitnet.vio.gait import Stance, strides_from_stances
from gaitnet.vio.imu_propagation import propagate_to
from gaitnet.vio.initialise import initialise, up_in_camera
from gaitnet.vio.measurement import Measurement
from gaitnet.vio.odometry import FrameOdometry
from gaitnet.vio.result import StanceFoot, VioResult
from gaitnet.vio.state import FilterState

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


def _reason(up: covariance.UpdateResult) -> str:
    """A rejected update's reason without its numbers (counts group by reason)."""
    if np.isfinite(up.chi2) and "chi2" in up.reason:
        return "outside the chi2 gate"
    return re.sub(r"[-+]?\d+(\.\d+)?(e[-+]?\d+)?", "#", up.reason) or "rejected"


def _freeze(state: FilterState, lm_id: int, lm: _Landmark) -> None:
    """Copy a landmark's estimate and standard deviations out of the state."""
    sl = state.index(("lm", lm_id))
    lm.xy = state.landmarks[lm_id].copy()
    lm.std_xy = np.sqrt(np.diag(state.P[sl, sl]))


def _T_WfromI(state: FilterState) -> np.ndarray:
    return make_T(state.imu.R_WfromI, state.imu.p_IinW)


def _frames(source: SessionSource, progress: Progress | None) -> Iterator[Frame]:
    it: Iterable = source.frames()
    if progress is not None:
        it = progress(it, len(source))
    yield from it


def run_vio(source: SessionSource, cfg: VioConfig, progress: Progress | None = None) -> VioResult:
    """Run the filter, the smoother and the gait analysis on ``source`` (module docstring)."""
    from gaitnet.vio.apriltags import detect_board_pose, imu_pose_from_camera
    from gaitnet.vio.foot_model import foot_measurement, landmark_from_observation
    from gaitnet.vio.stance_tracker import StanceTracker
    from gaitnet.vio.tag_model import tag_measurement
    from gaitnet.vio.vo_model import vo_measurement

    calib = source.calibration
    if not calib.depth_aligned_to_color:
        raise SessionError("the filter needs depth aligned to colour (session.yaml)")
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
    tic = time.perf_counter()

    first = [source.frame(i) for i in range(min(len(source), cfg.init.max_tag_frames))]
    init = initialise(first, imu, calib, t_ref_ns, cfg.init, cfg.tags, cfg.floor)
    state = init.state
    gravity = cfg.filter.gravity_mps2 or init.measured_gravity_mps2
    baseline = state.copy()
    odometry = FrameOdometry(cfg.vo)
    tracker = StanceTracker(cfg.stance)
    landmarks: dict[int, _Landmark] = {}
    result_used: Counter = Counter()
    skipped: dict[str, Counter] = {}

    def gated_update(m: Measurement, probability: float) -> covariance.UpdateResult:
        gate = covariance.chi2_gate(m.dim, probability) if probability else None
        return covariance.update(state, m, gate_chi2=gate)

    def skip(kind: str, reason: str) -> None:
        skipped.setdefault(kind, Counter())[reason] += 1

    n = len(source)
    T_WfromI_f = np.zeros((n, 4, 4))
    T_WfromC_b = np.zeros((n, 4, 4))
    prev: Frame | None = None
    tags_initialised = init.method == "apriltag"
    clock["initialise"] += time.perf_counter() - tic

    for frame in _frames(source, progress):
        k = frame.index
        t = (frame.t_ns - t_ref_ns) * 1e-9
        tic = time.perf_counter()
        if t > state.imu.t_s:
            propagate_to(state, imu, t, noise, gravity_mps2=gravity, t_ref_ns=t_ref_ns)
            propagate_to(baseline, imu, t, noise, gravity_mps2=gravity, t_ref_ns=t_ref_ns)
            covariance.check_healthy(state)  # a corrupt IMU sample stops here, not later
        clock["propagation"] += time.perf_counter() - tic

        # --- visual odometry between the previous frame and this one (3.11)–(3.21)
        if prev is not None and state.clone is not None and cfg.filter.use_vo:
            tic = time.perf_counter()
            T_WfromCprev = make_T(state.clone.R_WfromI, state.clone.p_IinW) @ T_IfromC
            T_WfromCk = _T_WfromI(state) @ T_IfromC
            guess = np.linalg.inv(T_WfromCk) @ T_WfromCprev
            vo = odometry.estimate(prev, frame, K, guess)
            clock["vo_frontend"] += time.perf_counter() - tic
            tic = time.perf_counter()
            if vo.ok:
                m = vo_measurement(state, T_CfromI, vo.R, vo.t, vo.cov6)
                up = gated_update(m, cfg.filter.vo_gate_probability)
                if up.accepted:
                    result_used["vo"] += 1
                else:
                    skip("vo", _reason(up))
            else:
                skip("vo", vo.reason or "odometry failed")
            clock["vo_update"] += time.perf_counter() - tic

        # --- AprilTag update (3.27)–(3.34); the first pose initialised the state
        if calib.apriltag_boards and cfg.filter.use_tags and k != init.frame_index:
            tic = time.perf_counter()
            T_WfromC_guess = _T_WfromI(state) @ T_IfromC
            obs = detect_board_pose(frame, calib, cfg.tags, T_WfromC_guess)
            if obs is not None:
                cov_I = imu_pose_from_camera(obs.T_WfromC, obs.cov6, T_CfromI)[1]
                eps2 = cfg.filter.end_sheet_std_m**2 if obs.board != init.board else 0.0
                m = tag_measurement(
                    state,
                    T_CfromI,
                    obs.T_WfromC,
                    cov_I,
                    end_sheet_eps2=eps2,
                    use_attitude=not tags_initialised,
                )
                up = gated_update(m, cfg.filter.tag_gate_probability)
                if up.accepted:
                    result_used["tag"] += 1
                    tags_initialised = True
                else:
                    skip("tag", _reason(up))
            clock["tags"] += time.perf_counter() - tic

        # --- floor, stance-foot candidates, landmarks (3.22)–(3.26), (3.35)–(3.48)
        if cfg.filter.use_feet:
            tic = time.perf_counter()
            up_C = up_in_camera(state.imu.R_WfromI, T_CfromI)
            plane = fit_floor_depth(frame.depth_m, K, up_C, cfg.floor)
            candidates = (
                [] if plane is None else detect_foot_candidates(frame.depth_m, K, plane, cfg.feet)
            )
            if plane is None:
                skip("frame", "no floor plane")
            T_WfromC = _T_WfromI(state) @ T_IfromC
            p_W = [T_WfromC[:3, :3] @ c.p_FinC + T_WfromC[:3, 3] for c in candidates]
            assignments = tracker.update(
                t, [p[:2] for p in p_W], heading_W=T_WfromC[:3, 2], p_CinW=T_WfromC[:3, 3]
            )
            clock["feet_frontend"] += time.perf_counter() - tic
            tic = time.perf_counter()
            R3 = np.eye(3) * cfg.filter.foot_std_m**2
            for cand, a in zip(candidates, assignments, strict=True):
                if a is None:
                    continue
                if a.stance_id not in state.landmarks:
                    if a.stance_id in landmarks:  # already marginalised: not reopened
                        skip("foot", "landmark already marginalised")
                        continue
                    aug = landmark_from_observation(state, T_CfromI, cand.p_FinC, R3)
                    covariance.augment_landmark(state, a.stance_id, aug)
                    landmarks[a.stance_id] = _Landmark(a.side, t, t)
                    result_used["foot_new"] += 1
                    continue
                m = foot_measurement(state, T_CfromI, a.stance_id, cand.p_FinC, R3)
                up = gated_update(m, cfg.filter.foot_gate_probability)
                if up.accepted:
                    lm = landmarks[a.stance_id]
                    lm.t_last_s = t
                    lm.n_obs += 1
                    result_used["foot"] += 1
                else:
                    skip("foot", _reason(up))
            for lm_id in list(state.landmarks):
                if t - landmarks[lm_id].t_last_s > cfg.filter.marginalise_after_s:
                    _freeze(state, lm_id, landmarks[lm_id])
                    covariance.marginalise_landmark(state, lm_id)
            clock["feet_update"] += time.perf_counter() - tic

        covariance.check_healthy(state)
        covariance.clone(state)
        T_WfromI_f[k] = _T_WfromI(state)
        T_WfromC_b[k] = _T_WfromI(baseline) @ T_IfromC
        prev = frame

    for lm_id in list(state.landmarks):
        _freeze(state, lm_id, landmarks[lm_id])
    sides = {s.id: s.side for s in tracker.finish()}

    feet = [
        StanceFoot(
            i,
            sides.get(i, lm.side),
            lm.t_first_s + t_ref_ns * 1e-9,
            lm.t_last_s + t_ref_ns * 1e-9,
            lm.xy,
            lm.std_xy,
            lm.n_obs,
        )
        for i, lm in landmarks.items()
        if lm.n_obs >= cfg.filter.min_foot_observations
    ]
    stances = [Stance(f.side, f.t_first_s, f.t_last_s, f.xy) for f in feet]
    strides = strides_from_stances(stances, cfg.gait.max_stride_time_s, cfg.gait.max_stance_time_s)
    T_WfromC_f = T_WfromI_f @ T_IfromC
    return VioResult(
        t_s=times_ns.astype(np.float64) * 1e-9,
        T_WfromI_filter=T_WfromI_f,
        T_WfromC_filter=T_WfromC_f,
        T_WfromC_imu_only=T_WfromC_b,
        T_WfromI_smoothed=None,
        T_WfromC_smoothed=None,
        stance_feet=feet,
        strides=strides,
        initialisation=init.method,
        initialisation_note=init.note,
        used=result_used,
        skipped=skipped,
        timings_s=dict(clock),
    )
