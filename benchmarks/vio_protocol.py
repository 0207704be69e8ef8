"""The stride-length protocol of thesis sec. 5.2 on simulated sessions (``bench_vio.py``).

**Protocol.** Five simulated subjects, each with a fixed body height and walking speed
(:data:`SUBJECTS`; everything else about them — segment lengths, shoes, gait variability — is
drawn from the session's seed), walk straight for 5, 10 and 15 m (:data:`WALK_LENGTHS_M`)
between AprilTag sheets, ``trials`` times each, with the simulator's default config
(``configs/sim/default.yaml``: 1.5 s standing at each end, camera pitched 70° down). The floor
family rotates over the trials (:func:`protocol_trial`) so that every family, the
textureless one included, appears for every subject and every walk length once there are two
trials or more; textureless trials are reported separately as well. One more session of 60 s
(:func:`long_trial`) measures the smoother's time on the session length of its budget; it is
left out of the accuracy tables (it would outweigh its subject's other trials).

**Seeds.** Trial ``t`` (0-based) of subject ``s`` (0-based) at walk length index ``l`` uses seed
``1000 + 100 s + 30 l + t`` (``t`` < 30), the 60 s session (:func:`long_trial`) seed 1500: the
benchmark range 1000–1500, disjoint from the seeds the filter was tuned on (200–210, and
300–999 for later tuning). A seed does not change when other
subjects, lengths or trial counts are selected, so cached sessions stay valid.

**Strides.** Each method's strides are matched to the simulator's true ones by time
(:func:`gaitnet.evaluation.strides.match_strides`: both stances within 0.25 s, all strides of
the session, gait initiation and termination included); the error is estimated minus true
length. Three methods:

- ``smoothed``: the strides of the smoothed stance feet (``VioResult.strides``, the output);
- ``filter``: the filter's own (``VioResult.strides_filter``);
- ``imu_only``: the IMU-only dead reckoning has no stance feet of its own. Its stride uses the
  filter's stances (same sides and first-observation times): each stance's floor point is
  expressed in the camera frame of the filter's pose at the stance's first observation and
  placed in the world with the IMU-only camera pose of that frame,
  ``x̃ = T_WfromC_imu(t_first) · T_WfromC_filter(t_first)⁻¹ · (x, y, 0)``; the stride length
  is the floor distance between consecutive ``x̃`` of one side. This is the stride a
  dead-reckoning system with the same foot detector would measure: the foot relative to the
  camera is what the camera sees (the filter's estimate of it, a few mm off), and the camera's
  motion over the stride is the IMU's alone. (The camera's own displacement between the two
  times would add the body's within-stride speed changes and sway to the error even for a
  perfect trajectory.)

**Time.** Every run uses one thread for OpenMP/BLAS/OpenCV (set by ``bench_vio.py`` before the
imports). ``time.process_time`` around ``run_vio`` gives the CPU seconds of all threads (the
session reader decodes PNGs ahead in a background thread: on one core that time counts);
``time.thread_time`` the main thread's. The per-stage figures are ``VioResult.timings_s`` (the
main thread's CPU seconds per stage). Filter CPU = all threads − the smoother's stage; per
frame = divided by the session's frame count.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import yaml

from gaitnet.config import dump_config, load_config
from gaitnet.errors import GaitnetError, SessionError
from gaitnet.evaluation.metrics import ate_yaw_aligned, match_times
from gaitnet.evaluation.strides import SIDES, StrideRows, match_strides, read_strides
from gaitnet.io import open_session
from gaitnet.sim.config import SimConfig
from gaitnet.sim.floor import FLOOR_FAMILIES
from gaitnet.vio.config import VioConfig
from gaitnet.vio.gait import Stride
from gaitnet.vio.result import VioResult

log = logging.getLogger(__name__)

REPO = Path(__file__).resolve().parents[1]
SIM_CONFIG = REPO / "configs" / "sim" / "default.yaml"
SEED_BASE = 1000
MAX_TRIALS = 30
METHODS = ("smoothed", "filter", "imu_only")
SCOPES = ("all", "textured", "textureless")
FILTER_TARGET_MS = 33.0
SMOOTHER_TARGET_S_PER_60S = 2.0


@dataclass(frozen=True)
class SubjectSpec:
    """One simulated subject: label, body height [m], steady walking speed [m/s]."""

    label: str
    height_m: float
    speed_mps: float


SUBJECTS: tuple[SubjectSpec, ...] = (
    SubjectSpec("S1", 1.55, 1.05),
    SubjectSpec("S2", 1.63, 1.40),
    SubjectSpec("S3", 1.72, 0.90),
    SubjectSpec("S4", 1.81, 1.20),
    SubjectSpec("S5", 1.90, 1.50),
)
WALK_LENGTHS_M: tuple[float, ...] = (5.0, 10.0, 15.0)


@dataclass(frozen=True)
class Trial:
    """One protocol session: subject index, walk length [m], trial number (0-based), seed,
    floor family; ``speed_only`` sessions time the run and stay out of the accuracy tables."""

    subject_index: int
    walk_length_m: float
    trial: int
    seed: int
    floor_family: str
    speed_only: bool = False

    @property
    def subject(self) -> SubjectSpec:
        return SUBJECTS[self.subject_index]

    @property
    def name(self) -> str:
        kind = "long_" if self.speed_only else ""
        return f"{kind}{self.subject.label}_{self.walk_length_m:g}m_t{self.trial + 1}_s{self.seed}"

    def overrides(self) -> list[str]:
        return [
            f"subject.height_m={self.subject.height_m}",
            f"gait.speed_mps={self.subject.speed_mps}",
            f"gait.walk_length_m={self.walk_length_m}",
            f"scene.floor_family={self.floor_family}",
        ]

    def sim_config(self, base: Path = SIM_CONFIG) -> SimConfig:
        return load_config(SimConfig, base, self.overrides())


def protocol_trial(subject_index: int, length_index: int, trial: int) -> Trial:
    """Trial ``trial`` of a subject at a walk length (indices into :data:`SUBJECTS` and
    :data:`WALK_LENGTHS_M`): seed ``1000 + 100 s + 30 l + t``; floor family number
    ``(s + 2 l + t) mod 5``, which takes every value for every subject over its 3 lengths × 2
    trials, and for every length over the 5 subjects."""
    if not 0 <= trial < MAX_TRIALS:
        raise ValueError(f"trial must be 0–{MAX_TRIALS - 1}, got {trial}")
    k = subject_index + 2 * length_index + trial
    return Trial(
        subject_index,
        WALK_LENGTHS_M[length_index],
        trial,
        SEED_BASE + 100 * subject_index + 30 * length_index + trial,
        FLOOR_FAMILIES[k % len(FLOOR_FAMILIES)],
    )


def protocol_trials(subjects: Sequence[int], lengths: Sequence[int], trials: int) -> list[Trial]:
    """The trials of the selected subjects and walk lengths (indices), ``trials`` each."""
    if not 1 <= trials <= MAX_TRIALS:
        raise ValueError(f"trials must be 1–{MAX_TRIALS}, got {trials}")
    return [protocol_trial(s, li, t) for s in subjects for li in lengths for t in range(trials)]


LONG_WALK_S = 54.0
"""Steady walking time of the 60 s session: with the 1.5 s standing phases at each end and
about 3 s of gait initiation and termination the session lasts about 60 s."""


def long_trial() -> Trial:
    """A session of about 60 s for the smoother's time budget (seed 1500, S4 at 1.20 m/s
    walking 64.8 m, tiles): timed, not in the accuracy tables."""
    subject = 3
    length = round(SUBJECTS[subject].speed_mps * LONG_WALK_S, 1)
    return Trial(subject, length, 0, SEED_BASE + 500, "tiles", speed_only=True)


def cached_session_matches(folder: Path, seed: int, config_text: str) -> bool:
    """Whether ``folder`` is a complete session simulated with ``seed`` and this config."""
    try:
        text = (folder / "sim_config.yaml").read_text()
        extra = yaml.safe_load((folder / "session.yaml").read_text()).get("extra", {})
    except (OSError, yaml.YAMLError, AttributeError):
        return False
    return (
        extra.get("simulator_seed") == seed
        and yaml.safe_load(text) == yaml.safe_load(config_text)
        and (folder / "groundtruth" / "strides.csv").is_file()
    )


def ensure_session(
    trial: Trial, sessions_dir: Path, workers: int | None = None
) -> tuple[Path, float | None]:
    """The trial's session folder under ``sessions_dir``, simulated unless a matching one is
    cached; returns the folder and the seconds spent simulating (None when cached)."""
    from gaitnet.sim.session import simulate_session

    cfg = trial.sim_config()
    text = dump_config(cfg)
    folder = sessions_dir / trial.name
    if cached_session_matches(folder, trial.seed, text):
        return folder, None
    if folder.exists():
        log.warning("%s: cached session does not match the protocol; simulating again", folder)
    t0 = time.perf_counter()
    simulate_session(cfg, trial.seed, folder, overwrite=True, config_text=text, workers=workers)
    return folder, time.perf_counter() - t0


def stride_rows(strides: Sequence[Stride]) -> StrideRows:
    """Strides as :class:`StrideRows` (the columns ``strides.csv`` has: events at the stances'
    first observations)."""
    return StrideRows(
        np.array([s.side for s in strides], dtype=str),
        np.array([s.start.t_first_s for s in strides], dtype=float),
        np.array([s.end.t_first_s for s in strides], dtype=float),
        np.array([s.length_m for s in strides], dtype=float),
    )


def imu_only_strides(result: VioResult) -> StrideRows:
    """The IMU-only baseline's strides (module docstring): the filter's stances placed with the
    IMU-only camera poses of their first observations."""
    t = np.asarray(result.t_s, dtype=float)

    def placed(t_first: float, xy: np.ndarray) -> np.ndarray:
        k = int(np.argmin(np.abs(t - t_first)))
        if abs(t[k] - t_first) > 1e-3:
            raise ValueError(f"no processed frame at the stance time {t_first:.3f} s")
        p = np.array([xy[0], xy[1], 0.0, 1.0])
        p_C = np.linalg.solve(result.T_WfromC_filter[k], p)
        return (result.T_WfromC_imu_only[k] @ p_C)[:2]

    strides = result.strides_filter
    ends = [
        (placed(s.start.t_first_s, s.start.xy), placed(s.end.t_first_s, s.end.xy)) for s in strides
    ]
    lengths = [float(np.linalg.norm(b - a)) for a, b in ends]
    rows = stride_rows(strides)
    return StrideRows(rows.side, rows.start_s, rows.end_s, np.array(lengths, dtype=float))


@dataclass
class MethodStrides:
    """One method's strides in one session: matched errors per side [m] and the counts of
    unmatched estimated and true strides."""

    errors_m: dict[str, list[float]] = field(default_factory=lambda: {s: [] for s in SIDES})
    unmatched_estimate: int = 0
    unmatched_truth: int = 0


def compare_strides(est: StrideRows, ref: StrideRows) -> MethodStrides:
    """Match ``est`` to ``ref`` (``gaitnet evaluate``'s matching) and keep the errors."""
    match = match_strides(est, ref)
    out = MethodStrides()
    for side in SIDES:
        out.errors_m[side] = [
            float(est.length_m[i] - ref.length_m[j]) for i, j in match.pairs[side]
        ]
    out.unmatched_estimate = sum(match.unmatched_estimate.values())
    out.unmatched_truth = sum(match.unmatched_reference.values())
    return out


@dataclass
class SessionOutcome:
    """Everything the benchmark keeps of one session's run."""

    name: str
    path: str
    subject: str
    height_m: float
    speed_mps: float
    walk_length_m: float
    floor_family: str
    seed: int | None
    n_frames: int
    duration_s: float
    failure: str | None = None
    strides: dict[str, MethodStrides] = field(default_factory=dict)
    ate_m: dict[str, float] = field(default_factory=dict)
    smoother_ran: bool = False
    smoother_iterations: int = 0
    vo_used: int = 0
    vo_skipped: int = 0
    cpu_s: dict[str, float] = field(default_factory=dict)
    stage_cpu_s: dict[str, float] = field(default_factory=dict)
    wall_s: float = 0.0
    speed_only: bool = False

    @property
    def textureless(self) -> bool:
        return self.floor_family == "textureless"

    def to_json(self) -> dict[str, object]:
        d = asdict(self)
        d["strides"] = {m: asdict(v) for m, v in self.strides.items()}
        return d


def session_facts(path: Path) -> dict[str, object]:
    """Floor family, seed, subject height, speed and walk length of a simulated session."""
    cfg = yaml.safe_load((path / "sim_config.yaml").read_text()) or {}
    extra = yaml.safe_load((path / "session.yaml").read_text()).get("extra", {})
    subject = yaml.safe_load((path / "groundtruth" / "subject.yaml").read_text()) or {}
    gait = cfg.get("gait", {})
    return {
        "floor_family": str(extra.get("floor_family", cfg.get("scene", {}).get("floor_family"))),
        "seed": extra.get("simulator_seed"),
        "height_m": float(subject.get("height_m", math.nan)),
        "speed_mps": float(gait.get("speed_mps", math.nan)),
        "walk_length_m": float(gait.get("walk_length_m", math.nan)),
    }


def run_session(
    path: Path, vio_cfg: VioConfig, subject: str | None = None, speed_only: bool = False
) -> SessionOutcome:
    """Run ``run_vio`` on one simulated session and evaluate it against its ground truth;
    ``subject`` labels it in the per-subject table (the folder name when None); a
    ``speed_only`` session stays out of the accuracy tables. A run that fails is recorded
    with its message (an error other than a :class:`GaitnetError` is a bug: logged with its
    traceback), its true strides counted as unmatched."""
    from gaitnet.vio.run import run_vio

    facts = session_facts(path)
    source = open_session(path)
    times_ns = np.asarray(source.frame_times_ns, dtype=np.int64)
    ref = read_strides(path / "groundtruth" / "strides.csv", SessionError)
    out = SessionOutcome(
        name=path.name,
        path=str(path),
        subject=subject or path.name,
        height_m=facts["height_m"],  # type: ignore[arg-type]
        speed_mps=facts["speed_mps"],  # type: ignore[arg-type]
        walk_length_m=facts["walk_length_m"],  # type: ignore[arg-type]
        floor_family=facts["floor_family"],  # type: ignore[arg-type]
        seed=facts["seed"],  # type: ignore[arg-type]
        n_frames=len(source),
        duration_s=float(times_ns[-1] - times_ns[0]) * 1e-9,
        speed_only=speed_only,
    )
    wall0, cpu0, main0 = time.perf_counter(), time.process_time(), time.thread_time()
    try:
        result = run_vio(source, vio_cfg)
    except Exception as err:  # a long benchmark goes on; a bug is logged with its trace
        if isinstance(err, GaitnetError):
            log.warning("%s: the run failed: %s", path, err)
            out.failure = str(err)
        else:
            log.exception("%s: the run failed with a bug", path)
            out.failure = f"bug: {type(err).__name__}: {err}"
        for method in METHODS:
            out.strides[method] = MethodStrides(unmatched_truth=len(ref))
        return out
    cpu, main = time.process_time() - cpu0, time.thread_time() - main0
    out.wall_s = time.perf_counter() - wall0
    stages = {k: float(v) for k, v in result.timings_s.items()}
    smoother = stages.get("smoother", 0.0)
    out.stage_cpu_s = stages
    out.cpu_s = {
        "total": cpu,
        "main_thread": main,
        "other_threads": cpu - main,
        "filter": cpu - smoother,
        "smoother": smoother,
        "main_thread_untimed": main - sum(stages.values()),
    }
    out.strides = {
        "smoothed": compare_strides(stride_rows(result.strides), ref),
        "filter": compare_strides(stride_rows(result.strides_filter), ref),
        "imu_only": compare_strides(imu_only_strides(result), ref),
    }
    truth = np.loadtxt(path / "groundtruth" / "camera_frames.tum", ndmin=2)
    i, j = match_times(times_ns[result.session_index], np.round(truth[:, 0] * 1e9))
    trajectories = {
        "smoothed": result.T_WfromC_smoothed,
        "filter": result.T_WfromC_filter,
        "imu_only": result.T_WfromC_imu_only,
    }
    for method, T in trajectories.items():
        if T is not None and len(i) >= 2:
            out.ate_m[method] = ate_yaw_aligned(T[i, :3, 3], truth[j, 1:4])
    out.smoother_ran = bool(result.smoother.get("ran", False))
    out.smoother_iterations = int(result.smoother.get("iterations", 0) or 0)
    out.vo_used = int(result.used.get("vo", 0))
    out.vo_skipped = int(sum(result.skipped.get("vo", {}).values()))
    return out


# --- aggregation -------------------------------------------------------------------------------


def error_stats(errors: Sequence[float]) -> dict[str, float]:
    """n, RMSE, maximum |error|, mean and standard deviation (population: RMSE² = mean² +
    std²) of stride-length errors [m]; NaN where there is no error."""
    e = np.asarray(errors, dtype=float)
    if len(e) == 0:
        nan = math.nan
        return {"n": 0, "rmse_m": nan, "max_m": nan, "mean_m": nan, "std_m": nan}
    return {
        "n": int(len(e)),
        "rmse_m": float(np.sqrt(np.mean(e**2))),
        "max_m": float(np.max(np.abs(e))),
        "mean_m": float(np.mean(e)),
        "std_m": float(np.std(e)),
    }


def _in_scope(o: SessionOutcome, scope: str) -> bool:
    if o.speed_only:
        return False
    return scope == "all" or (scope == "textureless") == o.textureless


def per_subject_table(outcomes: Sequence[SessionOutcome], method: str) -> dict[str, dict]:
    """Thesis Table 5.2: per subject and side, the statistics of the matched strides' errors
    over all the subject's trials."""
    table: dict[str, dict] = {}
    for o in outcomes:
        if o.speed_only:
            continue
        row = table.setdefault(
            o.subject,
            {"height_m": o.height_m, "speed_mps": o.speed_mps, "errors": {s: [] for s in SIDES}},
        )
        if method in o.strides:
            for side in SIDES:
                row["errors"][side] += o.strides[method].errors_m[side]
    return {
        subject: {
            "height_m": row["height_m"],
            "speed_mps": row["speed_mps"],
            **{side: error_stats(row["errors"][side]) for side in SIDES},
        }
        for subject, row in table.items()
    }


def overall(outcomes: Sequence[SessionOutcome], method: str, scope: str) -> dict[str, object]:
    """Pooled statistics of one method's matched strides over the sessions of ``scope``, the
    unmatched counts, and the thesis's overall figure: the plain mean of the per-subject,
    per-side RMSEs (docs/references.md)."""
    chosen = [o for o in outcomes if _in_scope(o, scope) and method in o.strides]
    errors = [e for o in chosen for side in SIDES for e in o.strides[method].errors_m[side]]
    rmses = [
        stats["rmse_m"]
        for row in per_subject_table(chosen, method).values()
        for stats in (row[s] for s in SIDES)
        if stats["n"]
    ]
    return {
        **error_stats(errors),
        "sessions": len(chosen),
        "unmatched_estimate": sum(o.strides[method].unmatched_estimate for o in chosen),
        "unmatched_truth": sum(o.strides[method].unmatched_truth for o in chosen),
        "mean_of_subject_side_rmse_m": float(np.mean(rmses)) if rmses else math.nan,
    }


def ate_summary(outcomes: Sequence[SessionOutcome], method: str, scope: str) -> dict[str, float]:
    """Mean and maximum body ATE [m] over the sessions of ``scope`` that have one."""
    v = [o.ate_m[method] for o in outcomes if _in_scope(o, scope) and method in o.ate_m]
    if not v:
        return {"n": 0, "mean_m": math.nan, "max_m": math.nan}
    return {"n": len(v), "mean_m": float(np.mean(v)), "max_m": float(np.max(v))}


def speed_summary(outcomes: Sequence[SessionOutcome]) -> dict[str, object]:
    """Filter CPU ms per frame (mean, p95, max over sessions) with its per-stage breakdown
    (frame-weighted means), the smoother's CPU seconds per session and scaled to a 60 s
    session (per session: × 60 / duration; a least-squares line through the sessions when
    there are 3 or more whose durations span a factor of 1.5 or more; and
    measured on the 60 s sessions, ``speed_only``, when there are any)."""
    ran = [o for o in outcomes if o.failure is None and o.cpu_s]
    if not ran:
        return {}
    frames = np.array([o.n_frames for o in ran], dtype=float)
    per_frame = np.array([1e3 * o.cpu_s["filter"] / o.n_frames for o in ran])
    keys = sorted({k for o in ran for k in o.stage_cpu_s} - {"smoother"})
    stages = {k: 1e3 * sum(o.stage_cpu_s.get(k, 0.0) for o in ran) / frames.sum() for k in keys}
    stages["frame decoding and other threads"] = (
        1e3 * sum(o.cpu_s["other_threads"] for o in ran) / frames.sum()
    )
    stages["main thread outside the stages"] = (
        1e3 * sum(o.cpu_s["main_thread_untimed"] for o in ran) / frames.sum()
    )
    smoother = np.array([o.cpu_s["smoother"] for o in ran])
    duration = np.array([o.duration_s for o in ran])
    scaled = smoother * 60.0 / duration
    fit = math.nan
    if len(ran) >= 3 and duration.max() >= 1.5 * duration.min():  # else the slope is noise
        slope, intercept = np.polyfit(duration, smoother, 1)
        fit = float(intercept + 60.0 * slope)
    long = [o for o in ran if o.speed_only]
    return {
        "sessions": len(ran),
        "filter_ms_per_frame": {
            "mean": float(np.mean(per_frame)),
            "frame_weighted_mean": float(1e3 * sum(o.cpu_s["filter"] for o in ran) / frames.sum()),
            "p95": float(np.percentile(per_frame, 95)),
            "max": float(np.max(per_frame)),
            "target": FILTER_TARGET_MS,
        },
        "filter_stages_ms_per_frame": stages,
        "smoother_s": {
            "mean_per_session": float(np.mean(smoother)),
            "max_per_session": float(np.max(smoother)),
            "mean_session_duration_s": float(np.mean(duration)),
            "per_60s_session_mean": float(np.mean(scaled)),
            "per_60s_session_max": float(np.max(scaled)),
            "per_60s_session_linear_fit": fit,
            "measured_on_long_sessions": [
                {"duration_s": o.duration_s, "smoother_s": o.cpu_s["smoother"]} for o in long
            ],
            "target_per_60s": SMOOTHER_TARGET_S_PER_60S,
        },
        "wall_s_total": float(sum(o.wall_s for o in ran)),
        "cpu_s_total": float(sum(o.cpu_s["total"] for o in ran)),
    }


def summarise(outcomes: Sequence[SessionOutcome]) -> dict[str, object]:
    """Every table of the benchmark as plain data (the ``--json`` file's ``summary``)."""
    return {
        "per_subject": {m: per_subject_table(outcomes, m) for m in METHODS},
        "overall": {m: {s: overall(outcomes, m, s) for s in SCOPES} for m in METHODS},
        "ate": {m: {s: ate_summary(outcomes, m, s) for s in SCOPES} for m in METHODS},
        "speed": speed_summary(outcomes),
        "failures": {o.name: o.failure for o in outcomes if o.failure is not None},
    }
