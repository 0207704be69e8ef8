"""Visual-odometry accuracy, consistency and speed on simulated sessions (run by hand).

For each session: moving frame pairs (true camera motion above ``--min-motion-mm``) get
``FrameOdometry.estimate`` with two guesses — the truth perturbed by a realistic IMU-prediction
error (``--guess-mm`` / ``--guess-deg``, random direction) and the identity — and, for
comparison, OpenCV 5's dense ``cv.Odometry`` (RGB_DEPTH, default settings; it takes no
initial guess). Truth: ``groundtruth/camera_frames.tum`` (``T_WfromC``), relative motion
``T_CkfromCk1 = inv(T_WfromCk) @ T_WfromCk-1``.

Printed per floor family: pairs, ok fraction, median / 95th-percentile translation [mm] and
rotation [°] errors, fraction of ok pairs off by > 1 cm or > 1°, median CPU ms per pair (thread
time: the machines are shared, so wall time is not the cost), and the
mean normalised error squared (NEES, 6 dof: 6 expected) with the fraction inside the 95 %
χ²(6) bound (12.59).

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/bench_vo.py /tmp/sessions/vo_*_s2* \
        [--every 2] [--scale 1.0] [--dense] [--set motion_std=0] [--dump pairs.npz]

``--dump`` writes the IMU-guess pairs' session, frame, error vector, covariance, true motion,
residual and inlier count for further analysis (e.g. the share of the error along the motion:
motion blur makes the measured translation a few per cent short on long exposures). The
per-pair NEES judges the covariance of single pairs; the floor ``motion_std`` is meant for
errors that persist over consecutive pairs, so with it the per-pair NEES is well below 6
(the filter's own consistency: ``benchmarks/bench_nees.py``).

Sessions are made with ``gaitnet simulate --seed N --out DIR scene.floor_family=F``.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections import defaultdict
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import cv2 as cv  # noqa: E402
import numpy as np  # noqa: E402
import yaml  # noqa: E402

from gaitnet.geometry.rotation import so3_exp, so3_log  # noqa: E402
from gaitnet.io import open_session  # noqa: E402
from gaitnet.io.trajectory import read_tum  # noqa: E402
from gaitnet.training.scripts import ScriptParser  # noqa: E402
from gaitnet.vio.odometry import FrameOdometry, OdometryParams  # noqa: E402

CHI2_6_95 = 12.592


def floor_family(session: Path) -> str:
    cfg = session / "sim_config.yaml"
    if cfg.is_file():
        data = yaml.safe_load(cfg.read_text())
        fam = (data.get("scene") or {}).get("floor_family")
        if fam and fam != "random":
            return str(fam)
    return f"({session.name})"  # a random floor's family is not recorded in the session


def errors(R: np.ndarray, t: np.ndarray, T_true: np.ndarray) -> tuple[float, float, np.ndarray]:
    """Translation error [mm], rotation error [°], error vector (dφ, dt) in the VoResult chart."""
    dphi = so3_log(T_true[:3, :3] @ R.T)
    dt = T_true[:3, 3] - t
    e = np.concatenate([dphi, dt])
    return 1e3 * float(np.linalg.norm(dt)), float(np.degrees(np.linalg.norm(dphi))), e


def perturbed(T: np.ndarray, mm: float, deg: float, rng: np.random.Generator) -> np.ndarray:
    def unit() -> np.ndarray:
        v = rng.normal(size=3)
        return v / np.linalg.norm(v)

    G = T.copy()
    G[:3, :3] = so3_exp(np.radians(deg) * unit()) @ T[:3, :3]
    G[:3, 3] = T[:3, 3] + 1e-3 * mm * unit()
    return G


def dense_odometry(K: np.ndarray):
    s = cv.OdometrySettings()
    s.setCameraMatrix(K.astype(np.float32))
    odo = cv.Odometry(cv.ODOMETRY_TYPE_RGB_DEPTH, s, cv.OdometryAlgoType_COMMON)

    def run(a, b):
        ok, Rt = odo.compute(
            a.depth_m,
            cv.cvtColor(a.rgb, cv.COLOR_RGB2BGR),
            b.depth_m,
            cv.cvtColor(b.rgb, cv.COLOR_RGB2BGR),
        )
        return ok, Rt[:3, :3], Rt[:3, 3]

    return run


def main(argv: list[str] | None = None) -> None:
    ap = ScriptParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("sessions", nargs="+", type=Path)
    ap.add_argument("--every", type=int, default=1, help="use every N-th moving pair")
    ap.add_argument("--min-motion-mm", type=float, default=10.0)
    ap.add_argument("--guess-mm", type=float, default=5.0)
    ap.add_argument("--guess-deg", type=float, default=0.5)
    ap.add_argument(
        "--scale", type=float, default=None, help="working resolution (default: params)"
    )
    ap.add_argument("--dense", action="store_true", help="also run cv.Odometry (slow)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--set", nargs="*", default=[], metavar="KEY=VALUE", help="OdometryParams")
    ap.add_argument("--no-identity", action="store_true", help="only the IMU-like guess")
    ap.add_argument(
        "--dump",
        type=Path,
        default=None,
        help="write the IMU-guess pairs' errors, covariances and statistics to this .npz",
    )
    args = ap.parse_args(argv)
    cv.setNumThreads(1)
    rng = np.random.default_rng(args.seed)
    overrides = {
        k: type(getattr(OdometryParams(), k))(v) for k, v in (a.split("=") for a in args.set)
    }
    if args.scale is not None:
        overrides["scale"] = args.scale
    params = OdometryParams(**overrides)
    no_gate = OdometryParams(
        **{**params.__dict__, "max_guess_rotation_rad": np.inf, "max_guess_translation_m": np.inf}
    )
    methods = {"imu-guess": FrameOdometry(params), "identity": FrameOdometry(no_gate)}
    if args.no_identity:
        del methods["identity"]
    rows: dict[tuple[str, str], list] = defaultdict(list)
    dump: dict[str, list] = defaultdict(list)
    reasons: dict[tuple[str, str], dict[str, int]] = defaultdict(lambda: defaultdict(int))
    for session in args.sessions:
        fam = floor_family(session)
        src = open_session(session)
        K = src.calibration.color.K
        _, T_WfromC = read_tum(session / "groundtruth" / "camera_frames.tum")
        dense = dense_odometry(K) if args.dense else None
        moving = [
            i
            for i in range(1, len(src))
            if np.linalg.norm((np.linalg.inv(T_WfromC[i]) @ T_WfromC[i - 1])[:3, 3])
            > 1e-3 * args.min_motion_mm
        ][:: args.every]
        print(f"{session.name}: {fam}, {len(moving)} moving pairs", file=sys.stderr)
        cache = {}
        for i in moving:
            prev = cache.get(i - 1) or src.frame(i - 1)
            cur = src.frame(i)
            cache = {i: cur}
            T_true = np.linalg.inv(T_WfromC[i]) @ T_WfromC[i - 1]
            motion_mm = 1e3 * np.linalg.norm(T_true[:3, 3])
            guesses = {
                "imu-guess": perturbed(T_true, args.guess_mm, args.guess_deg, rng),
                "identity": np.eye(4),
            }
            for name, odo in methods.items():
                if name not in guesses:
                    continue
                odo._cache_key = None  # time each pair on its own (no cached previous frame)
                t0 = time.thread_time()
                res = odo.estimate(prev, cur, K, guesses[name])
                ms = 1e3 * (time.thread_time() - t0)
                et, er, e = errors(res.R, res.t, T_true)
                nees = float(e @ np.linalg.solve(res.cov6, e)) if res.ok else np.nan
                rows[(fam, name)].append((res.ok, et, er, ms, nees, motion_mm, res.weak_dirs))
                if args.dump is not None and name == "imu-guess" and res.ok:
                    dump["session"].append(session.name)
                    dump["pair"].append(i)
                    dump["error"].append(e)
                    dump["cov6"].append(res.cov6)
                    dump["T_true"].append(T_true)
                    dump["residual_px"].append(res.residual)
                    dump["n_inliers"].append(res.n_inliers)
                    dump["weak_dirs"].append(res.weak_dirs)
                reasons[(fam, name)][res.reason.split(" (")[0].split(":")[0] or "ok"] += 1
            if dense is not None:
                t0 = time.thread_time()
                ok, R, t = dense(prev, cur)
                ms = 1e3 * (time.thread_time() - t0)
                et, er, _ = errors(R, t, T_true)
                rows[(fam, "cv.Odometry")].append((ok, et, er, ms, np.nan, motion_mm, 0))

    head = (
        f"{'floor':<12}{'method':<12}{'pairs':>6}{'ok%':>6}{'t med':>7}{'t p95':>7}"
        f"{'r med':>7}{'r p95':>7}{'>1cm|1°':>9}{'ms':>6}{'NEES':>7}{'in95%':>7}{'weak%':>7}"
    )
    print(head)
    print("-" * len(head))
    for (fam, name), rs in sorted(rows.items()):
        a = np.array(rs, dtype=float)
        ok = a[:, 0] > 0
        g = a[ok]
        if len(g):
            bad = np.mean((g[:, 1] > 10) | (g[:, 2] > 1))
            nees = g[:, 4]
            nees_ok = nees[np.isfinite(nees)]
            print(
                f"{fam:<12}{name:<12}{len(a):>6}{100 * ok.mean():>6.0f}"
                f"{np.median(g[:, 1]):>7.2f}{np.percentile(g[:, 1], 95):>7.2f}"
                f"{np.median(g[:, 2]):>7.3f}{np.percentile(g[:, 2], 95):>7.3f}"
                f"{100 * bad:>8.1f}%{np.median(a[:, 3]):>6.1f}"
                f"{np.mean(nees_ok) if len(nees_ok) else np.nan:>7.2f}"
                f"{100 * np.mean(nees_ok < CHI2_6_95) if len(nees_ok) else np.nan:>7.1f}"
                f"{100 * np.mean(g[:, 6] > 0):>7.1f}"
            )
        else:
            print(
                f"{fam:<12}{name:<12}{len(a):>6}{0:>6.0f}  (no ok pair)  "
                f"{np.median(a[:, 3]):.1f} ms"
            )
    if args.dump is not None:
        np.savez(args.dump, **{k: np.array(v) for k, v in dump.items()})
    print("\nfailure reasons:")
    for (fam, name), r in sorted(reasons.items()):
        print(f"  {fam:<12}{name:<12}", dict(r))
    all_motion = np.concatenate([np.array(r, float)[:, 5] for r in rows.values()])
    print(
        f"\ntrue motion per moving pair: median {np.median(all_motion):.1f} mm, "
        f"95th percentile {np.percentile(all_motion, 95):.1f} mm"
    )


if __name__ == "__main__":
    from gaitnet.cli.scripts import run_script

    raise SystemExit(run_script(main))
