"""The ``gaitnet`` command: a thin layer over library functions.

Each subcommand parses its arguments, calls one library function and prints a short report.

Exit codes (docs/cli.md):

* 0: success;
* 1: the input is wrong: a bad option or argument (argparse's own errors included), a
  :class:`gaitnet.errors.GaitnetError` from the library, or an ``OSError`` on a path the user
  named (not found, permission denied, a folder where a file was expected, disk full). Exactly
  one line on stderr: ``gaitnet COMMAND: error: ...``;
* 2: a bug in gaitnet (any other exception): the traceback, then one line asking for a report;
* 130 / 143: interrupted by Ctrl-C (SIGINT) / SIGTERM. Both raise ``KeyboardInterrupt`` inside
  the command, so staging folders and temporary files are removed on the way out.
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import math
import signal
import sys
import traceback
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from types import FrameType
from typing import NoReturn

import numpy as np
from tqdm import tqdm

from gaitnet import __version__
from gaitnet.errors import USER_ERRORS, GaitnetError, one_line, user_error_message

log = logging.getLogger("gaitnet")

PROG = "gaitnet"
EXIT_USER_ERROR = 1
EXIT_BUG = 2
EXIT_SIGINT = 130  # 128 + SIGINT, the shell's convention
EXIT_SIGTERM = 143  # 128 + SIGTERM


class UsageError(GaitnetError):
    """A bad command line; ``prog`` is the (sub)command whose parser found it."""

    def __init__(self, prog: str, message: str) -> None:
        super().__init__(message)
        self.prog = prog


class Parser(argparse.ArgumentParser):
    """An ArgumentParser whose errors raise :class:`UsageError` instead of exiting with 2.

    ``add_subparsers`` builds its subparsers with the parent's class, so subcommands inherit
    this behaviour.
    """

    def error(self, message: str) -> NoReturn:
        raise UsageError(self.prog, f"{message} (see '{self.prog} --help')")


# --- option value types: every value is validated where it enters --------------------------


def _integer(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None


def _finite_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return value


def _output_folder(text: str) -> Path:
    if not text:
        raise argparse.ArgumentTypeError("empty path")
    path = Path(text)
    if path.exists() and not path.is_dir():
        raise argparse.ArgumentTypeError(f"{text}: exists and is not a folder")
    return path


def _output_file(text: str) -> Path:
    if not text:
        raise argparse.ArgumentTypeError("empty path")
    path = Path(text)
    if path.is_dir():
        raise argparse.ArgumentTypeError(f"{text}: is a folder (give a file name)")
    if not path.parent.is_dir():
        raise argparse.ArgumentTypeError(f"{text}: folder {path.parent} does not exist")
    return path


# --- commands -----------------------------------------------------------------------------


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
    imu_span = (imu.t_ns[-1] - imu.t_ns[0]) * 1e-9 if len(imu) > 1 else 0.0
    imu_rate = (len(imu) - 1) / imu_span if imu_span > 0 else float("nan")
    print(f"session   {args.session}")
    print(f"device    {calib.device}")
    print(
        f"frames    {len(session)} over {duration:.2f} s ({rate:.1f} Hz), "
        f"{calib.color.width}×{calib.color.height}"
    )
    print(f"imu       {len(imu)} samples ({imu_rate:.1f} Hz)")
    print(f"boards    {len(calib.apriltag_boards)} AprilTag board(s)")
    if args.decode:
        print(f"depth     {100 * n_invalid / max(len(session), 1):.1f} % invalid pixels on average")
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

    if (args.pitch_min is None) != (args.pitch_max is None):
        raise UsageError(
            f"{PROG} simulate-dataset", "give --pitch-min and --pitch-max together (or neither)"
        )
    pitch_range = None if args.pitch_min is None else (args.pitch_min, args.pitch_max)
    cfg = load_config(SimConfig, args.config, args.overrides)
    result = simulate_dataset(
        cfg,
        args.n,
        args.seed,
        args.out,
        pitch_range_deg=pitch_range,
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
        if isinstance(value, dict):
            parts = ", ".join(
                f"{k} {v:.4f}" if isinstance(v, float) else f"{k} {v}" for k, v in value.items()
            )
            print(f"{key:16s} {parts}")
        else:
            print(f"{key:16s} {value:.4f}")
    if args.json:
        write_report(report, args.json)
        print(f"wrote {args.json}")
    return 0


def _cmd_vio(args: argparse.Namespace) -> int:
    from gaitnet.config import dump_config, load_config
    from gaitnet.io import open_session
    from gaitnet.io.atomic import check_output_folder
    from gaitnet.vio.config import VioConfig
    from gaitnet.vio.report import summary, write_result
    from gaitnet.vio.run import run_vio

    cfg = load_config(VioConfig, args.config, args.overrides)
    check_output_folder(args.out, args.overwrite)
    session = open_session(args.session)
    result = run_vio(
        session,
        cfg,
        progress=lambda it, total: tqdm(it, total=total, desc="filter", unit="frame"),
    )
    out = write_result(result, args.out, dump_config(cfg), overwrite=args.overwrite)
    info = summary(result)
    gait = info["gait"]
    print(f"initialisation: {result.initialisation_note}")
    if result.smoother.get("ran"):
        print(f"smoother: {result.smoother['iterations']} Gauss–Newton iterations (sec. 3.5)")
    elif result.smoother:
        print(f"smoother failed ({result.smoother['reason']}): the filter's estimates follow")
    else:
        print("smoother off: the filter's estimates follow")
    print(
        f"{info['frames']} frames, {info['duration_s']:.1f} s, "
        f"camera path {info['distance_m']:.2f} m; "
        f"{len(result.stance_feet)} stance feet, {len(result.strides)} strides"
    )
    for side in ("left", "right"):
        length = gait[side]["stride_length_m"]
        if length:
            print(
                f"{side:5s} stride length {length['mean']:.3f} ± {length['std']:.3f} m over "
                f"{gait[side]['n_strides']} steady strides"
            )
        else:
            print(f"{side:5s} no steady stride")
    if info["walking_speed_mps"] is not None:
        print(f"walking speed {info['walking_speed_mps']:.2f} m/s")
    print(f"wrote {out} (summary.json, strides.csv, trajectory.png)")
    return 0


def _add_simulator_options(p: argparse.ArgumentParser, out_help: str) -> None:
    """Options shared by the simulator commands: config, overrides, seed, output folder."""
    p.add_argument(
        "--config", metavar="FILE", default=None, help="YAML simulator config (default: built-in)"
    )
    p.add_argument(
        "--seed",
        metavar="N",
        type=_integer,
        default=0,
        help="random seed, 0 ≤ N < 2**32 (default 0)",
    )
    p.add_argument("--out", metavar="DIR", type=_output_folder, required=True, help=out_help)
    p.add_argument("--overwrite", action="store_true", help="replace an existing output folder")
    p.add_argument("overrides", nargs="*", metavar="KEY=VALUE", help="config overrides")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of every command (``gaitnet --help``)."""
    parser = Parser(
        prog=PROG,
        description="Gait measurements and lower-body pose from one waist-worn RGB-D camera "
        "with its IMU (Intel RealSense D455).",
        epilog="Exit status: 0 success, 1 bad input (one line on stderr), 2 a bug in gaitnet "
        "(traceback), 130/143 interrupted. See docs/cli.md.",
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
    p.add_argument("session", metavar="SESSION", help="session folder or RealSense .bag file")
    p.add_argument("--decode", action="store_true", help="decode every frame (slower)")
    p.set_defaults(func=_cmd_check)

    p = sub.add_parser(
        "convert",
        help="convert a RealSense .bag (or a session folder) into a session folder",
        description="Read a recording through the session reader and write a session folder "
        "v1 (docs/session-format.md). IMU streams are merged onto common timestamps.",
    )
    p.add_argument("input", metavar="INPUT", help="RealSense .bag file or session folder")
    p.add_argument(
        "output",
        metavar="OUTPUT",
        type=_output_folder,
        help="output session folder (must not exist or be empty)",
    )
    p.add_argument("--overwrite", action="store_true", help="replace an existing output folder")
    p.set_defaults(func=_cmd_convert)

    p = sub.add_parser(
        "simulate",
        help="simulate a walking session (RGB-D + IMU) with full ground truth",
        description="Write a session folder plus groundtruth/ (docs/simulator.md). Same seed "
        "and config give byte-identical output.",
    )
    _add_simulator_options(p, out_help="output session folder")
    p.set_defaults(func=_cmd_simulate)

    p = sub.add_parser(
        "simulate-dataset",
        help="render labelled frames (RGB, depth, gravity, labels, labelme JSON) for segmentation",
        description="Each frame has its own random subject, floor and lighting; the camera "
        "pitch is the config's mount.pitch_deg (a number or a range) or --pitch-min/--pitch-max. "
        "Layout: see gaitnet/sim/dataset.py and docs/simulator.md.",
    )
    _add_simulator_options(p, out_help="output folder")
    p.add_argument(
        "--n", metavar="N", type=_integer, required=True, help="number of frames, 1–1000000"
    )
    p.add_argument("--labelme", action="store_true", help="also write labelme JSON polygons")
    p.add_argument(
        "--pitch-min",
        metavar="DEG",
        type=_finite_float,
        default=None,
        help="draw each frame's camera pitch from [--pitch-min, --pitch-max], within 10–89° "
        "(default: the config's mount.pitch_deg, a number or a [lo, hi] range)",
    )
    p.add_argument(
        "--pitch-max", metavar="DEG", type=_finite_float, default=None, help="see --pitch-min"
    )
    p.set_defaults(func=_cmd_simulate_dataset)

    p = sub.add_parser(
        "evaluate",
        help="compare a result folder with a simulated session's ground truth (JSON metrics)",
        description="Reports the evaluation-contract metric keys the inputs allow: mpjpe_m from "
        "RESULT_DIR/joints.npz, body_ate_m from RESULT_DIR/camera_frames.tum, stride_rmse_m, "
        "stride_max_err_m and n_strides from RESULT_DIR/strides.csv.",
    )
    p.add_argument(
        "result_dir",
        metavar="RESULT_DIR",
        help="folder with results (joints.npz, camera_frames.tum, strides.csv)",
    )
    p.add_argument(
        "--session",
        metavar="SESSION",
        required=True,
        help="simulated session folder (groundtruth/)",
    )
    p.add_argument(
        "--json",
        metavar="OUT.json",
        type=_output_file,
        default=None,
        help="write the metrics to this JSON file",
    )
    p.set_defaults(func=_cmd_evaluate)

    p = sub.add_parser(
        "vio",
        help="visual-inertial filter and smoother: trajectory, stance feet and strides",
        description="Track the camera with the IMU, RGB-D odometry, AprilTag sheets and "
        "stance feet (thesis ch. 3), smooth the whole session, and write the trajectory, stance "
        "feet, strides, a summary and a top-view plot (docs/vio.md).",
    )
    p.add_argument("session", metavar="SESSION", help="session folder or RealSense .bag file")
    p.add_argument("--out", metavar="DIR", type=_output_folder, required=True, help="output folder")
    p.add_argument(
        "--config", metavar="FILE", default=None, help="YAML filter config (default: built-in)"
    )
    p.add_argument("--overwrite", action="store_true", help="replace an existing output folder")
    p.add_argument("overrides", nargs="*", metavar="KEY=VALUE", help="config overrides")
    p.set_defaults(func=_cmd_vio)

    return parser


class _Terminated(KeyboardInterrupt):
    """SIGTERM, delivered as a KeyboardInterrupt so every cleanup path runs."""


@contextlib.contextmanager
def _sigterm_as_interrupt() -> Iterator[None]:
    def handler(signum: int, frame: FrameType | None) -> None:
        raise _Terminated()

    try:
        previous = signal.signal(signal.SIGTERM, handler)
    except ValueError:  # not the main thread (e.g. embedded): leave signals alone
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``gaitnet`` with ``argv`` (default: ``sys.argv[1:]``); returns the exit status."""
    name = PROG
    with _sigterm_as_interrupt():
        try:
            try:
                args, unknown = build_parser().parse_known_args(argv)
            except SystemExit as exc:  # --help / --version
                return exc.code if isinstance(exc.code, int) else 0
            name = f"{PROG} {args.command}"
            if unknown and hasattr(args, "overrides"):
                # KEY=VALUE after an option (``SESSION --out DIR a=1``) is not a positional
                # to argparse once the positionals are filled: it is still an override
                late = [u for u in unknown if "=" in u and not u.startswith("-")]
                args.overrides = [*(args.overrides or []), *late]
                unknown = [u for u in unknown if u not in late]
            if unknown:
                raise UsageError(
                    name, f"unrecognized arguments: {' '.join(unknown)} (see '{name} --help')"
                )
            logging.basicConfig(
                level=logging.DEBUG if args.verbose else logging.INFO,
                format="%(levelname)s %(name)s: %(message)s",
            )
            func: Callable[[argparse.Namespace], int] = args.func
            return func(args)
        except UsageError as exc:
            print(f"{exc.prog}: error: {one_line(exc)}", file=sys.stderr)
            return EXIT_USER_ERROR
        except USER_ERRORS as exc:
            print(f"{name}: error: {user_error_message(exc)}", file=sys.stderr)
            return EXIT_USER_ERROR
        except _Terminated:
            print(f"{name}: terminated", file=sys.stderr)
            return EXIT_SIGTERM
        except KeyboardInterrupt:
            print(f"{name}: interrupted", file=sys.stderr)
            return EXIT_SIGINT
        except Exception:
            traceback.print_exc()
            print(
                f"{name}: internal error: this is a bug in gaitnet {__version__}; please report "
                "it with the command line and the traceback above",
                file=sys.stderr,
            )
            return EXIT_BUG


if __name__ == "__main__":
    sys.exit(main())
