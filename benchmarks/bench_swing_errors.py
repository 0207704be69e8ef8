"""Where the error of ``gaitnet infer``'s filled swing frames comes from, on simulated sessions.

For each session folder (``gaitnet simulate`` output, with ``groundtruth/``) the observations
are computed or taken from ``--cache`` (the cache of ``bench_infer.py``), the reconstruction
runs with the default config (``--set`` overrides), and two things are compared with the truth:

1. **Timing of each swing** (:func:`gaitnet.pipeline.swing_fill.plan_swings`, the feet's
   pairs but their first): its start against the true heel off of the rest it leaves and its
   landing (the landmark's first frame) against the true foot flat (``events.csv``), per side;
   with the share of swings whose start the bound of the foot's last resting frame set
   (``from_rest_end``: the timing line put it earlier), and their start's error apart; and
   its start against the start that lays the template best over the true path of the point
   the template follows (the keypoint as the pose correction models it, ankle +
   ``G_ank`` · ``KEYPOINT_OFFSET_M`` on the true pose of ``groundtruth/joints.npz``; over the
   swing's filled frames, its landing fixed, the true resting points as its rests: the
   least mean |·| of the progress along the step, over starts 2 ms apart), which is the
   start the filled frames' error depends on (heel off varies between subjects more than the
   swing does).
2. **Error of the output's filled frames** (``foot_nmate_filled_m``'s frames and alignment:
   :mod:`gaitnet.evaluation.feet`), per side, split along the walking direction (start to end
   of the true path), across it (positive: to the left) and vertically: mean and mean |·| in
   cm, over all filled frames and per tenth of the true swing (τ = 0 at heel off, 1 at the
   next foot flat).

    python benchmarks/bench_swing_errors.py SESSION [SESSION ...] [--cache DIR]
        [--segmenter X.onnx|oracle] [--set KEY=VALUE ...]

docs/pipeline.md (*Swing fill*, measured and not adopted) has the figures.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import yaml
from bench_infer import cached_observations
from bench_swing_fill import keypoints_on_pose

from gaitnet.config import load_config
from gaitnet.errors import InputError, SessionError
from gaitnet.evaluation.feet import read_feet
from gaitnet.evaluation.metrics import align_yaw_translation, match_times
from gaitnet.motion.onnx_runtime import OnnxPredictor
from gaitnet.motion.skeleton import from_rest_joints
from gaitnet.pipeline.config import InferConfig
from gaitnet.pipeline.infer import default_predictor_path, reconstruct
from gaitnet.pipeline.swing_fill import (
    MIN_SPAN_S,
    SWING_PROGRESS,
    SWING_TAU,
    SwingPlan,
    plan_swings,
)
from gaitnet.training.scripts import ScriptParser

SIDES = ("left", "right")
TAU_BINS = np.linspace(0.0, 1.0, 11)


def true_events(session_dir: Path) -> dict[str, list[tuple[float, float]]]:
    """Per side, ``(foot_flat_s, heel_off_s)`` of each true stance (NaN where it has none);
    an :class:`InputError` naming the file when ``events.csv`` or ``feet.csv`` is missing or
    the events do not read."""
    path = session_dir / "groundtruth" / "events.csv"
    if not path.is_file():
        raise InputError(f"{path}: missing (a simulated session's ground truth is needed)")
    if not (session_dir / "groundtruth" / "feet.csv").is_file():
        raise InputError(f"{session_dir / 'groundtruth' / 'feet.csv'}: missing")
    out: dict[str, list[tuple[float, float]]] = {side: [] for side in SIDES}
    try:
        with path.open(newline="", encoding="utf-8") as f:
            for row in csv.DictReader(f):
                flat, off = (
                    float(row[k]) if row[k] else np.nan for k in ("foot_flat_s", "heel_off_s")
                )
                out[row["side"]].append((flat, off))
    except (KeyError, TypeError, ValueError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: not a simulator events file ({exc!r})") from None
    return out


def true_keypoints(session_dir: Path) -> tuple[np.ndarray, np.ndarray]:
    """``t_ns`` (n,) and the true keypoint of each foot (n, 2, 3) as the pose correction models
    it (:func:`bench_swing_fill.keypoints_on_pose`), on the true pose and skeleton of
    ``groundtruth/joints.npz`` and the height of ``subject.yaml``; an :class:`InputError`
    naming the folder when either is missing or unreadable."""
    truth = session_dir / "groundtruth"
    try:
        with np.load(truth / "joints.npz") as z:
            t_ns, root, trans, aa = z["t_ns"], z["root_orient"], z["trans"], z["joint_aa"]
            skel = from_rest_joints(z["rest_joints"])
        height = float(yaml.safe_load((truth / "subject.yaml").read_text())["height_m"])
    except (OSError, KeyError, TypeError, ValueError, yaml.YAMLError) as exc:
        raise InputError(f"{truth}: no true pose and subject height ({exc!r})") from None
    return t_ns, keypoints_on_pose(skel, root, trans, aa, height)


def swing_timing(stances: list[tuple[float, float]], heel_off_s: float, landing_s: float):
    """(start − true heel off, landing − true foot flat) [s] of one swing: the true stance it
    lands in is the one whose foot flat is nearest the landing, the one before it the rest it
    leaves; None when either is missing."""
    flats = np.array([s[0] for s in stances])
    if not np.isfinite(flats).any():
        return None
    k = int(np.nanargmin(np.abs(flats - landing_s)))
    if k == 0 or not np.isfinite(stances[k - 1][1]):
        return None
    return heel_off_s - stances[k - 1][1], landing_s - flats[k]


def best_start(
    plan: SwingPlan, t_s: np.ndarray, point: np.ndarray, stances: list[tuple[float, float]]
) -> float:
    """The start [s] that lays the template best over the true path (n, 3) of the point it
    follows in the plan's filled frames (module docstring), its landing fixed; the rests are
    the median true point over the foot flat → heel off frames of the two true stances around
    the landing (the next one's first 0.1 s where it has no heel off); frames without a true
    point (NaN) are left out. NaN when a rest or the window has no frame, or the rests
    coincide."""
    flats = np.array([s[0] for s in stances])
    if not np.isfinite(flats).any():
        return float("nan")
    k = int(np.nanargmin(np.abs(flats - plan.landing_s)))
    if k == 0:
        return float("nan")
    (ff0, ho0), (ff1, ho1) = stances[k - 1], stances[k]
    end1 = ho1 if np.isfinite(ho1) else ff1 + 0.1
    known = np.isfinite(point[:, 0])
    rest0 = known & (t_s <= ho0) & (t_s >= ff0 if np.isfinite(ff0) else True)
    rest1 = known & (t_s >= ff1) & (t_s <= end1)
    window = known & plan.window
    if not rest0.any() or not rest1.any() or not window.any():
        return float("nan")
    p0, p1 = np.median(point[rest0], axis=0), np.median(point[rest1], axis=0)
    step = (p1 - p0)[:2]
    length = float(np.hypot(step[0], step[1]))
    if length < 1e-6:
        return float("nan")
    progress = (point[window, :2] - p0[:2]) @ (step / length) / length
    t = t_s[window][:, None]
    starts = plan.landing_s - np.arange(MIN_SPAN_S, 1.5, 0.002)[None, :]
    tau = np.clip((t - starts) / (plan.landing_s - starts), 0.0, 1.0)
    cost = np.abs(np.interp(tau, SWING_TAU, SWING_PROGRESS) - progress[:, None]).mean(axis=0)
    return float(starts[0, int(np.argmin(cost))])


def true_tau(stances: list[tuple[float, float]], t: np.ndarray) -> np.ndarray:
    """τ of each time within the true swing around it (heel off → next foot flat); NaN
    outside any swing."""
    tau = np.full(len(t), np.nan)
    for (_, off), (flat, _) in zip(stances, stances[1:], strict=False):
        if np.isfinite(off) and np.isfinite(flat) and flat > off:
            inside = (t >= off) & (t < flat)
            tau[inside] = (t[inside] - off) / (flat - off)
    return tau


def _row(label: str, e: np.ndarray) -> str:
    mean, mean_abs = 100 * e.mean(axis=0), 100 * np.abs(e).mean(axis=0)
    cells = "  ".join(f"{m:+6.2f} |{a:5.2f}|" for m, a in zip(mean, mean_abs, strict=True))
    return f"  {label:14s} n {len(e):5d}  {cells}"


def main() -> None:
    ap = ScriptParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("sessions", nargs="+", type=Path)
    ap.add_argument("--segmenter", default=None, help="ONNX file or 'oracle'")
    ap.add_argument("--cache", type=Path, default=None, help="bench_infer.py's cache folder")
    ap.add_argument(
        "--set", dest="overrides", nargs="*", default=[], metavar="KEY=VALUE",
        help="infer config overrides",
    )  # fmt: skip
    args = ap.parse_args()
    cfg = load_config(InferConfig, None, args.overrides)
    p = cfg.pipeline
    predictor = OnnxPredictor(default_predictor_path())
    timing: dict[str, list[tuple[float, float, bool, float]]] = {side: [] for side in SIDES}
    errors: dict[str, list[np.ndarray]] = {side: [] for side in SIDES}
    for session_dir in args.sessions:
        events = true_events(session_dir)
        obs = cached_observations(session_dir, cfg, args.segmenter, args.cache)
        t_kp, p_kp = true_keypoints(session_dir)
        keypoints = np.full((len(obs.t_ns), 2, 3), np.nan)
        at_frame, at_truth = match_times(obs.t_ns, t_kp)
        keypoints[at_frame] = p_kp[at_truth]
        plans = plan_swings(obs.vio.t_s, obs.foot_W, obs.vio.stance_feet, **p.swing_timing())
        for plan in plans:
            side = SIDES[plan.side]
            found = (
                None if plan.first else swing_timing(events[side], plan.heel_off_s, plan.landing_s)
            )
            if found is not None:
                best = best_start(plan, obs.vio.t_s, keypoints[:, plan.side], events[side])
                timing[side].append((*found, plan.from_rest_end, plan.heel_off_s - best))
        result = reconstruct(obs, cfg, predictor)
        t_ref, p_ref, _ = read_feet(session_dir / "groundtruth" / "feet.csv", SessionError, False)
        i, j = match_times(result.t_ns, t_ref)
        for s, side in enumerate(SIDES):
            est, ref = result.feet_W[i, s], p_ref[side][j]
            R, t = align_yaw_translation(est, ref)
            e = (est @ R.T + t - ref)[~result.foot_measured[i, s]]
            ahead = ref[-1, :2] - ref[0, :2]
            ahead /= np.linalg.norm(ahead)
            left = np.array([-ahead[1], ahead[0]])
            tau = true_tau(events[side], result.t_s[i][~result.foot_measured[i, s]])
            errors[side].append(np.c_[e[:, :2] @ ahead, e[:, :2] @ left, e[:, 2], tau])
    print(f"{len(args.sessions)} sessions")
    print("swing timing (pairs but each foot's first), ms: median / mean |·|")
    for side in SIDES:
        a = np.array(timing[side], dtype=float).reshape(-1, 4)
        if not len(a):
            print(f"  {side}: no swings")
            continue
        rest_end = a[:, 2] == 1
        print(
            f"  {side:5s} {len(a):4d} swings: start − heel off {1e3 * np.median(a[:, 0]):+5.0f}"
            f" / {1e3 * np.abs(a[:, 0]).mean():3.0f}; landing − foot flat"
            f" {1e3 * np.median(a[:, 1]):+5.0f} / {1e3 * np.abs(a[:, 1]).mean():3.0f}; start from"
            f" the rest's end in {rest_end.sum()} (their start − heel off "
            f"{1e3 * np.median(a[rest_end, 0]) if rest_end.any() else np.nan:+.0f}, the others' "
            f"{1e3 * np.median(a[~rest_end, 0]) if (~rest_end).any() else np.nan:+.0f})"
        )
        best = a[np.isfinite(a[:, 3]), 3]
        if len(best):
            print(
                f"        start − best-laying start {1e3 * np.median(best):+5.0f}"
                f" / {1e3 * np.abs(best).mean():3.0f} ({len(best)} swings)"
            )
    print("filled frames, cm: mean |mean abs| along the walk, across it (+ left), vertical")
    for side in SIDES:
        e = np.concatenate(errors[side])
        print(f" {side}")
        if not len(e):
            print("  no filled frames")
            continue
        print(_row("all", e[:, :3]))
        for lo, hi in zip(TAU_BINS[:-1], TAU_BINS[1:], strict=True):
            inside = (e[:, 3] >= lo) & (e[:, 3] < hi)
            if inside.any():
                print(_row(f"τ {lo:.1f}–{hi:.1f}", e[inside, :3]))
        outside = np.isnan(e[:, 3])
        if outside.any():
            print(_row("not in a swing", e[outside, :3]))


if __name__ == "__main__":
    from gaitnet.cli.scripts import run_script

    raise SystemExit(run_script(main))
