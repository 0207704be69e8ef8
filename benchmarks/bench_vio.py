"""The filter and smoother on simulated sessions: thesis sec. 5.2's stride-length protocol.

Without session folders, runs the protocol of ``benchmarks/vio_protocol.py`` (its docstring
has the details): 5 simulated subjects of fixed height and speed (S1 1.55 m 1.05 m/s, S2 1.63 m
1.40 m/s, S3 1.72 m 0.90 m/s, S4 1.81 m 1.20 m/s, S5 1.90 m 1.50 m/s) × straight walks of 5,
10 and 15 m × ``--trials`` trials (default 2), the floor family rotating over the trials so
every family appears, seeds 1000 + 100·subject + 30·length + trial (never used for tuning),
and one session of about 60 s (S4 walking 64.8 m, seed 1500; ``--no-long`` leaves it out)
that times the smoother on the session length of its budget and stays out of the accuracy
tables.
Sessions are simulated into ``--sessions-dir`` first and reused when a cached one has the same
seed and config. Then ``run_vio`` runs on each with the default config (or ``--vio-config``)
and prints:

- one row per session: floor, smoothed strides matched per side with their RMSE and maximum
  error, the filter's and the IMU-only strides' RMSE, body ATE (smoothed / filter /
  IMU-only), VO updates used/skipped, filter CPU ms per frame, smoother CPU seconds;
- thesis Table 5.2 for the smoothed strides: per subject and side, maximum |error|, RMSE,
  standard deviation of the error and the number of matched strides;
- overall rows for IMU-only, filter and smoother (pooled RMSE, maximum, std, matched and
  unmatched strides, and the thesis's figure: the mean of the per-subject-side RMSEs), for all
  trials, textured floors and textureless floors separately;
- body ATE (yaw + translation aligned) per method: mean and maximum over sessions;
- speed: filter CPU ms per frame (mean and p95 over sessions, target ≤ 33 ms per 640×480 frame
  on one core) with the CPU per stage, and the smoother's CPU seconds per session and scaled to
  a 60 s session (target ≤ 2 s; measured on the 60 s session when it ran, else a linear fit
  over the sessions' durations).

IMU-only strides: the IMU-only dead reckoning has no stance feet; its stride is the filter's
pair of same-side stances, each stance's floor point carried from the filter's camera pose to
the IMU-only camera pose at the stance's first observation (vio_protocol.py).

One thread for OpenMP, BLAS and OpenCV; CPU times with ``time.process_time`` (all threads:
the reader's background PNG decoding counts) and per stage with the main thread's CPU clock.

    python benchmarks/bench_vio.py [--trials N] [--sessions-dir DIR] [--json FILE]
    python benchmarks/bench_vio.py --quick            # S1, 5 m, 1 trial
    python benchmarks/bench_vio.py --sessions SESSION [SESSION ...]   # given folders
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import datetime  # noqa: E402
import json  # noqa: E402
import logging  # noqa: E402
import math  # noqa: E402
import platform  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import vio_protocol as vp  # noqa: E402

from gaitnet.config import load_config  # noqa: E402
from gaitnet.evaluation.strides import SIDES  # noqa: E402
from gaitnet.training.scripts import ScriptParser  # noqa: E402
from gaitnet.vio.config import VioConfig  # noqa: E402

DEFAULT_SESSIONS_DIR = Path("/tmp/gaitnet-bench/sessions")


def _cm(value: float) -> str:
    return "—" if value is None or not math.isfinite(value) else f"{100 * value:.2f}"


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def _indices(text: str, n: int, what: str) -> list[int]:
    """1-based comma-separated indices → 0-based."""
    try:
        picked = [int(v) - 1 for v in text.split(",") if v.strip()]
    except ValueError:
        raise SystemExit(
            f"--{what}: give 1-based numbers separated by commas, got {text!r}"
        ) from None
    if not picked or any(not 0 <= k < n for k in picked):
        raise SystemExit(f"--{what}: numbers must be 1–{n}, got {text!r}")
    return picked


def _session_row(o: vp.SessionOutcome) -> str:
    if o.failure is not None:
        return f"{o.name} | {o.floor_family} | FAILED: {o.failure}"
    if o.speed_only:
        return (
            f"{o.name} | {o.floor_family} | timing only, {o.duration_s:.1f} s, {o.n_frames} "
            f"frames | filter CPU {1e3 * o.cpu_s['filter'] / o.n_frames:.1f} ms/frame | "
            f"smoother CPU {o.cpu_s['smoother']:.2f} s"
        )
    s = o.strides["smoothed"]
    stats = {side: vp.error_stats(s.errors_m[side]) for side in SIDES}
    pooled = {m: vp.error_stats(sum(o.strides[m].errors_m.values(), [])) for m in vp.METHODS}
    ate = " / ".join(_cm(o.ate_m.get(m, math.nan)) for m in vp.METHODS)
    return (
        f"{o.name} | {o.floor_family} | {stats['left']['n']}/{stats['right']['n']} "
        f"(+{s.unmatched_estimate} / −{s.unmatched_truth}) | "
        f"{_cm(stats['left']['rmse_m'])}/{_cm(stats['right']['rmse_m'])} | "
        f"{_cm(stats['left']['max_m'])}/{_cm(stats['right']['max_m'])} | "
        f"{_cm(pooled['filter']['rmse_m'])} | {_cm(pooled['imu_only']['rmse_m'])} | {ate} | "
        f"{o.vo_used}/{o.vo_skipped} | {1e3 * o.cpu_s['filter'] / o.n_frames:.1f} | "
        f"{o.cpu_s['smoother']:.2f}{'' if o.smoother_ran else ' (did not run)'}"
    )


def _print_summary(summary: dict, outcomes: list[vp.SessionOutcome]) -> None:
    print("\nStride length, smoothed (thesis Table 5.2), cm: max |error| / RMSE / std (n)")
    print("subject | height | speed | left | right")
    table = summary["per_subject"]["smoothed"]
    for subject, row in table.items():
        cells = [
            f"{_cm(row[side]['max_m'])} / {_cm(row[side]['rmse_m'])} / "
            f"{_cm(row[side]['std_m'])} ({row[side]['n']})"
            for side in SIDES
        ]
        print(
            f"{subject} | {row['height_m']:.2f} m | {row['speed_mps']:.2f} m/s | "
            f"{cells[0]} | {cells[1]}"
        )

    print(
        "\nOverall stride-length error, cm (pooled over matched strides; 'thesis' = mean of the"
        " per-subject-side RMSEs, as Table 5.2's 3.8 cm)"
    )
    print(
        "method | floors | sessions | matched | unmatched est/true | RMSE | max | mean | std"
        " | thesis"
    )
    for method in ("imu_only", "filter", "smoothed"):
        for scope in vp.SCOPES:
            r = summary["overall"][method][scope]
            if not r["sessions"]:
                continue
            print(
                f"{method} | {scope} | {r['sessions']} | {r['n']} | "
                f"{r['unmatched_estimate']}/{r['unmatched_truth']} | {_cm(r['rmse_m'])} | "
                f"{_cm(r['max_m'])} | {_cm(r['mean_m'])} | {_cm(r['std_m'])} | "
                f"{_cm(r['mean_of_subject_side_rmse_m'])}"
            )
    print(
        "IMU-only strides: the filter's same-side stance pairs, each stance's floor point moved"
        " from the filter's to the IMU-only camera pose at its first observation."
    )

    print("\nBody (camera) ATE, yaw + translation aligned, cm: mean / max over sessions")
    print("method | all | textured | textureless")
    for method in ("imu_only", "filter", "smoothed"):
        cells = []
        for scope in vp.SCOPES:
            a = summary["ate"][method][scope]
            cells.append(f"{_cm(a['mean_m'])} / {_cm(a['max_m'])} ({a['n']})")
        print(f"{method} | " + " | ".join(cells))

    speed = summary["speed"]
    if speed:
        f = speed["filter_ms_per_frame"]
        print(
            f"\nSpeed ({speed['sessions']} sessions, one thread, {_cpu_model()}, "
            f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs)"
        )
        print(
            f"filter: {f['mean']:.1f} ms CPU per frame (mean over sessions; frame-weighted "
            f"{f['frame_weighted_mean']:.1f}), p95 {f['p95']:.1f}, max {f['max']:.1f}; "
            f"target ≤ {f['target']:.0f}: {'met' if f['p95'] <= f['target'] else 'NOT met'}"
        )
        stages = speed["filter_stages_ms_per_frame"]
        total = sum(stages.values())
        print("  where the filter's time goes (CPU, ms per frame, share):")
        for name, ms in sorted(stages.items(), key=lambda kv: -kv[1]):
            print(f"    {name:34s} {ms:6.2f}  {100 * ms / total:4.0f} %")
        s = speed["smoother_s"]
        fit = s["per_60s_session_linear_fit"]
        print(
            f"smoother: {s['mean_per_session']:.2f} s CPU per session (max "
            f"{s['max_per_session']:.2f}; sessions {s['mean_session_duration_s']:.1f} s on "
            f"average); scaled to 60 s of session {s['per_60s_session_mean']:.2f} (max "
            f"{s['per_60s_session_max']:.2f}; linear fit over the sessions "
            f"{'—' if not math.isfinite(fit) else f'{fit:.2f}'})"
        )
        long = s["measured_on_long_sessions"]
        for run in long:
            print(f"  measured on a {run['duration_s']:.1f} s session: {run['smoother_s']:.2f} s")
        if long:
            figure, how = max(60.0 * r["smoother_s"] / r["duration_s"] for r in long), "measured"
        elif math.isfinite(fit):
            figure, how = fit, "linear fit"
        else:
            figure, how = s["per_60s_session_max"], "scaled"
        verdict = "met" if figure <= s["target_per_60s"] else "NOT met"
        print(
            f"  smoother per 60 s session ({how}): {figure:.2f} s; target ≤ "
            f"{s['target_per_60s']:.0f} s: {verdict}"
        )
    if summary["failures"]:
        print(f"\n{len(summary['failures'])} run(s) failed (their true strides are unmatched):")
        for name, why in summary["failures"].items():
            print(f"  {name}: {why}")
    missing = set(vp.FLOOR_FAMILIES) - {o.floor_family for o in outcomes}
    if missing:
        print(f"floor families not in this run: {', '.join(sorted(missing))}")


def _json_safe(value: object) -> object:
    if isinstance(value, dict):
        return {str(k): _json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_safe(v) for v in value]
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    return value


def main() -> None:
    parser = ScriptParser(
        description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("folders", nargs="*", type=Path, help="session folders (as --sessions)")
    parser.add_argument(
        "--sessions",
        nargs="+",
        type=Path,
        default=[],
        metavar="SESSION",
        help="run on these simulated session folders instead of the protocol",
    )
    parser.add_argument("--trials", type=int, default=2, help="trials per subject and length")
    parser.add_argument("--subjects", default="1,2,3,4,5", help="subjects, e.g. 1,3 (1–5)")
    parser.add_argument("--lengths", default="1,2,3", help="walk lengths, 1–3 = 5, 10, 15 m")
    parser.add_argument("--quick", action="store_true", help="S1, 5 m, 1 trial")
    parser.add_argument(
        "--no-long", action="store_true", help="without the 60 s session timing the smoother"
    )
    parser.add_argument(
        "--sessions-dir",
        type=Path,
        default=DEFAULT_SESSIONS_DIR,
        help=f"where protocol sessions are cached (default {DEFAULT_SESSIONS_DIR})",
    )
    parser.add_argument("--workers", type=int, default=None, help="simulator render processes")
    parser.add_argument("--vio-config", type=Path, default=None, help="VIO config YAML")
    parser.add_argument("--json", type=Path, default=None, help="write every figure here")
    args = parser.parse_args()
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    cv2.setNumThreads(1)
    vio_cfg = load_config(VioConfig, args.vio_config) if args.vio_config else VioConfig()

    folders = [*args.folders, *args.sessions]
    jobs: list[tuple[Path, str | None, bool]] = []
    protocol: dict[str, object] = {"mode": "folders"}
    if folders:
        jobs = [(f, None, False) for f in folders]
    else:
        if args.quick:
            subjects, lengths, trials = [0], [0], 1
        else:
            subjects = _indices(args.subjects, len(vp.SUBJECTS), "subjects")
            lengths = _indices(args.lengths, len(vp.WALK_LENGTHS_M), "lengths")
            trials = args.trials
        if not 1 <= trials <= vp.MAX_TRIALS:
            raise SystemExit(f"--trials must be 1–{vp.MAX_TRIALS}")
        plan = vp.protocol_trials(subjects, lengths, trials)
        if not (args.quick or args.no_long):
            plan.append(vp.long_trial())
        protocol = {
            "mode": "quick" if args.quick else "protocol",
            "subjects": [vars(vp.SUBJECTS[s]) for s in subjects],
            "walk_lengths_m": [vp.WALK_LENGTHS_M[k] for k in lengths],
            "trials": trials,
            "sim_config": str(vp.SIM_CONFIG.relative_to(vp.REPO)),
            "sessions": [
                {
                    "name": t.name,
                    "seed": t.seed,
                    "floor_family": t.floor_family,
                    "walk_length_m": t.walk_length_m,
                    "speed_only": t.speed_only,
                }
                for t in plan
            ],
        }
        args.sessions_dir.mkdir(parents=True, exist_ok=True)
        print(f"{len(plan)} protocol sessions in {args.sessions_dir}")
        for trial in plan:
            folder, seconds = vp.ensure_session(trial, args.sessions_dir, args.workers)
            made = "cached" if seconds is None else f"simulated in {seconds:.0f} s"
            print(f"  {trial.name}: {trial.floor_family}, {made}", flush=True)
            jobs.append((folder, trial.subject.label, trial.speed_only))

    print(
        "\nsession | floor | smoothed strides L/R (+unmatched est / −unmatched true) | "
        "RMSE L/R [cm] | max L/R [cm] | filter RMSE [cm] | IMU-only RMSE [cm] | "
        "ATE smoothed / filter / IMU-only [cm] | VO used/skipped | filter CPU ms/frame | "
        "smoother CPU s"
    )
    outcomes: list[vp.SessionOutcome] = []
    t0 = time.perf_counter()
    for folder, subject, speed_only in jobs:
        outcome = vp.run_session(folder, vio_cfg, subject, speed_only)
        outcomes.append(outcome)
        print(_session_row(outcome), flush=True)
    summary = vp.summarise(outcomes)
    _print_summary(summary, outcomes)
    print(f"\n{len(outcomes)} sessions in {time.perf_counter() - t0:.0f} s wall")
    if args.json is not None:
        doc = {
            "date": datetime.datetime.now().isoformat(timespec="seconds"),
            "machine": {
                "cpu": _cpu_model(),
                "cpus": os.cpu_count(),
                "load_average_1min_at_end": os.getloadavg()[0],
                "python": platform.python_version(),
            },
            "protocol": protocol,
            "vio_config": str(args.vio_config) if args.vio_config else "defaults",
            "summary": summary,
            "sessions": [o.to_json() for o in outcomes],
        }
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(_json_safe(doc), indent=1, ensure_ascii=False) + "\n")
        print(f"wrote {args.json}")


if __name__ == "__main__":
    from gaitnet.cli.scripts import run_script

    raise SystemExit(run_script(main))
