"""Detectors of ``gaitnet.vio`` against simulated ground truth: tags, floor, feet, stances.

For each session folder (made by ``gaitnet simulate``; its ``groundtruth/`` is required):

* **tags** on every standing frame (both feet flat at the start or end): decoded tags per frame
  (of the sheet's 35), camera-position and -attitude error of :func:`detect_board_pose` against
  ``camera_frames.tum``, the normalised error ``e^T cov^{-1} e`` (mean ≈ 6 when ``cov6`` is
  honest), CPU ms per frame (one thread), with and without a pose guess (the filter's ROI search);
  for the two corner detectors, ``cv.aruco`` and AprilTag 3 (``tags.detector``), and with
  ``--all`` for more of their settings;
* **floor** on every ``--step``-th frame: angle between the fitted and the true normal, error of
  the camera height ``h`` (the floor is z = 0 up to mm relief), ms per frame, with the up prior
  from the true attitude tilted by a random 5° (an accelerometer during walking);
* **feet**: candidates per frame moved to the world with the true camera pose; each is matched to
  the true flat sole (``events.csv``) whose flat interval holds the frame time: distance in the
  floor plane (per point method), candidates without a flat foot within 10 cm, ms per frame;
* **stances**: :class:`StanceTracker` over all frames with the true poses; true stances found
  (recall), tracked stances that match a true one within 6 cm (precision), side accuracy.

    python benchmarks/bench_detectors.py SESSION [SESSION ...] [--parts tags floor feet stance]
        [--all]
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import csv  # noqa: E402
import time  # noqa: E402
from contextlib import contextmanager  # noqa: E402
from dataclasses import dataclass, replace  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2 as cv  # noqa: E402
import numpy as np  # noqa: E402

from gaitnet.geometry.floor_plane import FloorParams, fit_floor_depth  # noqa: E402
from gaitnet.geometry.rotation import so3_exp, so3_log  # noqa: E402
from gaitnet.io.session_folder import SessionFolder  # noqa: E402
from gaitnet.io.trajectory import read_tum  # noqa: E402
from gaitnet.training.scripts import ScriptParser  # noqa: E402
from gaitnet.vio import tag_detectors  # noqa: E402
from gaitnet.vio.apriltags import AprilTagParams, detect_board_pose  # noqa: E402
from gaitnet.vio.feet import FootParams, detect_foot_candidates  # noqa: E402

cv.setNumThreads(1)


@dataclass
class Truth:
    """A session and its ground truth."""

    session: SessionFolder
    T_WfromC: np.ndarray  # (n, 4, 4) per frame
    t_true_s: np.ndarray  # (n,) true exposure mid-times
    events: list[dict]

    @property
    def name(self) -> str:
        return self.session.root.name


def load_truth(path: str | Path) -> Truth:
    s = SessionFolder(path)
    gt = Path(path) / "groundtruth"
    t_tum, T = read_tum(gt / "camera_frames.tum")
    by_t = {round(t * 1e9): k for k, t in enumerate(t_tum)}
    idx = []
    for t_ns in s.frame_times_ns:
        k = by_t.get(int(t_ns))
        if k is None:  # TUM times are printed in seconds with 9 decimals
            k = int(np.argmin(np.abs(t_tum - t_ns * 1e-9)))
        idx.append(k)
    with open(gt / "frame_times.csv") as f:
        rows = {int(r["t_ns"]): float(r["true_exposure_mid_s"]) for r in csv.DictReader(f)
                if r["dropped"] == "0"}  # fmt: skip
    t_true = np.array([rows[int(t)] for t in s.frame_times_ns])
    with open(gt / "events.csv") as f:
        events = []
        for r in csv.DictReader(f):
            events.append(
                {
                    "side": r["side"],
                    "flat_start_s": float(r["flat_start_s"]),
                    "flat_end_s": float(r["flat_end_s"]),
                    "xy": np.array([float(r["sole_x_m"]), float(r["sole_y_m"])]),
                    "standing": r["heel_strike_s"] == "" or r["toe_off_s"] == "",
                }
            )
    return Truth(s, T[idx], t_true, events)


def standing_frames(tr: Truth) -> np.ndarray:
    """Frame indices where every foot is in a standing (start or end) flat interval."""
    out = []
    for k, t in enumerate(tr.t_true_s):
        sides = {e["side"] for e in tr.events
                 if e["standing"] and e["flat_start_s"] <= t <= e["flat_end_s"]}  # fmt: skip
        if sides == {"left", "right"}:
            out.append(k)
    return np.array(out, dtype=int)


def pose_error(T_est: np.ndarray, T_true: np.ndarray) -> tuple[float, float, np.ndarray]:
    """(position error m, attitude error deg, error vector [δθ, δp] in the cov6 convention)."""
    dth = so3_log(T_true[:3, :3].T @ T_est[:3, :3])  # R_est = R_true exp(δθ)
    dp = T_est[:3, 3] - T_true[:3, 3]
    return float(np.linalg.norm(dp)), float(np.degrees(np.linalg.norm(dth))), np.r_[dth, dp]


# ---------------------------------------------------------------------------- tags

#: aruco with its tuned settings (the corner noise floor that suits its corners: 0.25 px)
_ARUCO = AprilTagParams(detector="aruco", corner_sigma_px=0.25)
_CV_DEFAULT = replace(
    _ARUCO, upsample=1, corner_refinement="none", error_correction_rate=0.6, max_tag_error_px=1e9
)

#: name → (params, AprilTag 3 settings overriding tag_detectors.APRILTAG3_SETTINGS, max hamming,
#: search with a pose guess). Without --all only the rows marked * run.
# fmt: off
TAG_SETTINGS: dict[str, tuple[AprilTagParams, dict, int | None, bool]] = {
    "aruco opencv-default-x1": (_CV_DEFAULT, {}, None, False),
    "aruco x1-small-win": (replace(_CV_DEFAULT, adaptive_thresh_win_max=15,
                                   adaptive_thresh_win_step=4,
                                   min_marker_perimeter_rate=0.01), {}, None, False),
    "aruco x2-none": (replace(_CV_DEFAULT, upsample=2), {}, None, False),
    "aruco x2-subpix": (replace(_CV_DEFAULT, upsample=2, corner_refinement="subpix"), {}, None,
                        False),
    "aruco x2-contour": (replace(_CV_DEFAULT, upsample=2, corner_refinement="contour"), {}, None,
                         False),
    "aruco x4-contour-ec0.8": (replace(_ARUCO, upsample=4), {}, None, False),
    "*aruco x3-contour-ec0.8": (_ARUCO, {}, None, False),
    "*aruco x3 + ROI guess": (_ARUCO, {}, None, True),
    "apriltag3 quad_decimate2": (AprilTagParams(), {"quad_decimate": 2.0}, None, False),
    "apriltag3 quad_sigma0.8": (AprilTagParams(), {"quad_sigma": 0.8}, None, False),
    "apriltag3 no refine_edges": (AprilTagParams(), {"refine_edges": 0}, None, False),
    "apriltag3 hamming 0": (AprilTagParams(), {}, 0, False),
    "apriltag3 hamming <=1": (AprilTagParams(), {}, 1, False),
    "apriltag3 corner_sigma0.25": (replace(AprilTagParams(), corner_sigma_px=0.25), {}, None,
                                   True),
    "apriltag3 corner_sigma0.35": (replace(AprilTagParams(), corner_sigma_px=0.35), {}, None,
                                   True),
    "apriltag3 corner_sigma0.5": (replace(AprilTagParams(), corner_sigma_px=0.5), {}, None,
                                  True),
    "*apriltag3": (AprilTagParams(), {}, None, False),
    "*apriltag3 + ROI guess": (AprilTagParams(), {}, None, True),
}
# fmt: on


@contextmanager
def _apriltag3_settings(settings: dict, max_hamming: int | None):
    """Temporarily change the module's AprilTag 3 settings (the detector cache is keyed on
    them)."""
    old, old_h = dict(tag_detectors.APRILTAG3_SETTINGS), tag_detectors.APRILTAG3_MAX_HAMMING
    tag_detectors.APRILTAG3_SETTINGS.update(settings)
    if max_hamming is not None:
        tag_detectors.APRILTAG3_MAX_HAMMING = max_hamming
    try:
        yield
    finally:
        tag_detectors.APRILTAG3_SETTINGS.clear()
        tag_detectors.APRILTAG3_SETTINGS.update(old)
        tag_detectors.APRILTAG3_MAX_HAMMING = old_h


def bench_tags(truths: list[Truth], all_settings: bool) -> None:
    """Every setting on every standing frame; the settings take turns frame by frame, so that
    a busy machine slows all of them alike. Times are the process's CPU time (one thread:
    OpenCV and AprilTag 3 are set to one), which other processes inflate far less than the
    wall clock."""
    print("\n== AprilTags on standing frames (35 tags per sheet; CPU ms, one thread) ==")
    print(f"{'setting':24s} {'frames':>6s} {'tags/frame':>10s} {'pose ok':>7s} "
          f"{'pos mm med/p95':>15s} {'att deg med/p95':>16s} {'NEES mean':>9s} "
          f"{'ms med/p95':>11s}")  # fmt: skip
    settings = {n.lstrip("*"): v for n, v in TAG_SETTINGS.items() if all_settings or n[0] == "*"}
    stats = {name: ([], [], [], [], []) for name in settings}
    rng = np.random.default_rng(0)
    for tr in truths:
        calib = tr.session.calibration
        for k in standing_frames(tr):
            fr = tr.session.frame(int(k))
            # a pose guess as the filter's prediction: 2 cm and 1° off
            T_guess = tr.T_WfromC[k].copy()
            T_guess[:3, 3] += rng.normal(0, 0.02, 3)
            T_guess[:3, :3] = T_guess[:3, :3] @ so3_exp(rng.normal(0, np.radians(1.0), 3))
            for name, (params, at3, max_hamming, guess) in settings.items():
                ntag, perr, aerr, nees, ms = stats[name]
                with _apriltag3_settings(at3, max_hamming):
                    t0 = time.process_time()
                    obs = detect_board_pose(fr, calib, params, T_guess if guess else None)
                    ms.append(1e3 * (time.process_time() - t0))
                ntag.append(0 if obs is None else obs.n_tags)
                if obs is not None:
                    dp, da, e = pose_error(obs.T_WfromC, tr.T_WfromC[k])
                    perr.append(dp)
                    aerr.append(da)
                    nees.append(float(e @ np.linalg.solve(obs.cov6, e)))
    for name, row in stats.items():
        _tag_row(name, *row)


def _tag_row(name, ntag, perr, aerr, nees, ms) -> None:
    def mp(x, f):
        return f"{f * np.median(x):6.2f}/{f * np.percentile(x, 95):6.2f}" if x else "     -/     -"

    print(f"{name:24s} {len(ntag):6d} {np.mean(ntag):10.1f} {len(perr):7d} {mp(perr, 1e3):>15s} "
          f"{mp(aerr, 1):>16s} {np.mean(nees) if nees else float('nan'):9.1f} "
          f"{np.median(ms):5.1f}/{np.percentile(ms, 95):5.1f}")  # fmt: skip


# ---------------------------------------------------------------------------- floor


def true_plane(T_WfromC: np.ndarray) -> tuple[np.ndarray, float]:
    """Floor z = 0 in the camera frame: (n_C, h) with n·p + h = 0."""
    return T_WfromC[:3, :3].T @ np.array([0.0, 0.0, 1.0]), float(T_WfromC[2, 3])


def noisy_up(T_WfromC: np.ndarray, rng: np.random.Generator, tilt_deg: float = 5.0) -> np.ndarray:
    n, _ = true_plane(T_WfromC)
    return so3_exp(rng.normal(0, np.radians(tilt_deg) / np.sqrt(2), 3)) @ n


def bench_floor(truths: list[Truth], step: int, params: FloorParams) -> None:
    print("\n== floor plane (RANSAC + gravity prior) ==")
    print(f"{'session':14s} {'frames':>6s} {'fail':>4s} {'angle deg med/p95':>18s} "
          f"{'h mm med/p95':>14s} {'inliers':>7s} {'ms':>5s}")  # fmt: skip
    for tr in truths:
        rng = np.random.default_rng(1)
        K = tr.session.calibration.color.K
        ang, dh, ms, inl, fail = [], [], [], [], 0
        for k in range(0, len(tr.session), step):
            fr = tr.session.frame(k)
            up = noisy_up(tr.T_WfromC[k], rng)
            t0 = time.perf_counter()
            pl = fit_floor_depth(fr.depth_m, K, up, params)
            ms.append(1e3 * (time.perf_counter() - t0))
            if pl is None:
                fail += 1
                continue
            n_t, h_t = true_plane(tr.T_WfromC[k])
            ang.append(np.degrees(np.arccos(np.clip(pl.n_C @ n_t, -1, 1))))
            dh.append(abs(pl.h - h_t))
            inl.append(pl.n_inliers)
        print(f"{tr.name:14s} {len(ms):6d} {fail:4d} "
              f"{np.median(ang):8.3f}/{np.percentile(ang, 95):7.3f} "
              f"{1e3 * np.median(dh):6.1f}/{1e3 * np.percentile(dh, 95):6.1f} {np.mean(inl):7.0f} "
              f"{np.median(ms):5.2f}")  # fmt: skip


# ---------------------------------------------------------------------------- feet


def flat_feet_at(tr: Truth, t: float) -> list[dict]:
    return [e for e in tr.events if e["flat_start_s"] <= t <= e["flat_end_s"]]


def frame_candidates(tr: Truth, k: int, fparams: FloorParams, params: FootParams, rng):
    """World (x, y) of the candidates of frame k with the true pose, and the fit/detect ms."""
    fr = tr.session.frame(k)
    K = tr.session.calibration.color.K
    t0 = time.perf_counter()
    pl = fit_floor_depth(fr.depth_m, K, noisy_up(tr.T_WfromC[k], rng), fparams)
    t1 = time.perf_counter()
    cands = [] if pl is None else detect_foot_candidates(fr.depth_m, K, pl, params)
    t2 = time.perf_counter()
    T = tr.T_WfromC[k]
    xy = [(T[:3, :3] @ c.p_FinC + T[:3, 3])[:2] for c in cands]
    return cands, xy, 1e3 * (t1 - t0), 1e3 * (t2 - t1)


def shoe_length(tr: Truth) -> float:
    import yaml  # noqa: PLC0415

    path = tr.session.root / "groundtruth" / "subject.yaml"
    return float(yaml.safe_load(path.read_text())["shoe_length_m"])


def bench_feet(truths: list[Truth], fparams: FloorParams, variants: dict) -> None:
    """``variants``: name → FootParams, or a function of the Truth returning FootParams."""
    print("\n== foot points vs true flat sole centres (true camera poses) ==")
    print(f"{'variant':22s} {'cands':>6s} {'matched':>7s} {'err mm med/p90':>15s} "
          f"{'along/across bias mm':>20s} {'false':>5s} {'flat seen %':>11s} "
          f"{'ms':>5s}")  # fmt: skip
    for name, variant in variants.items():
        err, along, across, ms, n_c, n_false, flat_frames, flat_seen = [], [], [], [], 0, 0, 0, 0
        for tr in truths:
            params = variant(tr) if callable(variant) else variant
            rng = np.random.default_rng(2)
            for k in range(len(tr.session)):
                cands, xy, _, t_det = frame_candidates(tr, k, fparams, params, rng)
                ms.append(t_det)
                flats = flat_feet_at(tr, tr.t_true_s[k])
                n_c += len(xy)
                seen = set()
                for p in xy:
                    d = [np.linalg.norm(p - e["xy"]) for e in flats]
                    if d and min(d) < 0.10:
                        e = flats[int(np.argmin(d))]
                        seen.add(id(e))
                        err.append(min(d))
                        dv = p - e["xy"]
                        along.append(dv[0])
                        across.append(dv[1])
                    else:
                        n_false += 1
                flat_frames += len(flats)
                flat_seen += len(seen)
        print(f"{name:22s} {n_c:6d} {len(err):7d} "
              f"{1e3 * np.median(err):6.1f}/{1e3 * np.percentile(err, 90):6.1f} "
              f"{1e3 * np.mean(along):9.1f}/{1e3 * np.mean(across):6.1f} {n_false:5d} "
              f"{100 * flat_seen / max(flat_frames, 1):11.1f} {np.median(ms):5.2f}")  # fmt: skip


# ---------------------------------------------------------------------------- stances


def bench_stance(truths: list[Truth], fparams: FloorParams, params: FootParams) -> None:
    from gaitnet.vio.stance_tracker import StanceParams, StanceTracker  # noqa: PLC0415

    sparams = StanceParams()
    print("\n== stance grouping and left/right (true camera poses) ==")
    print(f"{'session':14s} {'true':>4s} {'visible':>7s} {'found':>5s} {'tracked':>7s} "
          f"{'precise':>7s} {'side ok':>7s} {'pos err mm':>10s} {'ms':>5s}")  # fmt: skip
    tot = np.zeros(6)
    for tr in truths:
        rng = np.random.default_rng(3)
        trk = StanceTracker(sparams)
        visible: set[int] = set()
        ms = []
        for k in range(len(tr.session)):
            _, xy, _, _ = frame_candidates(tr, k, fparams, params, rng)
            for i, e in enumerate(tr.events):
                flat = e["flat_start_s"] <= tr.t_true_s[k] <= e["flat_end_s"]
                if flat and any(np.linalg.norm(p - e["xy"]) < 0.06 for p in xy):
                    visible.add(i)
            T = tr.T_WfromC[k]
            t0 = time.perf_counter()
            trk.update(tr.t_true_s[k], xy, heading_W=T[:2, 2], p_CinW=T[:2, 3])
            ms.append(1e3 * (time.perf_counter() - t0))
        stances = trk.finish()
        found, precise, side_ok, pos = set(), 0, 0, []
        for st in stances:
            d = [np.linalg.norm(st.xy - e["xy"]) for e in tr.events]
            i = int(np.argmin(d))
            e = tr.events[i]
            overlap = st.t_first <= e["flat_end_s"] + 0.1 and st.t_last >= e["flat_start_s"] - 0.1
            if d[i] < 0.06 and overlap:
                precise += 1
                pos.append(d[i])
                if i not in found:
                    found.add(i)
                side_ok += st.side == e["side"]
        print(f"{tr.name:14s} {len(tr.events):4d} {len(visible):7d} {len(found):5d} "
              f"{len(stances):7d} {precise:7d} {side_ok:7d} {1e3 * np.median(pos):10.1f} "
              f"{np.median(ms):5.2f}")  # fmt: skip
        tot += [len(tr.events), len(visible), len(found), len(stances), precise, side_ok]
    print(
        f"{'all':14s} {tot[0]:4.0f} {tot[1]:7.0f} {tot[2]:5.0f} {tot[3]:7.0f} {tot[4]:7.0f} "
        f"{tot[5]:7.0f}   recall(visible) {tot[2] / max(tot[1], 1):.3f} "
        f"precision {tot[4] / max(tot[3], 1):.3f} side {tot[5] / max(tot[4], 1):.3f}"
    )


def main(argv: list[str] | None = None) -> int:
    ap = ScriptParser(description=__doc__.splitlines()[0])
    ap.add_argument("sessions", nargs="+")
    ap.add_argument("--parts", nargs="+", default=["tags", "floor", "feet", "stance"])
    ap.add_argument("--step", type=int, default=3, help="floor: every n-th frame")
    ap.add_argument("--all", action="store_true", help="tags: every setting, not only *")
    args = ap.parse_args(argv)
    truths = [load_truth(p) for p in args.sessions]
    fparams = FloorParams()
    if "tags" in args.parts:
        bench_tags(truths, all_settings=args.all)
    if "floor" in args.parts:
        bench_floor(truths, args.step, fparams)
    if "feet" in args.parts:
        base = FootParams()
        bench_feet(truths, fparams, {
            "toe (default)": base,
            "toe, true shoe length": lambda tr: replace(base, shoe_length_m=shoe_length(tr)),
            "centroid": replace(base, point_method="centroid"),
            "ray through ellipse": replace(base, point_method="ray"),
        })  # fmt: skip
    if "stance" in args.parts:
        bench_stance(truths, fparams, FootParams())
    return 0


if __name__ == "__main__":
    from gaitnet.cli.scripts import run_script

    raise SystemExit(run_script(main))
