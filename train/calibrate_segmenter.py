"""Choose a trained segmenter's per-class logit bias on its validation set (docs/segmenter.md).

    python train/calibrate_segmenter.py --config configs/segmenter/C.yaml \
        --checkpoint runs/segmenter/N/best.pt                     # → runs/segmenter/N/calibrated.pt
    python train/calibrate_segmenter.py --config C.yaml --checkpoint X.pt --set S.txt --out Y.pt

Runs the checkpoint's net (on ``train.device``) on ``data.val`` (or ``--set``), picks the bias
that maximises the mean IoU of those pixels (:mod:`gaitnet.training.calibration`; every class
must occur in the set) and writes a copy of the checkpoint whose ``config.model.logit_bias``
holds it (added to any bias it had), with a ``calibration`` entry (set, bias, mIoU before and
after). Score it on ``eval.sets`` with ``train/segmenter.py --eval-only --checkpoint`` (which
writes ``eval_calibrated.json`` beside it) and export it with ``export/to_onnx.py``.
"""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path
from typing import Any

try:
    import torch
    from torch.utils.data import DataLoader
except ModuleNotFoundError as exc:  # the core install has no PyTorch
    raise SystemExit(f"error: {exc.name} is not installed: pip install -e '.[train]'") from None
from tqdm import tqdm

from gaitnet.cli.scripts import run_script
from gaitnet.config import load_config
from gaitnet.errors import InputError
from gaitnet.segmentation.segmenter_net import model_input
from gaitnet.training.calibration import PixelSample, fit_logit_bias
from gaitnet.training.checkpoint import load_checkpoint, load_state, save_checkpoint
from gaitnet.training.logs import close_logging, setup_logging
from gaitnet.training.runs import resolve_device
from gaitnet.training.scripts import ScriptParser
from gaitnet.training.segmenter import (
    SegmenterTrainingConfig,
    architecture_only,
    build_model,
    with_checkpoint_model,
)
from gaitnet.training.segmenter_data import build_dataset, set_name

logger = logging.getLogger("train.calibrate_segmenter")


def main(args: argparse.Namespace) -> int:
    cfg = load_config(SegmenterTrainingConfig, args.config, args.overrides)
    if cfg.train.num_threads > 0:
        torch.set_num_threads(cfg.train.num_threads)
    source = Path(args.checkpoint)
    out = Path(args.out) if args.out else source.with_name("calibrated.pt")
    if out.resolve() == source.resolve():
        raise InputError(f"--out {out} would overwrite the checkpoint it calibrates")
    setup_logging(0)
    device = resolve_device(cfg.train.device)
    ckpt = load_checkpoint(source)
    cfg = with_checkpoint_model(cfg, ckpt, source)
    model = build_model(architecture_only(cfg.model))  # its weights come from the checkpoint
    load_state(model, ckpt["model"], source, "model")
    model.to(device).eval()
    data_set = Path(args.set) if args.set else cfg.data.val
    ds = build_dataset(data_set, cfg, augment=False)
    sample = PixelSample(cfg.model.num_classes, cfg.loss.ignore_index, args.max_pixels)
    loader = DataLoader(ds, cfg.eval.batch_size, shuffle=False, num_workers=cfg.data.num_workers)
    with torch.no_grad():
        for batch in tqdm(loader, desc=f"calibrate on {set_name(data_set)}", mininterval=2.0):
            x = model_input(cfg.model.arch, batch["rgb"], batch["hha"]).to(device)
            sample.add(model(x).cpu().numpy(), batch["label"].numpy())
    fit = fit_logit_bias(*sample.arrays())
    if fit.at_grid_edge:
        logger.warning(
            "%s: the fitted bias %s reaches the end of the search grid; the net is far from "
            "calibrated on %s (check the set and the checkpoint)",
            source,
            list(fit.bias),
            data_set,
        )
    bias = [round(old + new, 6) for old, new in zip(model.logit_bias, fit.bias, strict=True)]
    calibrated: dict[str, Any] = dict(ckpt)
    config = dict(ckpt["config"])
    config["model"] = {**config["model"], "logit_bias": bias}
    calibrated["config"] = config
    calibrated["calibration"] = {
        "set": str(data_set),
        "frames": len(ds),
        "pixels": int(sample.arrays()[1].size),
        "fitted_bias": list(fit.bias),
        "logit_bias": bias,
        "miou_before": fit.miou_before,
        "miou_after": fit.miou_after,
        "at_grid_edge": fit.at_grid_edge,
        "source": str(source),
    }
    save_checkpoint(calibrated, out)
    logger.info(
        "%s: logit bias %s; validation mIoU %.4f → %.4f (%d frames); wrote %s",
        source,
        bias,
        fit.miou_before,
        fit.miou_after,
        len(ds),
        out,
    )
    return 0


def get_args_parser() -> argparse.ArgumentParser:
    parser = ScriptParser(prog="train/calibrate_segmenter.py", description=__doc__.splitlines()[0])
    parser.add_argument("--config", required=True, help="the checkpoint's training config")
    parser.add_argument("--checkpoint", required=True, help="segmenter checkpoint (best.pt)")
    parser.add_argument("--set", help="split file or folder to calibrate on (default data.val)")
    parser.add_argument("--out", help="checkpoint to write (default calibrated.pt beside it)")
    parser.add_argument(
        "--max-pixels",
        type=int,
        default=20_000_000,
        help="labelled pixels kept (a random subset beyond; default 20 million)",
    )
    parser.add_argument("overrides", nargs="*", help="config overrides key=value")
    return parser


def cli(argv: list[str] | None = None) -> int:
    """As train/segmenter.py: bad input is one line on stderr and exit status 1."""
    try:
        return run_script(lambda: main(get_args_parser().parse_args(argv)))
    finally:
        close_logging()


if __name__ == "__main__":
    sys.exit(cli())
