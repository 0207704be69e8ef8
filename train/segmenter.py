"""Train the foot/leg segmenter (RGB, HHA or late-fusion RGB+HHA FCN-8s, thesis sec. 4.1).

    python train/segmenter.py --config configs/segmenter/fusion_cpu.yaml
    python train/segmenter.py --config configs/segmenter/fusion_cpu.yaml --resume
    python train/segmenter.py --config C.yaml train.epochs=5 optim.lr=1e-3        # overrides
    torchrun --nproc_per_node 2 train/segmenter.py --config C.yaml                  # DDP
    python train/segmenter.py --config C.yaml --eval-only --checkpoint runs/segmenter/N/best.pt
    python train/segmenter.py --config C.yaml --eval-only --onnx models/segmenter/N.onnx

Outputs in ``<output_dir>/<name>/``: config.yaml (resolved), train.log, metrics.csv, tb/,
last.pt (every ``train.checkpoint_every`` batches and at each epoch's end), best.pt (highest
validation mIoU) and eval.json (pixel accuracy, mIoU, FW-IoU, per-class IoU and the confusion
matrix of best.pt on every set of ``eval.sets``). See docs/segmenter.md.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

try:
    import torch
    from torch.utils.data import DataLoader, DistributedSampler
except ModuleNotFoundError as exc:  # the core install has no PyTorch
    raise SystemExit(f"error: {exc.name} is not installed: pip install -e '.[train]'") from None
from tqdm import tqdm

from gaitnet.cli.scripts import run_script
from gaitnet.config import config_to_dict, dump_config, load_config
from gaitnet.errors import InputError
from gaitnet.io.atomic import atomic_write_text
from gaitnet.segmentation.segmenter_net import model_input
from gaitnet.training.checkpoint import (
    CheckpointError,
    git_hash,
    load_checkpoint,
    load_state,
    save_checkpoint,
)
from gaitnet.training.distributed import (
    DistInfo,
    all_reduce_sum,
    barrier,
    cleanup_distributed,
    init_distributed,
)
from gaitnet.training.logs import close_logging, setup_logging
from gaitnet.training.metrics import MetricsLogger, require_finite
from gaitnet.training.runs import (
    SkipSampler,
    checkpoint_to_resume,
    gather_rng_states,
    resolve_device,
    restore_rank_rng,
)
from gaitnet.training.scripts import ScriptParser
from gaitnet.training.seeding import seed_everything
from gaitnet.training.segmenter import (
    CLASS_NAMES,
    SegmenterTrainingConfig,
    architecture_only,
    build_loss,
    build_model,
    build_optimizer,
    build_scheduler,
    confusion_of,
    scores_of,
    with_checkpoint_model,
)
from gaitnet.training.segmenter_data import build_dataset, build_training_set, set_name

logger = logging.getLogger("train.segmenter")


def class_names(num_classes: int) -> list[str]:
    return [CLASS_NAMES[i] if i < len(CLASS_NAMES) else f"class{i}" for i in range(num_classes)]


def metric_fields(num_classes: int) -> list[str]:
    ious = [f"val/iou_{n}" for n in class_names(num_classes)]
    return [
        "lr",
        "train/loss",
        "train/pixel_acc",
        "val/loss",
        "val/pixel_acc",
        "val/miou",
        "val/fw_iou",
        *ious,
        "time/epoch_s",
    ]


def batch_input(batch: dict[str, Any], arch: str, device: torch.device) -> torch.Tensor:
    """The net input of ``arch`` from a data set batch (RGB/255, HHA/255 or both)."""
    return model_input(arch, batch["rgb"], batch["hha"]).to(device, non_blocking=True)


class EpochState:
    """Running sums of one training epoch (loss × pixels, correct pixels, labelled pixels) and
    its learning rate at the start; kept in mid-epoch checkpoints."""

    def __init__(self, lr: float = 0.0, sums: torch.Tensor | None = None) -> None:
        self.lr = float(lr)
        self.sums = torch.zeros(3, dtype=torch.float64) if sums is None else sums.clone()


def train_one_epoch(
    model: torch.nn.Module,
    optimizer: torch.optim.Optimizer,
    scheduler: torch.optim.lr_scheduler.LRScheduler,
    loader: DataLoader,
    loss_fn: torch.nn.Module,
    cfg: SegmenterTrainingConfig,
    epoch: int,
    device: torch.device,
    steps: int,
    start_step: int,
    state: EpochState,
    show: bool,
    on_step: Any = None,
) -> dict[str, float]:
    """Batches ``start_step … steps-1`` of the epoch; ``on_step(step, state)`` after each."""
    model.train()
    ignore = cfg.loss.ignore_index
    bar = tqdm(
        total=steps,
        initial=start_step,
        desc=f"epoch {epoch}",
        leave=False,
        disable=not show,
        mininterval=2.0,
    )
    step = start_step
    for batch in loader:
        if step >= steps:
            break
        x = batch_input(batch, cfg.model.arch, device)
        target = batch["label"].to(device, non_blocking=True)
        logits = model(x)
        loss = loss_fn(logits, target)
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        if cfg.optim.grad_clip_norm > 0:
            torch.nn.utils.clip_grad_norm_(model.parameters(), cfg.optim.grad_clip_norm)
        optimizer.step()
        scheduler.step()
        with torch.no_grad():
            valid = target != ignore
            n = int(valid.sum())
            correct = int(((logits.argmax(1) == target) & valid).sum())
        state.sums += torch.tensor([float(loss.detach()) * n, correct, n], dtype=torch.float64)
        require_finite({"train/loss": float(loss.detach())}, f"epoch {epoch}, step {step}")
        step += 1
        bar.update(1)
        bar.set_postfix(loss=f"{float(state.sums[0] / max(state.sums[2], 1)):.4f}", refresh=False)
        if on_step is not None:
            on_step(step, state)
    bar.close()
    sums = all_reduce_sum(state.sums.to(device)).cpu()
    if sums[2] == 0:
        raise InputError(f"epoch {epoch}: no labelled training pixel")
    stats = {"train/loss": float(sums[0] / sums[2]), "train/pixel_acc": float(sums[1] / sums[2])}
    require_finite(stats, f"epoch {epoch}")
    return stats


@torch.no_grad()
def evaluate(
    model: torch.nn.Module,
    loader: DataLoader,
    loss_fn: torch.nn.Module,
    arch: str,
    num_classes: int,
    ignore_index: int,
    device: torch.device,
    show: bool = False,
    desc: str = "eval",
) -> tuple[float, np.ndarray]:
    """Mean loss per labelled pixel and the confusion matrix over the whole loader (all
    ranks)."""
    model.eval()
    conf = torch.zeros(num_classes, num_classes, dtype=torch.int64)
    sums = torch.zeros(2, dtype=torch.float64)
    for batch in tqdm(loader, desc=desc, leave=False, disable=not show, mininterval=2.0):
        logits = model(batch_input(batch, arch, device))
        target = batch["label"].to(device)
        n = int((target != ignore_index).sum())
        sums += torch.tensor([float(loss_fn(logits, target)) * n, n], dtype=torch.float64)
        conf += confusion_of(logits, target, num_classes, ignore_index)
    sums = all_reduce_sum(sums.to(device)).cpu()
    conf = all_reduce_sum(conf.to(device)).cpu()
    return float(sums[0] / max(float(sums[1]), 1.0)), conf.numpy()


def val_stats(loss: float, conf: np.ndarray, num_classes: int) -> dict[str, float]:
    scores = scores_of(conf, class_names(num_classes))
    stats = {
        "val/loss": loss,
        "val/pixel_acc": scores["pixel_acc"],
        "val/miou": scores["miou"],
        "val/fw_iou": scores["fw_iou"],
    }
    for name, iou in _per_class(scores).items():
        if iou is not None:  # a class absent from the set has no IoU (empty CSV cell)
            stats[f"val/iou_{name}"] = iou
    return stats


def _per_class(scores: dict[str, Any]) -> dict[str, float | None]:
    iou = scores["iou"]
    if isinstance(iou, dict):
        return iou
    return dict(zip(class_names(len(iou)), iou, strict=True))


def eval_sets(
    cfg: SegmenterTrainingConfig,
    predict: Any,
    out_file: Path,
    extra: dict[str, Any],
    show: bool = True,
) -> dict[str, Any]:
    """Scores of ``predict`` (batch input → logits) on every set of ``eval.sets``."""
    n = cfg.model.num_classes
    result: dict[str, Any] = {"sets": {}, **extra}
    for path in cfg.eval.sets:
        ds = build_dataset(path, cfg, augment=False)
        loader = DataLoader(
            ds, cfg.eval.batch_size, shuffle=False, num_workers=cfg.data.num_workers
        )
        conf = np.zeros((n, n), dtype=np.int64)
        for batch in tqdm(loader, desc=set_name(path), leave=False, disable=not show):
            logits = predict(batch)
            conf += confusion_of(logits, batch["label"], n, cfg.loss.ignore_index).numpy()
        scores = scores_of(conf, class_names(n))
        result["sets"][set_name(path)] = {"path": str(path), "frames": len(ds), **scores}
        per_class = " ".join(
            f"{k} {v:.4f}" if v is not None else f"{k} -" for k, v in _per_class(scores).items()
        )
        logger.info(
            "%s (%d frames): pixel acc %.4f, mIoU %.4f, FW-IoU %.4f; IoU %s",
            set_name(path),
            len(ds),
            scores["pixel_acc"],
            scores["miou"],
            scores["fw_iou"],
            per_class,
        )
    atomic_write_text(out_file, json.dumps(result, indent=1) + "\n")
    logger.info("wrote %s", out_file)
    return result


def torch_predict(model: torch.nn.Module, arch: str, device: torch.device) -> Any:
    model.eval()

    @torch.no_grad()
    def predict(batch: dict[str, Any]) -> torch.Tensor:
        return model(batch_input(batch, arch, device)).cpu()

    return predict


def main(args: argparse.Namespace) -> int:
    """Train (or ``--eval-only``). Every input is checked before the run folder is touched."""
    info = init_distributed()
    cfg = load_config(SegmenterTrainingConfig, args.config, args.overrides)
    device = resolve_device(cfg.train.device)
    if cfg.train.num_threads > 0:
        torch.set_num_threads(cfg.train.num_threads)
    if args.eval_only:
        setup_logging(info.rank)
        return eval_only(cfg, args, device) if info.is_main else 0
    if args.onnx is not None or args.out is not None:
        raise InputError("--onnx and --out only go with --eval-only")
    ckpt_path = checkpoint_to_resume(cfg.run_dir, args.resume, args.checkpoint)
    ckpt = None
    if ckpt_path is not None:
        ckpt = load_checkpoint(ckpt_path)
        cfg = with_checkpoint_model(cfg, ckpt, ckpt_path)
    return train(cfg, args, info, device, ckpt, ckpt_path)


def train(
    cfg: SegmenterTrainingConfig,
    args: argparse.Namespace,
    info: DistInfo,
    device: torch.device,
    ckpt: dict[str, Any] | None,
    ckpt_path: Path | None,
) -> int:
    run_dir = cfg.run_dir
    if info.world_size > cfg.train.batch_size:
        raise InputError(
            f"train.batch_size={cfg.train.batch_size} is smaller than the {info.world_size} "
            "processes: each needs at least one frame per step"
        )
    seed_everything(cfg.train.seed, info.rank)
    loader_gen = torch.Generator().manual_seed(cfg.train.seed + info.rank)
    train_ds = build_training_set(cfg, seed=cfg.train.seed)
    val_ds = build_dataset(cfg.data.val, cfg, augment=False)
    base_sampler = DistributedSampler(
        train_ds, info.world_size, info.rank, shuffle=True, seed=cfg.train.seed, drop_last=True
    )
    train_sampler = SkipSampler(base_sampler)
    per_rank_batch = cfg.train.batch_size // info.world_size
    steps = len(base_sampler) // per_rank_batch
    if cfg.train.max_steps_per_epoch > 0:
        steps = min(steps, cfg.train.max_steps_per_epoch)
    if steps == 0:
        raise InputError(
            f"train.batch_size={cfg.train.batch_size} exceeds the {len(train_ds)} training "
            f"frames of {cfg.data.train}: not one full batch per epoch"
        )
    train_loader = DataLoader(
        train_ds,
        per_rank_batch,
        sampler=train_sampler,
        drop_last=True,
        num_workers=cfg.data.num_workers,
        generator=loader_gen,
    )
    val_sampler = DistributedSampler(val_ds, info.world_size, info.rank, shuffle=False)
    val_loader = DataLoader(
        val_ds, cfg.train.eval_batch_size, sampler=val_sampler, num_workers=cfg.data.num_workers
    )
    # A resumed run's weights come from its checkpoint, not from its initialisation keys.
    model = build_model(cfg.model if ckpt is None else architecture_only(cfg.model)).to(device)
    model_without_ddp = model
    loss_fn = build_loss(cfg.loss).to(device)
    optimizer = build_optimizer(model.parameters(), cfg.optim)
    scheduler = build_scheduler(optimizer, cfg.optim, cfg.train.epochs, steps)
    start_epoch, start_step, best_metric, best_epoch = 0, 0, -1.0, -1
    partial = EpochState()
    if ckpt is not None:
        assert ckpt_path is not None
        load_state(model_without_ddp, ckpt["model"], ckpt_path, "model")
        load_state(optimizer, ckpt["optimizer"], ckpt_path, "optimizer")
        load_state(scheduler, ckpt["scheduler"], ckpt_path, "scheduler")
        restore_rank_rng(ckpt, info.rank, ckpt_path, loader_gen)
        start_epoch = int(ckpt["epoch"]) + 1
        start_step = int(ckpt.get("step_in_epoch", 0))
        if start_step:
            partials = ckpt.get("partial")
            if not isinstance(partials, list) or info.rank >= len(partials):
                raise CheckpointError(
                    f"checkpoint {ckpt_path}: written mid-epoch by fewer processes than "
                    f"{info.world_size}; resume it with as many processes as wrote it"
                )
            partial = EpochState(ckpt["epoch_lr"], partials[info.rank])
        best_metric, best_epoch = float(ckpt["best_metric"]), int(ckpt["best_epoch"])
    if info.distributed:
        ids = [info.local_rank] if device.type == "cuda" else None
        model = torch.nn.parallel.DistributedDataParallel(model, device_ids=ids)

    # Every input is valid: from here on the run folder is written.
    setup_logging(info.rank, run_dir)
    n_params = sum(p.numel() for p in model_without_ddp.parameters())
    logger.info(
        "run %s on %s (%d process(es), %d threads); %s: %d parameters",
        run_dir,
        device,
        info.world_size,
        torch.get_num_threads(),
        cfg.model,
        n_params,
    )
    logger.info(
        "frames: %d train (%s), %d val (%s); %d batches of %d per epoch",
        len(train_ds),
        cfg.data.train,
        len(val_ds),
        cfg.data.val,
        steps,
        cfg.train.batch_size,
    )
    if ckpt is not None:
        logger.info(
            "resumed after epoch %d, batch %d (best val mIoU %.4f at epoch %d)",
            start_epoch - 1,
            start_step,
            best_metric,
            best_epoch,
        )
    metrics = None
    if info.is_main:
        atomic_write_text(run_dir / "config.yaml", dump_config(cfg))
        metrics = MetricsLogger(
            run_dir,
            metric_fields(cfg.model.num_classes),
            start_epoch=start_epoch,
            tensorboard=cfg.train.tensorboard,
        )
    commit = git_hash()

    def checkpoint(
        epoch_done: int,
        step_in_epoch: int,
        state: EpochState,
        gen_state: Any,
        extra: dict[str, Any],
    ) -> dict[str, Any]:
        # Mid-epoch: the loader generator as at the epoch's start (the resumed run creates the
        # epoch's iterator again, drawing its base seed from it).
        gen = torch.Generator()
        gen.set_state(gen_state)
        partials = [state.sums]
        if info.distributed:
            partials = [None] * info.world_size
            torch.distributed.all_gather_object(partials, state.sums)
        return {
            "model": model_without_ddp.state_dict(),
            "optimizer": optimizer.state_dict(),
            "scheduler": scheduler.state_dict(),
            "epoch": epoch_done,
            "step_in_epoch": step_in_epoch,
            "partial": partials,
            "epoch_lr": state.lr,
            "best_metric": best_metric,
            "best_epoch": best_epoch,
            "config": config_to_dict(cfg),
            "git_hash": commit,
            "rng": gather_rng_states(info, gen),
            **extra,
        }

    try:
        for epoch in range(start_epoch, cfg.train.epochs):
            t0 = time.perf_counter()
            train_sampler.set_epoch(epoch)
            train_ds.set_epoch(epoch)  # augmentations drawn from (seed, epoch, item)
            train_sampler.skip_next(start_step * per_rank_batch)
            gen_at_start = loader_gen.get_state()
            if start_step == 0:
                partial = EpochState(optimizer.param_groups[0]["lr"])
            lr = partial.lr

            def on_step(step: int, state: EpochState, epoch: int = epoch, g: Any = gen_at_start):
                every = cfg.train.checkpoint_every
                if every and step % every == 0 and step < steps:
                    ck = checkpoint(epoch - 1, step, state, g, {})
                    if info.is_main:
                        save_checkpoint(ck, run_dir / "last.pt")

            stats = train_one_epoch(
                model,
                optimizer,
                scheduler,
                train_loader,
                loss_fn,
                cfg,
                epoch,
                device,
                steps,
                start_step,
                partial,
                info.is_main,
                on_step,
            )
            start_step = 0
            val_loss, conf = evaluate(
                model_without_ddp,
                val_loader,
                loss_fn,
                cfg.model.arch,
                cfg.model.num_classes,
                cfg.loss.ignore_index,
                device,
            )
            stats.update(val_stats(val_loss, conf, cfg.model.num_classes))
            stats.update({"lr": lr, "time/epoch_s": time.perf_counter() - t0})
            require_finite(stats, f"epoch {epoch}")
            is_best = stats["val/miou"] > best_metric
            if is_best:
                best_metric, best_epoch = stats["val/miou"], epoch
            logger.info(
                "epoch %d/%d lr %.3g train loss %.4f acc %.4f | val mIoU %.4f foot %.4f "
                "acc %.4f%s | %.0f s",
                epoch,
                cfg.train.epochs - 1,
                lr,
                stats["train/loss"],
                stats["train/pixel_acc"],
                stats["val/miou"],
                stats.get("val/iou_foot", float("nan")),
                stats["val/pixel_acc"],
                " *best*" if is_best else "",
                stats["time/epoch_s"],
            )
            ck = checkpoint(epoch, 0, EpochState(), loader_gen.get_state(), {"val": stats})
            if info.is_main:
                assert metrics is not None
                metrics.log(epoch, stats)
                save_checkpoint(ck, run_dir / "last.pt")
                if is_best:
                    save_checkpoint(ck, run_dir / "best.pt")
    finally:
        if metrics is not None:
            metrics.close()
    barrier()
    if info.is_main and not args.no_final_eval and cfg.eval.sets:
        best = load_checkpoint(run_dir / "best.pt")
        load_state(model_without_ddp, best["model"], run_dir / "best.pt", "model")
        extra = {
            "checkpoint": str(run_dir / "best.pt"),
            "epoch": int(best["epoch"]),
            "val_miou": float(best["best_metric"]),
            "config": config_to_dict(cfg),
        }
        eval_sets(
            cfg,
            torch_predict(model_without_ddp, cfg.model.arch, device),
            run_dir / "eval.json",
            extra,
        )
    barrier()
    return 0


def eval_only(cfg: SegmenterTrainingConfig, args: argparse.Namespace, device: torch.device) -> int:
    """``--eval-only``: score a checkpoint (architecture from it) or an ONNX file on
    ``eval.sets``."""
    if (args.checkpoint is None) == (args.onnx is None):
        raise InputError("--eval-only needs exactly one of --checkpoint or --onnx")
    if args.resume:
        raise InputError("--resume and --eval-only exclude each other")
    extra: dict[str, Any] = {}
    if args.checkpoint is not None:
        source = Path(args.checkpoint)
        ckpt = load_checkpoint(source)
        cfg = with_checkpoint_model(cfg, ckpt, source)
        model = build_model(architecture_only(cfg.model)).to(device)
        load_state(model, ckpt["model"], source, "model")
        predict = torch_predict(model, cfg.model.arch, device)
        extra.update(checkpoint=str(source), epoch=int(ckpt["epoch"]))
    else:
        from gaitnet.segmentation.onnx_runtime import OnnxSegmenter

        source = Path(args.onnx)
        net = OnnxSegmenter(source, threads=max(1, torch.get_num_threads()))
        if net.arch != cfg.model.arch:
            logger.warning("%s is a %s model (config says %s)", source, net.arch, cfg.model.arch)
            cfg = replace(cfg, model=replace(cfg.model, arch=net.arch))
        if net.input_scale != cfg.model.input_scale:  # the HHA stride follows the model
            cfg = replace(cfg, model=replace(cfg.model, input_scale=net.input_scale))

        def predict(batch: dict[str, Any]) -> torch.Tensor:
            x = model_input(net.arch, batch["rgb"], batch["hha"]).numpy().astype(np.float32)
            return torch.from_numpy(np.asarray(net(x)))

        extra.update(onnx=str(source))
    extra["config"] = config_to_dict(cfg)
    out = Path(args.out) if args.out else source.with_name(f"eval_{source.stem}.json")
    eval_sets(cfg, predict, out, extra)
    return 0


def get_args_parser() -> argparse.ArgumentParser:
    parser = ScriptParser(prog="train/segmenter.py", description=__doc__.splitlines()[0])
    parser.add_argument("--config", required=True, help="YAML config (configs/segmenter/)")
    parser.add_argument(
        "--resume",
        action="store_true",
        help="continue from <run_dir>/last.pt (or --checkpoint); the whole state is restored",
    )
    parser.add_argument("--eval-only", action="store_true", help="only evaluate, no training")
    parser.add_argument(
        "--checkpoint", help="checkpoint to evaluate (--eval-only) or to resume from (--resume)"
    )
    parser.add_argument("--onnx", help="with --eval-only: exported ONNX model to evaluate")
    parser.add_argument("--out", help="with --eval-only: JSON to write (default: next to it)")
    parser.add_argument(
        "--no-final-eval", action="store_true", help="skip eval.json after training"
    )
    parser.add_argument("overrides", nargs="*", help="config overrides key=value")
    return parser


def cli(argv: list[str] | None = None) -> int:
    """Parse ``argv`` and run :func:`main`: bad input is one line on stderr and exit status 1
    (gaitnet's error taxonomy, gaitnet/errors.py); anything else is a bug with a traceback."""
    try:
        return run_script(lambda: main(get_args_parser().parse_args(argv)))
    finally:
        close_logging()
        cleanup_distributed()


if __name__ == "__main__":
    sys.exit(cli())
