"""Export trained models to ONNX with a parity check against PyTorch.

    python export/to_onnx.py predictor --checkpoint runs/predictor/NAME/best.pt \
        --out models/predictor/NAME.onnx
    python export/to_onnx.py segmenter --checkpoint runs/segmenter/NAME/best.pt \
        --out models/segmenter/NAME.onnx [--height 480 --width 640]

``predictor``: the DCT-GCN motion predictor. The architecture comes from the checkpoint's
resolved config; the export is refused unless onnxruntime reproduces PyTorch within
``--atol`` (default 1e-4) on random inputs (gaitnet.motion.onnx_runtime.export_predictor_onnx).
Prints the largest absolute difference and writes a JSON sidecar next to the model
(``NAME.json``): input/output names and shapes, n_past, n_future, dct_n, frame rate, the node
layout, the training config and, when the run folder has one, the evaluation (eval.json).
The scores in a sidecar are always the exported checkpoint's own (:func:`read_eval`).

``segmenter``: the FCN-8s foot/leg segmenter (``train/segmenter.py``). The net comes from the
checkpoint (``config.model``: arch, width, num_classes, input_scale;
gaitnet.segmentation.segmenter_net.segmenter_from_checkpoint) and is exported for frames of
``--height`` × ``--width`` with a dynamic batch; the export is refused unless onnxruntime
reproduces PyTorch's logits within ``--atol`` (default 1e-4) on random inputs
(gaitnet.segmentation.onnx_runtime.export_segmenter_onnx). The arch, width, input scale,
padding, output stride, logit bias, class names and normalisation are stored in the model's
metadata_props (what OnnxSegmenter reads); the JSON sidecar repeats them with the checkpoint,
the training config, the calibration (``train/calibrate_segmenter.py``) and the checkpoint's
scores: ``eval_<checkpoint name>.json`` beside it (``train/segmenter.py --eval-only``), or for
``best.pt`` the run's eval.json.

Each model kind is a subcommand with its own ``run_*`` function.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from pathlib import Path
from typing import Any

from gaitnet.cli.scripts import missing_train_extra
from gaitnet.errors import USER_ERRORS, InputError, user_error_message
from gaitnet.io.atomic import atomic_write_text
from gaitnet.training.scripts import ScriptParser


def read_eval(checkpoint: Path) -> Any:
    """The checkpoint's own scores for the sidecar (without their config), or None: the
    ``eval_<name>.json`` that ``train/segmenter.py --eval-only`` writes next to it, else, for a
    ``best.pt``, the run folder's ``eval.json`` (written at the end of training, of ``best.pt``).
    Another checkpoint (``calibrated.pt``, ``last.pt``) without its own file gets None, never
    the scores of a different one."""
    candidates = [checkpoint.with_name(f"eval_{checkpoint.stem}.json")]
    if checkpoint.stem == "best":
        candidates.append(checkpoint.parent / "eval.json")
    eval_file = next((c for c in candidates if c.is_file()), None)
    if eval_file is None:
        return None
    try:
        full = json.loads(eval_file.read_text(encoding="utf-8"))
    except (ValueError, OSError) as exc:
        raise InputError(f"{eval_file}: not a readable eval.json ({exc})") from exc
    if not isinstance(full, dict):
        raise InputError(f"{eval_file}: expected a JSON object")
    return {k: full[k] for k in full if k not in ("config",)}


def file_facts(out: Path) -> dict[str, Any]:
    """Name, SHA-256 and size of a written model file."""
    data = out.read_bytes()
    return {"onnx": out.name, "sha256": hashlib.sha256(data).hexdigest(), "size_bytes": len(data)}


def run_predictor(args: argparse.Namespace) -> int:
    """Export a DCT-GCN checkpoint (``train/predictor.py``) and write its sidecar."""
    from gaitnet.config import parse_config
    from gaitnet.motion.gcn import DCTGCN, NODE_JOINT_NAMES, NODE_JOINTS
    from gaitnet.motion.onnx_runtime import INPUT_NAME, OUTPUT_NAME, export_predictor_onnx
    from gaitnet.training.checkpoint import load_checkpoint, load_state
    from gaitnet.training.predictor import PredictorTrainingConfig

    checkpoint = Path(args.checkpoint)
    ckpt = load_checkpoint(checkpoint)
    cfg = parse_config(PredictorTrainingConfig, ckpt["config"], f"{checkpoint} (config)")
    model = DCTGCN(cfg.model)
    load_state(model, ckpt["model"], checkpoint, "model")
    out = Path(args.out)
    report = export_predictor_onnx(model, out, opset=args.opset, atol=args.atol)
    print(f"parity: max |onnxruntime - torch| = {report.max_abs_diff:.3g} (atol {args.atol:g}, "
          f"batches {list(report.batch_sizes)})")  # fmt: skip

    m = cfg.model
    metrics = read_eval(checkpoint)
    sidecar = {
        "name": cfg.name,
        "kind": "gaitnet motion predictor (DCT-GCN, thesis sec. 4.2)",
        **file_facts(out),
        "opset": report.opset,
        "input": {"name": INPUT_NAME, "shape": ["batch", m.n_past, m.n_nodes], "dtype": "float32"},
        "output": {
            "name": OUTPUT_NAME,
            "shape": ["batch", m.n_past + m.n_future, m.n_nodes],
            "dtype": "float32",
            "note": "reconstructed past frames then the n_future predicted frames",
        },
        "n_past": m.n_past,
        "n_future": m.n_future,
        "dct_n": m.dct_n,
        "fps": float(ckpt.get("fps", 30.0)),
        "node_layout": {
            "nodes": m.n_nodes,
            "node": "3*j + c: axis-angle component c (x, y, z) of joint j",
            "smpl_joints": list(NODE_JOINTS),
            "joint_names": list(NODE_JOINT_NAMES),
            "joint_0": "root orientation, world-from-pelvis, heading-normalised so the body "
            "faces +x (z up) at the last observed frame",
            "others": "local rotations relative to the parent (SMPL convention)",
            "translation": "not predicted",
        },
        "parity_max_abs_diff": report.max_abs_diff,
        "checkpoint": {
            "path": str(checkpoint),
            "epoch": int(ckpt["epoch"]),
            "val_mpjpe_m": float(ckpt["best_metric"]),
            "git_hash": ckpt["git_hash"],
        },
        "config": ckpt["config"],
        "metrics": metrics,
    }
    sidecar_path = out.with_suffix(".json")
    atomic_write_text(sidecar_path, json.dumps(sidecar, indent=1) + "\n")
    print(f"wrote {out} ({out.stat().st_size / 1e6:.2f} MB) and {sidecar_path}")
    return 0


def run_segmenter(args: argparse.Namespace) -> int:
    """Export a segmenter checkpoint (``train/segmenter.py``) and write its sidecar."""
    from gaitnet.segmentation.onnx_runtime import (
        INPUT_NAME,
        OUTPUT_NAME,
        default_classes,
        export_segmenter_onnx,
        segmenter_metadata,
    )
    from gaitnet.segmentation.segmenter_net import segmenter_from_checkpoint
    from gaitnet.training.checkpoint import load_checkpoint

    checkpoint = Path(args.checkpoint)
    ckpt = load_checkpoint(checkpoint)
    model = segmenter_from_checkpoint(ckpt, str(checkpoint))
    out = Path(args.out)
    report = export_segmenter_onnx(
        model, out, height=args.height, width=args.width, opset=args.opset, atol=args.atol
    )
    print(f"parity: max |onnxruntime - torch| = {report.max_abs_diff:.3g} (atol {args.atol:g}, "
          f"batches {list(report.batch_sizes)}, {args.width}x{args.height})")  # fmt: skip
    meta = segmenter_metadata(model, default_classes(model.num_classes))
    c = model.in_channels
    sidecar = {
        "name": ckpt["config"].get("name"),
        "kind": "gaitnet foot/leg segmenter (FCN-8s, thesis sec. 4.1)",
        **file_facts(out),
        "opset": report.opset,
        "input": {"name": INPUT_NAME, "shape": ["batch", c, args.height, args.width],
                  "dtype": "float32", "channels": meta["gaitnet.input"]},
        "output": {"name": OUTPUT_NAME, "shape": ["batch", model.num_classes, args.height,
                   args.width], "dtype": "float32", "note": "logits; labels = arg-max"},
        **model.config(),
        "classes": json.loads(meta["gaitnet.classes"]),
        "normalisation": json.loads(meta["gaitnet.normalisation"]),
        "parameters": sum(p.numel() for p in model.parameters()),
        "parity_max_abs_diff": report.max_abs_diff,
        "checkpoint": {
            "path": str(checkpoint),
            "epoch": int(ckpt["epoch"]),
            "best_metric": float(ckpt["best_metric"]),
            "git_hash": ckpt["git_hash"],
        },
        "config": ckpt["config"],
        "calibration": ckpt.get("calibration"),
        "metrics": read_eval(checkpoint),
    }  # fmt: skip
    sidecar_path = out.with_suffix(".json")
    atomic_write_text(sidecar_path, json.dumps(sidecar, indent=1) + "\n")
    print(f"wrote {out} ({out.stat().st_size / 1e6:.2f} MB) and {sidecar_path}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = ScriptParser(prog="export/to_onnx.py", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="kind", required=True, metavar="KIND")
    p = sub.add_parser("predictor", help="DCT-GCN motion predictor checkpoint → ONNX")
    p.add_argument("--checkpoint", required=True, help="best.pt / last.pt of train/predictor.py")
    p.add_argument("--out", required=True, help="ONNX file to write (sidecar: same name .json)")
    p.add_argument("--opset", type=int, default=18, help="ONNX opset (default 18)")
    p.add_argument("--atol", type=float, default=1e-4, help="parity tolerance (default 1e-4)")
    p.set_defaults(func=run_predictor)
    p = sub.add_parser("segmenter", help="FCN-8s foot/leg segmenter checkpoint → ONNX")
    p.add_argument("--checkpoint", required=True, help="best.pt / last.pt of train/segmenter.py")
    p.add_argument("--out", required=True, help="ONNX file to write (sidecar: same name .json)")
    p.add_argument("--height", type=int, default=480, help="frame height (default 480)")
    p.add_argument("--width", type=int, default=640, help="frame width (default 640)")
    p.add_argument("--opset", type=int, default=18, help="ONNX opset (default 18)")
    p.add_argument("--atol", type=float, default=1e-4, help="parity tolerance (default 1e-4)")
    p.set_defaults(func=run_segmenter)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the exporter: bad input (gaitnet's errors, ``OSError``), a failed parity check and
    PyTorch missing (a core install) are one line on stderr and exit status 1; anything else
    is a bug with a traceback."""
    from gaitnet.io.onnx_export import OnnxParityError  # both models' exports raise it

    try:
        args = build_parser().parse_args(argv)
        return args.func(args)
    except USER_ERRORS as exc:
        print(f"error: {user_error_message(exc)}", file=sys.stderr)
        return 1
    except OnnxParityError as exc:
        print(f"error: export failed: {user_error_message(exc)}", file=sys.stderr)
        return 1
    except ModuleNotFoundError as exc:  # a core install without the train extra
        message = missing_train_extra(exc)
        if message is None:
            raise
        print(message, file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
