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

OpenBLAS (numpy's) runs on one thread unless ``OPENBLAS_NUM_THREADS`` is set: the filter's
matrices are small, and OpenBLAS's second thread spins between them on the core the
segmenter needs (``gaitnet vio`` on the default session: 16.5 s of CPU without, 10.4 s with;
``gaitnet infer``: 17.4 → 27.4 frames/s; docs/pipeline.md). It is set here, before numpy loads.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import contextlib
import logging
import signal
import sys
import traceback
from collections.abc import Callable, Iterator, Sequence
from types import FrameType

from gaitnet import __version__
from gaitnet.cli.arguments import (
    EXIT_BUG,
    EXIT_SIGINT,
    EXIT_SIGTERM,
    EXIT_USER_ERROR,
    PROG,
    Parser,
    UsageError,
    _finite_float,
    _integer,
    _output_file,
    _output_folder,
)
from gaitnet.cli.commands import (
    _cmd_batch,
    _cmd_check,
    _cmd_convert,
    _cmd_evaluate,
    _cmd_infer,
    _cmd_segment,
    _cmd_simulate,
    _cmd_simulate_dataset,
    _cmd_tags,
    _cmd_vio,
)
from gaitnet.errors import USER_ERRORS, one_line, user_error_message
from gaitnet.segmentation.edge_refine import EdgeRefineParams

log = logging.getLogger("gaitnet")


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


FORCE_HELP = (
    "run a session that fails the scene check (docs/vio.md, Scene check) and mark the result "
    "unreliable (the override scene.refuse=false)"
)


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
    parser.add_argument(
        "-v",
        "--verbose",
        action="count",
        default=0,
        help="log what each stage does (-vv: debug messages too); without it stderr shows "
        "progress bars, warnings and errors only",
    )
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
        "tags",
        help="write a printable sheet of AprilTags (tag36h11) and its session.yaml entry",
        description="Write a sheet of tag36h11 AprilTags to print at 100 %% (PNG with its dpi, "
        "or PDF of the paper's size) and print the apriltag_boards entry for session.yaml "
        "(docs/recording.md).",
    )
    p.add_argument(
        "--out", required=True, type=_output_file, metavar="SHEET", help="sheet.png or sheet.pdf"
    )
    p.add_argument("--rows", type=_integer, default=7, metavar="R", help="tag rows (default 7)")
    p.add_argument("--cols", type=_integer, default=5, metavar="C", help="tag columns (5)")
    p.add_argument(
        "--tag-size-mm",
        type=_finite_float,
        default=40.0,
        metavar="S",
        help="black square side [mm] (default 40)",
    )
    p.add_argument(
        "--gap-mm", type=_finite_float, default=12.0, metavar="G", help="gap between tags (12)"
    )
    p.add_argument("--first-id", type=_integer, default=0, metavar="I", help="first tag's id (0)")
    p.add_argument("--name", default="start", metavar="N", help="board name in session.yaml")
    p.add_argument(
        "--paper",
        choices=("a4", "a3", "letter"),
        default="a3",
        metavar="P",
        help="paper size: a3 (default), a4 or letter",
    )
    p.add_argument("--dpi", type=_integer, default=300, metavar="D", help="resolution (300)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing file")
    p.set_defaults(func=_cmd_tags)

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
    p.add_argument(
        "--board",
        metavar="FILE",
        help="YAML file with an apriltag_boards list (as gaitnet tags prints it) to add to the "
        "session's sheets",
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
    p.add_argument(
        "--motion",
        metavar="CLIP.npz",
        default=None,
        help="play this AMASS-format motion clip (SMPL+H G *_poses.npz or SMPL-X *_stageii.npz) "
        "as the subject's motion instead of generating a walk (sets motion.clip; "
        "docs/simulator.md, Motion sources)",
    )
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
    p.add_argument("--force", action="store_true", help=FORCE_HELP)
    p.add_argument("overrides", nargs="*", metavar="KEY=VALUE", help="config overrides")
    p.set_defaults(func=_cmd_vio)

    p = sub.add_parser(
        "segment",
        help="segment feet and legs in every frame of a session (label maps, foot keypoints)",
        description="Run the RGB+HHA segmenter (thesis sec. 4.1) with onnxruntime on every frame "
        "of a session folder or .bag: label maps, foot keypoints (eq. 4.1) with their 3-D "
        "points, a contact sheet and a summary (docs/segmenter.md).",
    )
    p.add_argument("session", metavar="SESSION", help="session folder or RealSense .bag file")
    p.add_argument("--out", metavar="DIR", type=_output_folder, required=True, help="output folder")
    p.add_argument(
        "--model",
        metavar="X.onnx",
        default=None,
        help="segmenter exported by export/to_onnx.py (default: the committed small fusion model)",
    )
    p.add_argument(
        "--threads",
        metavar="N",
        type=_integer,
        default=2,
        help="onnxruntime threads (0: its default; default 2)",
    )
    p.add_argument(
        "--raw-labels",
        action="store_true",
        help="write the label maps before the foot post-processing's depth checks (edge "
        "refinement still applied: add --refine-radius 0 for the network's own arg-max)",
    )
    p.add_argument(
        "--flip-average",
        action="store_true",
        help="average the network's logits over each frame and its mirror image (more "
        "accurate, twice the network's time; docs/segmenter.md)",
    )
    refine = EdgeRefineParams()
    p.add_argument(
        "--refine-radius",
        metavar="PX",
        type=_integer,
        default=refine.radius_px,
        help="move the label boundaries to the frame's colour edges with a guided filter of "
        f"this window radius (0: off; default {refine.radius_px}; docs/segmenter.md)",
    )
    p.add_argument(
        "--refine-eps",
        metavar="EPS",
        type=float,
        default=refine.eps,
        help=f"the guided filter's regularisation, colour in [0, 1] (default {refine.eps:g})",
    )
    p.add_argument(
        "--refine-region",
        metavar="REGION",
        choices=("feet", "frame"),
        default=refine.region,
        help="feet: refine the foot labels around each foot (fast); frame: every label of the "
        f"frame (default {refine.region})",
    )
    p.add_argument(
        "--label-frames",
        metavar="N",
        type=_integer,
        default=None,
        help="instead: write N frames spread over the session as a labelme folder, pre-labelled "
        "by the segmenter, to correct and fine-tune on (1–10000; docs/recording.md)",
    )
    p.add_argument("--overwrite", action="store_true", help="replace an existing output folder")
    p.set_defaults(func=_cmd_segment)

    p = sub.add_parser(
        "infer",
        help="the whole pipeline: trajectory, feet, lower-body pose, gait parameters",
        description="Run the filter and smoother, the segmenter, the motion predictor and the "
        "pose correction on a session folder or .bag and write joints, gap-free foot "
        "trajectories, strides and a summary (docs/pipeline.md).",
    )
    p.add_argument("session", metavar="SESSION", help="session folder or RealSense .bag file")
    p.add_argument("--out", metavar="DIR", type=_output_folder, required=True, help="output folder")
    p.add_argument(
        "--segmenter",
        metavar="X.onnx",
        default=None,
        help="segmenter ONNX (default: models.segmenter, else the committed small fusion model)",
    )
    p.add_argument(
        "--predictor",
        metavar="Y.onnx",
        default=None,
        help="motion predictor ONNX (default: models.predictor, else the committed small model)",
    )
    p.add_argument(
        "--config", metavar="FILE", default=None, help="YAML inference config (default: built-in)"
    )
    p.add_argument(
        "--save-labels", action="store_true", help="also write every frame's label map (labels/)"
    )
    p.add_argument("--overwrite", action="store_true", help="replace an existing output folder")
    p.add_argument("--force", action="store_true", help=FORCE_HELP)
    p.add_argument("overrides", nargs="*", metavar="KEY=VALUE", help="config overrides")
    p.set_defaults(func=_cmd_infer)

    _add_batch(sub)
    return parser


def _add_batch(sub: argparse._SubParsersAction) -> None:
    """``gaitnet batch``: many sessions, locally or on a Ray cluster, and a cohort table."""
    p = sub.add_parser(
        "batch",
        help="run the whole pipeline on many sessions (local processes or a Ray cluster) and "
        "gather a cohort table",
        description="Run gaitnet infer on every session found (session folders, .bag files, "
        "folders searched recursively), each into OUT/<name>/, skipping sessions whose result "
        "is complete; a failed session is listed in OUT/failures.csv and the others go on. "
        "Writes OUT/cohort.csv and OUT/cohort.html (docs/batch.md).",
    )
    p.add_argument(
        "sessions",
        nargs="+",
        metavar="SESSIONS",
        help="session folders, .bag files, or folders searched recursively for them",
    )
    p.add_argument("--out", metavar="DIR", type=_output_folder, required=True, help="output folder")
    p.add_argument(
        "--workers",
        metavar="N",
        type=_integer,
        default=None,
        help="sessions run at once (default: half the CPUs, of the cluster with --ray); each "
        "gets CPUs // N threads",
    )
    p.add_argument(
        "--ray",
        metavar="ADDRESS",
        default=None,
        help="run the sessions as tasks on the Ray cluster at ADDRESS (HOST:PORT, "
        "ray://HOST:PORT or auto), or on a Ray instance started here with 'local' (needs the "
        "cluster extra)",
    )
    p.add_argument(
        "--config", metavar="FILE", default=None, help="YAML inference config (default: built-in)"
    )
    p.add_argument("overrides", nargs="*", metavar="KEY=VALUE", help="config overrides")
    p.set_defaults(func=_cmd_batch)


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


def _end_progress_bars() -> None:
    """Close the progress bars still on screen (a command stopped by a signal leaves its
    bar's line open), so that the signal's one-line message starts its own line. A bar the
    signal stopped while it was being built has no position yet: it is only forgotten."""
    from tqdm import tqdm

    instances = getattr(tqdm, "_instances", set())
    for bar in list(instances):
        if hasattr(bar, "pos"):
            bar.close()
        else:
            instances.discard(bar)


def _clear_unhandled_interrupt_flag() -> None:
    """Forget, at the interpreter's level, a KeyboardInterrupt that :func:`main` handled.

    CPython remembers a KeyboardInterrupt that ended a nested evaluation of code and, when
    ``python -m gaitnet.cli`` or the ``gaitnet`` script exits, kills the process with SIGINT
    instead of returning its exit status. Under load (about one Ctrl-C in 30 at the start
    of ``gaitnet simulate``) a handled interrupt left that mark behind and the status came
    out as death by SIGINT rather than 130. Running an empty statement through the same
    entry point resets the mark."""
    import ctypes

    ctypes.pythonapi.PyRun_SimpleString(b"")


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
                level=(logging.WARNING, logging.INFO, logging.DEBUG)[min(args.verbose, 2)],
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
            _end_progress_bars()
            print(f"{name}: terminated", file=sys.stderr)
            _clear_unhandled_interrupt_flag()
            return EXIT_SIGTERM
        except KeyboardInterrupt:
            _end_progress_bars()
            print(f"{name}: interrupted", file=sys.stderr)
            _clear_unhandled_interrupt_flag()
            return EXIT_SIGINT
        except Exception:
            traceback.print_exc()
            print(
                f"{name}: internal error: this is a bug in gaitnet {__version__}; please report "
                "it with the command line and the traceback above",
                file=sys.stderr,
            )
            return EXIT_BUG
