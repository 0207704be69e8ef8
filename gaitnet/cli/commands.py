"""The ``gaitnet`` subcommands: each parses nothing, calls one library function and prints a short
report (the parser is in :mod:`gaitnet.cli`)."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

import numpy as np
from tqdm import tqdm

from gaitnet.cli.arguments import PROG, UsageError

if TYPE_CHECKING:  # the commands import their stages lazily, to start fast
    from gaitnet.vio.result import VioResult


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
    from dataclasses import replace

    from gaitnet.errors import SessionError
    from gaitnet.io import copy_session, open_session
    from gaitnet.io.session_yaml import read_board_file

    session = open_session(args.input)
    calib = session.calibration
    boards = () if args.board is None else read_board_file(args.board)
    if boards:
        try:
            calib = replace(calib, apriltag_boards=(*calib.apriltag_boards, *boards))
        except ValueError as exc:  # e.g. a name or tag id the session's boards have already
            raise SessionError(f"{args.board}: {exc}") from None
    out = copy_session(
        session,
        args.output,
        overwrite=args.overwrite,
        progress=lambda it, total: tqdm(it, total=total, desc="converting", unit="frame"),
        calibration=calib,
    )
    added = f", {len(boards)} AprilTag board(s) from {args.board}" if boards else ""
    print(f"wrote {len(session)} frames and {len(session.imu)} IMU samples{added} to {out}")
    return 0


def _cmd_simulate(args: argparse.Namespace) -> int:
    from gaitnet.sim.worker_pool import start_workers

    start_workers()  # the workers' forkserver imports the simulator while this process does
    from gaitnet.config import dump_config, load_config
    from gaitnet.sim.config import SimConfig
    from gaitnet.sim.session import simulate_session

    overrides = list(args.overrides)
    if args.motion is not None:
        overrides.append(f"motion.clip={_clip_path(args.motion)}")
    cfg = load_config(SimConfig, args.config, overrides)
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


def _clip_path(text: str) -> str:
    """``--motion``'s file as an absolute path quoted for a YAML override (so the session's
    ``sim_config.yaml`` reproduces it from any folder)."""
    import json
    from pathlib import Path

    path = Path(text)
    if not path.is_file():
        raise UsageError(f"{PROG} simulate", f"--motion {text!r}: no such file")
    return json.dumps(str(path.resolve()))


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
        if key == "n_strides":  # never a stride RMSE without how many strides it covers
            print(f"{key:16s} {_strides_matched(value, report.counts)}")
        elif isinstance(value, dict):
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


def _strides_matched(matched: dict[str, int], counts: dict[str, int]) -> str:
    """``left 2 of 3, right 3 of 3 true strides matched; found but unmatched: left 0, right
    1`` from the evaluation's ``n_strides`` and its unmatched-stride counts."""
    true = ", ".join(
        f"{s} {n} of {n + counts.get(f'strides_unmatched_groundtruth_{s}', 0)}"
        for s, n in matched.items()
    )
    found = ", ".join(f"{s} {counts.get(f'strides_unmatched_estimate_{s}', 0)}" for s in matched)
    return f"{true} true strides matched; found but unmatched: {found}"


def _print_trust(unreliable: list[str], vio: VioResult) -> None:
    """What ``gaitnet vio`` and ``gaitnet infer`` print before their figures: why the result is
    unreliable (``UNRELIABLE: …``) and a warning when its lengths rest on depth alone."""
    from gaitnet.vio.report import SCALE_FROM_SHEETS, scale_source

    if unreliable:
        print(f"UNRELIABLE: {'; '.join(unreliable)}")
    if scale_source(vio) != SCALE_FROM_SHEETS:
        print(f"warning: scale from {scale_source(vio)}")


def _cmd_vio(args: argparse.Namespace) -> int:
    from gaitnet.config import dump_config, load_config
    from gaitnet.io import open_session
    from gaitnet.io.atomic import check_output_folder
    from gaitnet.vio.config import VioConfig
    from gaitnet.vio.report import summary, write_result
    from gaitnet.vio.run import run_vio

    forced = ["scene.refuse=false"] if args.force else []
    cfg = load_config(VioConfig, args.config, [*args.overrides, *forced])
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
    _print_trust(result.unreliable, result)
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


def _cmd_segment(args: argparse.Namespace) -> int:
    from gaitnet.io import open_session
    from gaitnet.io.atomic import check_output_folder
    from gaitnet.segmentation.edge_refine import EdgeRefineParams
    from gaitnet.segmentation.onnx_runtime import OnnxSegmenter
    from gaitnet.segmentation.segment_session import (
        SegmentOptions,
        default_segmenter_path,
        segment_session,
    )

    try:
        edge_refine = EdgeRefineParams(args.refine_radius, args.refine_eps, args.refine_region)
    except ValueError as exc:
        raise UsageError(f"{PROG} segment", f"--refine-radius / --refine-eps: {exc}") from None
    if args.label_frames is not None and not 1 <= args.label_frames <= 10_000:
        raise UsageError(
            f"{PROG} segment", f"--label-frames must be within 1–10000, got {args.label_frames}"
        )
    check_output_folder(args.out, args.overwrite)
    session = open_session(args.session)
    model = OnnxSegmenter(
        args.model or default_segmenter_path(),
        threads=args.threads,
        flip_average=args.flip_average,
        edge_refine=edge_refine,
    )
    if args.label_frames is not None:
        return _write_frames_to_label(args, session, model)
    result = segment_session(
        session,
        model,
        args.out,
        overwrite=args.overwrite,
        options=SegmentOptions(raw_labels=args.raw_labels),
        progress=lambda it, total: tqdm(it, total=total, desc="segmenting", unit="frame"),
    )
    shares = ", ".join(f"{k} {100 * v:.1f} %" for k, v in result.label_fractions.items())
    ms = 1e3 * sum(result.timings_s.values()) / max(result.n_frames, 1)
    print(f"model {model.path} ({model.arch})")
    print(
        f"{result.n_frames} frames, a foot in {result.frames_with_foot}; pixels: {shares}; "
        f"{ms:.1f} ms per frame"
    )
    print(f"wrote {result.path} (labels/, keypoints.csv, contact_sheet.png, summary.json)")
    return 0


def _write_frames_to_label(args: argparse.Namespace, session, model) -> int:
    from gaitnet.segmentation.label_frames import write_frames_to_label

    result = write_frames_to_label(
        session,
        model,
        args.out,
        args.label_frames,
        overwrite=args.overwrite,
        progress=lambda it, total: tqdm(it, total=total, desc="pre-labelling", unit="frame"),
    )
    print(f"model {model.path} ({model.arch})")
    print(
        f"wrote {len(result.frame_ids)} frames with {result.shapes} pre-labelled shapes to "
        f"{result.path} (images/*.png and *.json, depth/, camera.yaml, frames.csv, labels.txt): "
        f"correct them in labelme (labelme {result.path}/images), then fine-tune "
        "(docs/recording.md)"
    )
    return 0


def _cmd_infer(args: argparse.Namespace) -> int:
    from gaitnet import __version__
    from gaitnet.config import load_config
    from gaitnet.io import open_session
    from gaitnet.io.atomic import check_output_folder
    from gaitnet.pipeline.config import InferConfig

    forced = ["vio.scene.refuse=false"] if args.force else []
    cfg = load_config(InferConfig, args.config, [*args.overrides, *forced])
    check_output_folder(args.out, args.overwrite)
    session = open_session(args.session)
    # the heavy imports (onnxruntime) once the arguments are known to be good
    from gaitnet.pipeline.infer_folder import load_models, write_infer_folder

    run = write_infer_folder(
        session,
        cfg,
        load_models(cfg, args.segmenter, args.predictor),
        args.out,
        {"path": str(args.session), "software": f"gaitnet {__version__}"},
        overwrite=args.overwrite,
        save_labels=args.save_labels,
        progress=lambda stage_name: (
            lambda it, total: tqdm(it, total=total, desc=stage_name, unit="frame")
        ),
    )
    result, wall, gait, out = run.result, run.wall_s, run.gait, run.path
    n = len(result.t_s)
    seen = result.foot_measured.mean(axis=0)
    _print_trust(result.unreliable, result.vio)
    print(
        f"{n} frames ({result.t_s[-1] - result.t_s[0]:.1f} s) in {wall:.1f} s "
        f"({n / wall:.1f} frames/s): "
        + ", ".join(f"{k} {v:.1f} s" for k, v in result.timings_s.items())
    )
    print(
        f"body height {result.subject_height_m:.2f} m; feet seen in {100 * seen[0]:.0f} % (left) "
        f"/ {100 * seen[1]:.0f} % (right) of frames, the rest filled in"
    )
    _print_gait_summary(gait)
    print(f"wrote {out} (joints.npz, feet.csv, gait_strides.csv, summary.json, ...)")
    print(f"gait report: {out / 'report.html'}")
    return 0


def _print_gait_summary(gait: dict) -> None:
    """The time-distance table per side (mean ± SD over steady strides) and the symmetry."""
    from gaitnet.pipeline.gait_parameters import PARAMETERS

    width = max(len(f"{label} [{unit}]") for _, label, unit in PARAMETERS)
    print(f"{'':{width}s} {'left':>16s} {'right':>16s} {'SI %':>7s}")
    for key, label, unit in PARAMETERS:
        cells = []
        for side in ("left", "right"):
            stat = gait.get(side, {}).get(key)
            cells.append(f"{stat['mean']:.3f} ± {stat['sd']:.3f}" if stat else "–")
        si = gait.get("symmetry_index_pct", {}).get(key)
        si_text = "" if si is None else f"{si:+.1f}"
        print(f"{label + ' [' + unit + ']':{width}s} {cells[0]:>16s} {cells[1]:>16s} {si_text:>7s}")
    inferred = sum(int(gait.get(side, {}).get("n_inferred", 0)) for side in ("left", "right"))
    if inferred:
        print(
            "strides through a stance the camera never saw, laid from the rhythm of the "
            f"steps: {inferred} (gait_strides.csv: inferred)"
        )


def _cmd_tags(args: argparse.Namespace) -> int:
    import io

    from PIL import Image

    from gaitnet.io.atomic import atomic_write_bytes
    from gaitnet.io.types import AprilTagBoard
    from gaitnet.sim.tag_sheet import printable_sheet

    out = args.out
    if out.suffix.lower() not in (".png", ".pdf"):
        raise UsageError(f"{PROG} tags", f"{out}: the sheet is written as .png or .pdf")
    if out.exists() and not args.overwrite:
        raise UsageError(f"{PROG} tags", f"{out}: exists (choose another name or add --overwrite)")
    try:
        board = AprilTagBoard(
            name=args.name,
            family="tag36h11",
            rows=args.rows,
            cols=args.cols,
            tag_size_m=args.tag_size_mm / 1000.0,
            gap_m=args.gap_mm / 1000.0,
            first_id=args.first_id,
            T_WfromBoard=np.eye(4),
        )
    except ValueError as exc:  # the sheet's numbers, named as the board checks them
        raise UsageError(f"{PROG} tags", str(exc)) from None
    image = Image.fromarray(printable_sheet(board, args.paper, args.dpi))
    data = io.BytesIO()
    if out.suffix.lower() == ".pdf":
        image.save(data, "PDF", resolution=float(args.dpi))
    else:
        image.save(data, "PNG", dpi=(args.dpi, args.dpi))
    atomic_write_bytes(out, data.getvalue())
    last = board.first_id + board.rows * board.cols - 1
    print(
        f"wrote {out}: {board.rows}×{board.cols} tag36h11 tags (ids {board.first_id}–{last}) "
        f"of {args.tag_size_mm:g} mm on {args.paper.upper()} at {args.dpi} dpi; print it at "
        f"100 % (no fit to page) and check that a tag's black square measures "
        f"{args.tag_size_mm:g} mm"
    )
    print("for session.yaml (docs/session-format.md; T_WfromBoard: where the sheet lies):")
    print("apriltag_boards:")
    print(f"- name: {board.name}")
    print("  family: tag36h11")
    print(f"  rows: {board.rows}")
    print(f"  cols: {board.cols}")
    print(f"  tag_size_m: {board.tag_size_m:g}")
    print(f"  gap_m: {board.gap_m:g}")
    print(f"  first_id: {board.first_id}")
    print("  T_WfromBoard: [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]")
    return 0


def _cmd_batch(args: argparse.Namespace) -> int:
    import sys
    from pathlib import Path

    from gaitnet import __version__
    from gaitnet.batch.run import plan_batch, run_batch
    from gaitnet.errors import one_line

    # KEY=VALUE among the sessions (both are positional): an override unless it is a path
    sessions = [s for s in args.sessions if "=" not in s or Path(s).exists()]
    overrides = [s for s in args.sessions if s not in sessions] + list(args.overrides)
    plan = plan_batch(sessions, args.out, args.config, overrides)
    bars: list[tqdm] = []

    def start(total: int, skipped: int) -> None:
        bars.append(tqdm(total=total, initial=skipped, desc="sessions", unit="session"))

    def done(outcome) -> None:
        if not outcome.ok:
            tqdm.write(f"failed: {outcome.name}: {outcome.error}")
        bars[0].update(1)

    result = run_batch(plan, f"gaitnet {__version__}", args.workers, args.ray, start, done)
    for bar in bars:
        bar.close()
    failed, n = result.failed, len(plan.sessions)
    print(
        f"{n} session(s): {len(result.outcomes) - len(failed)} written, {len(result.skipped)} "
        f"skipped (complete already), {len(failed)} failed"
    )
    if result.outcomes:
        where = f"Ray tasks ({args.ray})" if args.ray else "worker processes"
        print(
            f"{result.workers} {where}, each session with {result.threads[0]} segmentation "
            f"thread(s) × {result.threads[1]} onnxruntime thread(s); {result.wall_s:.1f} s"
        )
    print(f"wrote {plan.out / 'cohort.csv'} ({len(result.rows) // 2} sessions) and cohort.html")
    if failed:
        names = ", ".join(o.name for o in failed)
        print(
            f"{PROG} batch: error: {len(failed)} of {n} session(s) failed, listed with their "
            f"errors in {plan.out / 'failures.csv'}: {one_line(names, limit=300)}",
            file=sys.stderr,
        )
        return 1
    return 0
