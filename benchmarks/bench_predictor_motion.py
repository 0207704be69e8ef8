"""Motion predictors by motion type: MPJPE per horizon vs zero- and constant-velocity.

Labels every window (10 observed + 10 future frames at 30 fps) as standing, steady walking,
starting/stopping or turning (the rule: ``gaitnet.motion.motion_types``) and prints, per type,
the MPJPE [mm] of each model and both baselines at every horizon (33 … 333 ms), the mean over
the horizons, and the share of windows in which the model's mean error is below zero
velocity's. Windows come from a prepared file (``--prepared``, one split) or straight from a
folder of AMASS-format clips (``--amass-root``: read as a user's AMASS files with the project's
loader, every clip evaluated):

    python benchmarks/bench_predictor_motion.py --prepared data/cache/synthwalk_mix.npz \\
        --split test --model gcn=models/predictor/dctgcn_walk_small.onnx
    python benchmarks/bench_predictor_motion.py --amass-root /path/to/AMASS --include walk \\
        --model gcn=models/predictor/dctgcn_walk_small.onnx --json out.json

MPJPE on one evaluation skeleton (the built-in one of ``--skeleton-height``, as
``train/predictor.py``'s ``eval.json``), predicted and true poses sharing the true translation.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import tempfile  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from gaitnet.motion.amass import DEFAULT_EXCLUDE, DEFAULT_INCLUDE  # noqa: E402
from gaitnet.motion.evaluation import (  # noqa: E402
    constant_velocity,
    evaluate_predictors,
    onnx_predictor,
    zero_velocity,
)
from gaitnet.motion.motion_types import MOTION_TYPES, labelled_windows, per_window_mpjpe  # noqa: E402
from gaitnet.motion.onnx_runtime import OnnxPredictor  # noqa: E402
from gaitnet.motion.prepared import load_prepared, prepare_walking_subset  # noqa: E402
from gaitnet.motion.skeleton import builtin_skeleton  # noqa: E402
from gaitnet.motion.windows import WalkingWindows  # noqa: E402
from gaitnet.training.scripts import ScriptParser  # noqa: E402

N_PAST, N_FUTURE = 10, 10


def _model(text: str) -> tuple[str, str]:
    name, sep, path = text.partition("=")
    if not sep or not name or not path:
        raise argparse.ArgumentTypeError(f"expected NAME=PATH.onnx, got {text!r}")
    return name, path


def _windows(args: argparse.Namespace) -> WalkingWindows:
    if args.prepared is not None:
        prepared = load_prepared(args.prepared)
        split = args.split
    else:
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp) / "clips.npz"
            prepare_walking_subset(args.amass_root, out, include=args.include, exclude=args.exclude)
            prepared = load_prepared(out)
        prepared = replace(prepared, clip_split=np.full(prepared.n_clips, "test"))
        split = "test"
    return WalkingWindows(prepared, split, n_past=N_PAST, n_future=N_FUTURE, stride=args.stride)


def main(argv: list[str] | None = None) -> int:
    parser = ScriptParser(description=__doc__.splitlines()[0])
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--prepared", help="prepared file of data/prepare_amass.py")
    source.add_argument("--amass-root", help="folder of AMASS-format clips (all evaluated)")
    parser.add_argument("--split", default="test", choices=("train", "val", "test"))
    parser.add_argument("--include", nargs="+", default=list(DEFAULT_INCLUDE))
    parser.add_argument("--exclude", nargs="*", default=list(DEFAULT_EXCLUDE))
    parser.add_argument(
        "--model", type=_model, action="append", default=[], help="NAME=PATH.onnx (repeatable)"
    )
    parser.add_argument("--stride", type=int, default=1, help="frames between windows")
    parser.add_argument("--skeleton-height", type=float, default=1.75)
    parser.add_argument("--json", help="write the numbers to this JSON file")
    args = parser.parse_args(argv)
    windows = _windows(args)
    poses, labels = labelled_windows(windows)
    models = {n: onnx_predictor(OnnxPredictor(p, threads=1)) for n, p in args.model}
    skeleton = builtin_skeleton(args.skeleton_height)
    print(f"{len(poses)} windows (stride {args.stride}) from {windows.data.path}")
    report: dict[str, object] = {"n_windows": int(len(poses)), "types": {}}
    for kind in (*MOTION_TYPES, "all"):
        sel = poses if kind == "all" else poses[labels == kind]
        if len(sel) == 0:
            print(f"\n{kind}: no windows")
            continue
        result = evaluate_predictors(sel, models, skeleton, n_past=N_PAST, fps=windows.fps)
        past, truth = sel[:, :N_PAST], sel[:, N_PAST:]
        zv = per_window_mpjpe(zero_velocity(past, N_FUTURE), truth, skeleton)
        cv = per_window_mpjpe(constant_velocity(past, N_FUTURE), truth, skeleton)
        beats = {
            n: float(np.mean(per_window_mpjpe(m(past), truth, skeleton) < zv))
            for n, m in models.items()
        }
        beats["constant_velocity"] = float(np.mean(cv < zv))
        print(f"\n{kind}: {len(sel)} windows; MPJPE [mm] per horizon [ms], mean, beats-ZV share")
        print(f"{'':18s}" + "".join(f"{h:7.0f}" for h in result.horizons_ms) + "   mean  beats")
        entry = {"n_windows": int(len(sel)), "methods": {}}
        for name, m in result.methods.items():
            row = "".join(f"{1000 * v:7.2f}" for v in m.mpjpe_m)
            share = f"{100 * beats[name]:5.0f}%" if name in beats else ""
            print(f"{name:18s}{row}{1000 * m.mean_mpjpe_m:7.2f} {share}")
            entry["methods"][name] = {
                "mpjpe_mm": [round(1000 * float(v), 3) for v in m.mpjpe_m],
                "mean_mm": round(1000 * m.mean_mpjpe_m, 3),
                "beats_zero_velocity": beats.get(name),
            }
        report["types"][kind] = entry
    if args.json:
        Path(args.json).write_text(json.dumps(report, indent=1) + "\n")
        print(f"\nwrote {args.json}")
    return 0


if __name__ == "__main__":
    from gaitnet.cli.scripts import run_script

    raise SystemExit(run_script(main))
