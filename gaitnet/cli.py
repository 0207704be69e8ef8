"""The ``gaitnet`` command: a thin layer over library functions.

Each subcommand parses its arguments, calls one library function and prints a short report.
Known errors (:class:`gaitnet.errors.GaitnetError`) become one line on stderr and exit code 1.
"""

from __future__ import annotations

import argparse
import logging
import sys
from collections.abc import Callable, Sequence

import numpy as np
from tqdm import tqdm

from gaitnet import __version__
from gaitnet.errors import GaitnetError

log = logging.getLogger("gaitnet")


def _cmd_check(args: argparse.Namespace) -> int:
    from gaitnet.io import open_session

    session = open_session(args.session)
    frames = session.frames()
    if args.decode:
        n_invalid = 0.0
        for frame in tqdm(frames, total=len(session), desc="decoding frames", unit="frame"):
            n_invalid += float(np.mean(frame.depth_m == 0))
    calib = session.calibration
    times = session.frame_times_ns.astype(np.float64) * 1e-9
    imu = session.imu
    duration = times[-1] - times[0] if len(times) > 1 else 0.0
    rate = (len(times) - 1) / duration if duration > 0 else float("nan")
    imu_rate = (len(imu) - 1) / ((imu.t_ns[-1] - imu.t_ns[0]) * 1e-9)
    print(f"session   {args.session}")
    print(f"device    {calib.device}")
    print(
        f"frames    {len(session)} over {duration:.2f} s ({rate:.1f} Hz), "
        f"{calib.color.width}×{calib.color.height}"
    )
    print(f"imu       {len(imu)} samples ({imu_rate:.1f} Hz)")
    print(f"boards    {len(calib.apriltag_boards)} AprilTag board(s)")
    if args.decode:
        print(f"depth     {100 * n_invalid / len(session):.1f} % invalid pixels on average")
        print("ok: every frame decoded")
    else:
        print("ok: headers checked (add --decode to decode every frame)")
    return 0


def _cmd_convert(args: argparse.Namespace) -> int:
    from gaitnet.io import copy_session, open_session

    session = open_session(args.input)
    out = copy_session(
        session,
        args.output,
        overwrite=args.overwrite,
        progress=lambda it, total: tqdm(it, total=total, desc="converting", unit="frame"),
    )
    print(f"wrote {len(session)} frames and {len(session.imu)} IMU samples to {out}")
    return 0


def _cmd_simulate(args: argparse.Namespace) -> int:
    from gaitnet.config import dump_config, load_config
    from gaitnet.sim.config import SimConfig
    from gaitnet.sim.session import simulate_session

    cfg = load_config(SimConfig, args.config, args.overrides)
    result = simulate_session(
        cfg,
        args.seed,
        args.out,
        overwrite=args.overwrite,
        progress=lambda it, total: tqdm(it, total=total, desc="rendering", unit="frame"),
        config_text=dump_config(cfg),
    )
    checks = result.marker_checks
    print(
        f"wrote {result.n_frames} frames ({result.duration_s:.1f} s) and {result.n_imu} IMU "
        f"samples to {result.path}"
    )
    print(f"subject {result.subject.height_m:.2f} m, floor '{result.floor_family}'")
    print(
        f"foot markers visible in {100 * checks['visible_marker_fraction']:.1f} % of "
        f"frame-sides; on a foot label in {100 * checks['visible_marker_on_foot_label']:.2f} % "
        "of those"
    )
    print(f"preview: {result.path / 'preview.png'}")
    return 0


def _cmd_simulate_dataset(args: argparse.Namespace) -> int:
    from gaitnet.config import load_config
    from gaitnet.sim.config import SimConfig
    from gaitnet.sim.dataset import simulate_dataset

    cfg = load_config(SimConfig, args.config, args.overrides)
    result = simulate_dataset(
        cfg,
        args.n,
        args.seed,
        args.out,
        pitch_range_deg=(args.pitch_min, args.pitch_max),
        labelme=args.labelme,
        overwrite=args.overwrite,
        progress=lambda it, total: tqdm(it, total=total, desc="rendering", unit="frame"),
    )
    shares = ", ".join(f"{k} {100 * v:.1f} %" for k, v in result.label_fractions.items())
    print(f"wrote {result.n_frames} labelled frames to {result.path} (pixels: {shares})")
    return 0


def _cmd_evaluate(args: argparse.Namespace) -> int:
    from gaitnet.evaluation.evaluate import evaluate_result, write_report

    report = evaluate_result(args.result_dir, args.session)
    for key, value in sorted(report.metrics.items()):
        print(f"{key:14s} {value:.4f}")
    if args.json:
        write_report(report, args.json)
        print(f"wrote {args.json}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="gaitnet",
        description="Gait measurements and lower-body pose from one waist-worn RGB-D camera "
        "with its IMU (Intel RealSense D455).",
    )
    parser.add_argument("--version", action="version", version=f"gaitnet {__version__}")
    parser.add_argument("-v", "--verbose", action="store_true", help="log debug messages")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    p = sub.add_parser(
        "check",
        help="validate a recorded session (folder or RealSense .bag) and summarise it",
        description="Validate a session: session.yaml, IMU ordering and gaps, every frame's "
        "PNG header (size, type, truncation); with --decode also decode every frame.",
    )
    p.add_argument("session", help="session folder or RealSense .bag file")
    p.add_argument("--decode", action="store_true", help="decode every frame (slower)")
    p.set_defaults(func=_cmd_check)

    p = sub.add_parser(
        "convert",
        help="convert a RealSense .bag (or a session folder) into a session folder",
        description="Read a recording through the session reader and write a session folder "
        "v1 (docs/session-format.md). IMU streams are merged onto common timestamps.",
    )
    p.add_argument("input", help="RealSense .bag file or session folder")
    p.add_argument("output", help="output session folder (must not exist or be empty)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing output folder")
    p.set_defaults(func=_cmd_convert)

    p = sub.add_parser(
        "simulate",
        help="simulate a walking session (RGB-D + IMU) with full ground truth",
        description="Write a session folder plus groundtruth/ (docs/simulator.md). Same seed "
        "and config give byte-identical output.",
    )
    p.add_argument("--config", default=None, help="YAML config (default: built-in defaults)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--out", required=True, help="output session folder")
    p.add_argument("--overwrite", action="store_true", help="replace an existing output folder")
    p.add_argument("overrides", nargs="*", metavar="KEY=VALUE", help="config overrides")
    p.set_defaults(func=_cmd_simulate)

    p = sub.add_parser(
        "simulate-dataset",
        help="render labelled frames (RGB, depth, gravity, labels, labelme JSON) for segmentation",
        description="Each frame has its own random subject, floor, lighting and camera pitch. "
        "Layout: see gaitnet/sim/dataset.py and docs/simulator.md.",
    )
    p.add_argument("--config", default=None, help="YAML simulator config (default: built-in)")
    p.add_argument("--n", type=int, required=True, help="number of frames")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--labelme", action="store_true", help="also write labelme JSON polygons")
    p.add_argument("--pitch-min", type=float, default=55.0, help="camera pitch range [deg]")
    p.add_argument("--pitch-max", type=float, default=75.0, help="camera pitch range [deg]")
    p.add_argument("--overwrite", action="store_true", help="replace an existing output folder")
    p.add_argument("overrides", nargs="*", metavar="KEY=VALUE", help="config overrides")
    p.set_defaults(func=_cmd_simulate_dataset)

    p = sub.add_parser(
        "evaluate",
        help="compare a result folder with a simulated session's ground truth (JSON metrics)",
        description="Reports the DESIGN.md metric keys the inputs allow: mpjpe_m from "
        "RESULT_DIR/joints.npz, body_ate_m from RESULT_DIR/camera_frames.tum.",
    )
    p.add_argument("result_dir", help="folder with results (joints.npz, camera_frames.tum)")
    p.add_argument("--session", required=True, help="simulated session folder (groundtruth/)")
    p.add_argument("--json", default=None, help="write the metrics to this JSON file")
    p.set_defaults(func=_cmd_evaluate)

    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(
        level=logging.DEBUG if args.verbose else logging.INFO,
        format="%(levelname)s %(name)s: %(message)s",
    )
    func: Callable[[argparse.Namespace], int] = args.func
    try:
        return func(args)
    except GaitnetError as exc:
        print(f"gaitnet {args.command}: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("gaitnet: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
