"""Train the DCT-GCN lower-body motion predictor (thesis sec. 4.2) from a YAML config.

    python train/predictor.py --config configs/predictor/dctgcn_synthwalk_small.yaml
    python train/predictor.py --config configs/predictor/dctgcn_synthwalk_small.yaml --resume
    python train/predictor.py --config C.yaml --resume --checkpoint other/last.pt train.epochs=80
    python train/predictor.py --config C.yaml train.epochs=5 optim.lr=1e-3     # overrides
    python train/predictor.py --config C.yaml --init runs/predictor/N/best.pt   # fine-tune
    torchrun --nproc_per_node 2 train/predictor.py --config C.yaml              # DDP
    python train/predictor.py --config C.yaml --eval-only --checkpoint runs/predictor/N/best.pt
    python train/predictor.py --config C.yaml --eval-only --onnx models/predictor/N.onnx

Outputs in ``<output_dir>/<name>/``: config.yaml (resolved), train.log, metrics.csv, tb/,
last.pt, best.pt (lowest validation MPJPE over the future frames) and eval.json (per-horizon
MPJPE / MAE of the GCN and the zero- and constant-velocity baselines on ``eval.split``, from
best.pt). See docs/predictor.md.
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import sys
import time
from pathlib import Path
from typing import Any

try:
    import torch
    from torch.utils.data import DataLoader, DistributedSampler
except ModuleNotFoundError as exc:  # the core install has no PyTorch
    raise SystemExit(f"error: {exc.name} is not installed: pip install -e '.[train]'") from None
from tqdm import tqdm

from gaitnet.cli.scripts import run_script
from gaitnet.config import config_to_dict, dump_config, load_config
from gaitnet.errors import InputError
from gaitnet.evaluation.metrics import mean_angle_error, mpjpe_per_horizon
from gaitnet.io.atomic import atomic_write_text
from gaitnet.motion.evaluation import (
    Predictor,
    evaluate_predictors,
    onnx_predictor,
    torch_predictor,
)
from gaitnet.motion.gcn import DCTGCN, PredictorConfig, joint_positions
from gaitnet.motion.losses import motion_loss, per_window_skeleton
from gaitnet.motion.prepared import load_prepared
from gaitnet.training.checkpoint import (
    CheckpointError,
    git_hash,
    load_checkpoint,
    load_state,
    save_checkpoint,
    with_checkpoint_model,
)
from gaitnet.training.distributed import (
    all_reduce_sum,
    barrier,
    cleanup_distributed,
    init_distributed,
)
from gaitnet.training.logs import close_logging, setup_logging
from gaitnet.training.metrics import MetricsLogger, require_finite
from gaitnet.training.predictor import (
    PredictorTrainingConfig,
    augmented,
    build_windows,
    clip_skeletons,
    loss_skeleton,
    prepared_with_split,
    window_weights,
)
from gaitnet.training.scripts import ScriptParser
from gaitnet.training.seeding import restore_rng_state, rng_state, seed_everything

logger = logging.getLogger("train.predictor")
ARCH = "DCT-GCN architecture"  # what a checkpoint's config.model is, in errors
METRICS = (
    "lr",
    "train/loss",
    "train/mpjpe_m",
    "train/mae_rad",
    "val/loss",
    "val/mpjpe_m",
    "val/mae_rad",
    "val/mpjpe_last_m",
    "time/epoch_s",
)


def train_one_epoch(
    model: torch.nn.Module,
    optimizer: torch.optim.Optimizer,
    loader: DataLoader,
    cfg: PredictorTrainingConfig,
    epoch: int,
    device: torch.device | str,
    show: bool,
) -> dict[str, float]:
    """One pass over the training windows; loss (4.5)+(4.6) on all T + K output frames, each
    window's MPJPE on its clip's skeleton; input noise ``augment.input_noise_rad``."""
    model.train()
    n_past = cfg.model.n_past
    sums = torch.zeros(4, dtype=torch.float64, device=device)  # loss, mpjpe, mae, windows
    bar = tqdm(loader, desc=f"epoch {epoch}", leave=False, disable=not show, mininterval=2.0)
    noise = cfg.augment.input_noise_rad
    for i, (poses, skeleton) in enumerate(bar):
        poses = poses.to(device, non_blocking=True)
        skeleton = skeleton.to(device, non_blocking=True)
        past = poses[:, :n_past]
        if noise > 0:  # noise on the observed input only; the targets stay clean
            past = past + noise * torch.randn_like(past)
        out = model(past)
        weights = window_weights(cfg.loss, getattr(model, "module", model), poses, skeleton)
        loss = motion_loss(out, poses, skeleton, w_mpjpe=cfg.loss.w_mpjpe, w_mae=cfg.loss.w_mae,
                           window_weights=weights)  # fmt: skip
        optimizer.zero_grad(set_to_none=True)
        loss.total.backward()
        if cfg.optim.grad_clip_norm > 0:
            torch.nn.utils.clip_grad_norm_(model.parameters(), cfg.optim.grad_clip_norm)
        optimizer.step()
        b = poses.shape[0]
        terms = torch.stack([loss.total.detach(), loss.mpjpe.detach(), loss.mae.detach()])
        sums[:3] += terms.double() * b
        sums[3] += b
        if i % 50 == 0:  # a host sync: not every step
            require_finite({"train/loss": float(sums[0])}, f"epoch {epoch}, step {i}")
            bar.set_postfix(loss=f"{float(sums[0] / sums[3]):.4f}", refresh=False)
    sums = all_reduce_sum(sums).cpu()
    if sums[3] == 0:
        raise InputError(f"epoch {epoch}: no training batch (fewer windows than one batch)")
    stats = {
        "train/loss": float(sums[0] / sums[3]),
        "train/mpjpe_m": float(sums[1] / sums[3]),
        "train/mae_rad": float(sums[2] / sums[3]),
    }
    require_finite(stats, f"epoch {epoch}")
    return stats


@torch.no_grad()
def evaluate(
    model: torch.nn.Module,
    loader: DataLoader,
    cfg: PredictorTrainingConfig,
    device: torch.device | str,
) -> dict[str, float]:
    """Validation loss and MPJPE / MAE of the predicted (future) frames, per horizon too
    (each window's MPJPE on its clip's skeleton, as the training loss)."""
    model.eval()
    n_past, K = cfg.model.n_past, cfg.model.n_future
    # [loss × windows, windows, MPJPE sum per horizon (K), MAE × windows]
    sums = torch.zeros(3 + K, dtype=torch.float64, device=device)
    for poses, skeleton in loader:
        poses, skeleton = poses.to(device), skeleton.to(device)
        out = model(poses[:, :n_past])
        weights = window_weights(cfg.loss, model, poses, skeleton)
        loss = motion_loss(out, poses, skeleton, w_mpjpe=cfg.loss.w_mpjpe, w_mae=cfg.loss.w_mae,
                           window_weights=weights)  # fmt: skip
        b = poses.shape[0]
        pred, true = out[:, n_past:], poses[:, n_past:]
        skel = per_window_skeleton(skeleton, pred)
        p_pred, p_true = joint_positions(pred, skel), joint_positions(true, skel)
        sums[0] += loss.total.double() * b
        sums[1] += b
        sums[2 : 2 + K] += mpjpe_per_horizon(p_pred, p_true, reduction="sum").double()
        sums[-1] += mean_angle_error(pred, true).double() * b
    totals = all_reduce_sum(sums).cpu()
    n = totals[1]
    per_h = totals[2 : 2 + K] / n
    return {
        "val/loss": float(totals[0] / n),
        "val/mpjpe_m": float(per_h.mean()),
        "val/mae_rad": float(totals[-1] / n),
        "val/mpjpe_last_m": float(per_h[-1]),
    }


def final_evaluation(
    cfg: PredictorTrainingConfig,
    predictor: Predictor,
    name: str,
    out_file: Path,
    extra: dict[str, Any],
) -> dict[str, Any]:
    """Per-horizon MPJPE/MAE of ``predictor`` and both baselines on ``cfg.eval.split``."""
    prepared = prepared_with_split(load_prepared(cfg.data.prepared), cfg.data.split)
    windows = build_windows(cfg, cfg.eval.split, cfg.eval.stride, prepared).as_array()
    report = evaluate_predictors(
        windows,
        {name: predictor},
        loss_skeleton(cfg.loss),
        n_past=cfg.model.n_past,
        fps=float(prepared.fps),
        split=cfg.eval.split,
        batch_size=cfg.eval.batch_size,
    )
    result = {**report.to_dict(), **extra}
    atomic_write_text(out_file, json.dumps(result, indent=1) + "\n")
    logger.info("%s split, %d windows; MPJPE [mm] per horizon:", cfg.eval.split, len(windows))
    logger.info("%-18s %s", "horizon [ms]", " ".join(f"{h:6.0f}" for h in report.horizons_ms))
    for method, m in report.methods.items():
        logger.info("%-18s %s", method, " ".join(f"{1000 * v:6.2f}" for v in m.mpjpe_m))
    logger.info("wrote %s", out_file)
    return result


def _device(name: str) -> torch.device:
    """``train.device`` as a torch device; a device this machine lacks is an InputError."""
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    device = torch.device(name)
    if device.type == "cuda":
        n = torch.cuda.device_count() if torch.cuda.is_available() else 0
        if (device.index or 0) >= n:
            raise InputError(f"train.device={name}: this machine has {n} CUDA device(s)")
    if device.type == "mps" and not torch.backends.mps.is_available():
        raise InputError(f"train.device={name}: MPS is not available on this machine")
    return device


def _restore_rng(ckpt: dict[str, Any], rank: int, path: Path, loader_gen: torch.Generator) -> None:
    states = ckpt.get("rng")
    if not isinstance(states, list) or rank >= len(states):
        raise CheckpointError(f"checkpoint {path}: no random-generator state for rank {rank}")
    try:
        restore_rng_state(states[rank], loader_gen)
    except ValueError as exc:
        raise CheckpointError(f"checkpoint {path}: {exc}") from exc


def main(args: argparse.Namespace) -> int:
    """Train (or ``--eval-only``). Every input is checked before the run folder is touched."""
    info = init_distributed()
    cfg = load_config(PredictorTrainingConfig, args.config, args.overrides)
    run_dir = cfg.run_dir
    device = _device(cfg.train.device)
    if cfg.train.num_threads > 0:
        torch.set_num_threads(cfg.train.num_threads)

    if args.eval_only:
        setup_logging(info.rank)
        if info.is_main:
            return eval_only(cfg, args, device)
        return 0
    if args.onnx is not None or args.out is not None:
        raise InputError("--onnx and --out only go with --eval-only")

    ckpt, ckpt_path, init = None, None, None
    if args.init is not None:  # fine-tuning: weights (and architecture) only, a fresh run
        if args.resume or args.checkpoint is not None:
            raise InputError("--init starts a fresh run: it excludes --resume and --checkpoint")
        init = load_checkpoint(args.init)
        cfg = with_checkpoint_model(cfg, init, args.init, PredictorConfig, ARCH)
    if args.resume:
        ckpt_path = run_dir / "last.pt" if args.checkpoint is None else Path(args.checkpoint)
        ckpt = load_checkpoint(ckpt_path)
        cfg = with_checkpoint_model(cfg, ckpt, ckpt_path, PredictorConfig, ARCH)
    elif args.checkpoint is not None:
        raise InputError("--checkpoint goes with --resume or --eval-only")
    elif (run_dir / "last.pt").exists():
        raise InputError(
            f"{run_dir} already holds a checkpoint; pass --resume to continue it, or choose "
            "another run name (name=...)"
        )
    if info.world_size > cfg.train.batch_size:
        raise InputError(
            f"train.batch_size={cfg.train.batch_size} is smaller than the {info.world_size} "
            "processes: each needs at least one window per step"
        )

    seed_everything(cfg.train.seed, info.rank)
    loader_gen = torch.Generator().manual_seed(cfg.train.seed + info.rank)
    prepared = prepared_with_split(load_prepared(cfg.data.prepared), cfg.data.split)
    prepared = augmented(prepared, cfg.augment)
    skeletons = clip_skeletons(prepared, cfg.loss)
    train_ds = build_windows(
        cfg, "train", cfg.data.train_stride, prepared, skeletons, cfg.data.dataset_train_stride
    )
    val_ds = build_windows(cfg, "val", cfg.data.eval_stride, prepared, skeletons)
    train_sampler = DistributedSampler(
        train_ds, info.world_size, info.rank, shuffle=True, seed=cfg.train.seed, drop_last=True
    )
    val_sampler = DistributedSampler(val_ds, info.world_size, info.rank, shuffle=False)
    per_rank_batch = cfg.train.batch_size // info.world_size
    if len(train_sampler) < per_rank_batch:
        raise InputError(
            f"train.batch_size={cfg.train.batch_size} exceeds the {len(train_ds)} training "
            f"windows of {cfg.data.prepared}: not one full batch per epoch (lower "
            "train.batch_size or data.train_stride)"
        )
    train_loader = DataLoader(
        train_ds, per_rank_batch, sampler=train_sampler, drop_last=True,
        num_workers=cfg.data.num_workers, generator=loader_gen,
    )  # fmt: skip
    val_loader = DataLoader(
        val_ds, cfg.train.eval_batch_size, sampler=val_sampler, num_workers=cfg.data.num_workers
    )
    model = DCTGCN(cfg.model).to(device)
    model_without_ddp = model
    optimizer = torch.optim.Adam(
        model_without_ddp.parameters(), lr=cfg.optim.lr, weight_decay=cfg.optim.weight_decay
    )
    scheduler = torch.optim.lr_scheduler.StepLR(
        optimizer, step_size=cfg.optim.lr_step_epochs, gamma=cfg.optim.lr_gamma
    )
    start_epoch, best_metric, best_epoch = 0, math.inf, -1
    if init is not None:
        load_state(model_without_ddp, init["model"], args.init, "model")
    if ckpt is not None:
        load_state(model_without_ddp, ckpt["model"], ckpt_path, "model")
        load_state(optimizer, ckpt["optimizer"], ckpt_path, "optimizer")
        load_state(scheduler, ckpt["scheduler"], ckpt_path, "scheduler")
        _restore_rng(ckpt, info.rank, ckpt_path, loader_gen)
        start_epoch = int(ckpt["epoch"]) + 1
        best_metric, best_epoch = float(ckpt["best_metric"]), int(ckpt["best_epoch"])
    if info.distributed:
        ids = [info.local_rank] if device.type == "cuda" else None
        model = torch.nn.parallel.DistributedDataParallel(model, device_ids=ids)

    # Every input is valid: from here on the run folder is written.
    setup_logging(info.rank, run_dir)
    logger.info("run %s on %s (%d process(es), %d threads)", run_dir, device,
                info.world_size, torch.get_num_threads())  # fmt: skip
    logger.info("windows: %d train (stride %d%s), %d val (stride %d) from %s",
                len(train_ds), cfg.data.train_stride,
                "".join(f", {k} {v}" for k, v in cfg.data.dataset_train_stride.items()),
                len(val_ds), cfg.data.eval_stride, cfg.data.prepared)  # fmt: skip
    n_params = sum(p.numel() for p in model_without_ddp.parameters())
    logger.info("DCTGCN %s: %d parameters", cfg.model, n_params)
    if init is not None:
        logger.info("initialised from the weights of %s (epoch %d)", args.init, int(init["epoch"]))
    if ckpt is not None:
        logger.info("resumed from epoch %d (best %.5f at epoch %d)", start_epoch - 1,
                    best_metric, best_epoch)  # fmt: skip

    metrics = None
    if info.is_main:
        atomic_write_text(run_dir / "config.yaml", dump_config(cfg))
        metrics = MetricsLogger(
            run_dir, METRICS, start_epoch=start_epoch, tensorboard=cfg.train.tensorboard
        )
    commit = git_hash()
    try:
        for epoch in range(start_epoch, cfg.train.epochs):
            t0 = time.perf_counter()
            train_sampler.set_epoch(epoch)
            lr = optimizer.param_groups[0]["lr"]
            stats = train_one_epoch(
                model, optimizer, train_loader, cfg, epoch, device, info.is_main
            )
            scheduler.step()
            stats.update(evaluate(model_without_ddp, val_loader, cfg, device))
            stats.update({"lr": lr, "time/epoch_s": time.perf_counter() - t0})
            require_finite(stats, f"epoch {epoch}")
            is_best = stats["val/mpjpe_m"] < best_metric
            if is_best:
                best_metric, best_epoch = stats["val/mpjpe_m"], epoch
            # Every rank's generator states, so each resumes its own streams.
            rng = [rng_state(loader_gen)]
            if info.distributed:
                rng = [None] * info.world_size
                torch.distributed.all_gather_object(rng, rng_state(loader_gen))
            logger.info(
                "epoch %d/%d lr %.3g train loss %.5f | val MPJPE %.2f mm (@%d ms %.2f mm) MAE "
                "%.4f rad%s | %.0f s", epoch, cfg.train.epochs - 1, lr, stats["train/loss"],
                1000 * stats["val/mpjpe_m"], round(1000 * cfg.model.n_future / prepared.fps),
                1000 * stats["val/mpjpe_last_m"], stats["val/mae_rad"],
                " *best*" if is_best else "", stats["time/epoch_s"],
            )  # fmt: skip
            if info.is_main:
                metrics.log(epoch, stats)
                state = {
                    "model": model_without_ddp.state_dict(),
                    "optimizer": optimizer.state_dict(),
                    "scheduler": scheduler.state_dict(),
                    "epoch": epoch,
                    "best_metric": best_metric,
                    "best_epoch": best_epoch,
                    "config": config_to_dict(cfg),
                    "git_hash": commit,
                    "rng": rng,
                    "fps": float(prepared.fps),
                    "val": stats,
                }
                save_checkpoint(state, run_dir / "last.pt")
                if is_best:
                    save_checkpoint(state, run_dir / "best.pt")
    finally:
        if metrics is not None:
            metrics.close()
    barrier()
    if info.is_main and not args.no_final_eval:
        best = load_checkpoint(run_dir / "best.pt")
        load_state(model_without_ddp, best["model"], run_dir / "best.pt", "model")
        final_evaluation(
            cfg,
            torch_predictor(model_without_ddp, device=device, batch_size=cfg.eval.batch_size),
            "gcn",
            run_dir / "eval.json",
            {"checkpoint": str(run_dir / "best.pt"), "epoch": int(best["epoch"]),
             "val_mpjpe_m": float(best["best_metric"]), "config": config_to_dict(cfg)},
        )  # fmt: skip
    barrier()
    return 0


def eval_only(cfg: PredictorTrainingConfig, args: argparse.Namespace, device: torch.device) -> int:
    """``--eval-only``: evaluate a checkpoint (architecture from it) or an ONNX file."""
    if (args.checkpoint is None) == (args.onnx is None):
        raise InputError("--eval-only needs exactly one of --checkpoint or --onnx")
    if args.resume or args.init is not None:
        raise InputError("--resume and --init do not go with --eval-only")
    extra = {"config": config_to_dict(cfg)}
    if args.checkpoint is not None:
        ckpt = load_checkpoint(args.checkpoint)
        cfg = with_checkpoint_model(cfg, ckpt, args.checkpoint, PredictorConfig, ARCH)
        model = DCTGCN(cfg.model).to(device)
        load_state(model, ckpt["model"], args.checkpoint, "model")
        predictor = torch_predictor(model, device=device, batch_size=cfg.eval.batch_size)
        source = Path(args.checkpoint)
        extra.update(checkpoint=str(source), epoch=int(ckpt["epoch"]), config=config_to_dict(cfg))
    else:
        from gaitnet.motion.onnx_runtime import OnnxPredictor

        source = Path(args.onnx)
        predictor = onnx_predictor(OnnxPredictor(source, threads=max(1, torch.get_num_threads())))
        extra.update(onnx=str(source))
    out = Path(args.out) if args.out else source.with_name(f"eval_{source.stem}.json")
    final_evaluation(cfg, predictor, "gcn", out, extra)
    return 0


def get_args_parser() -> argparse.ArgumentParser:
    parser = ScriptParser(prog="train/predictor.py", description=__doc__.splitlines()[0])
    parser.add_argument("--config", required=True, help="YAML config (configs/predictor/)")
    parser.add_argument(
        "--resume",
        action="store_true",
        help="continue from <run_dir>/last.pt (or --checkpoint); the whole state is restored",
    )
    parser.add_argument(
        "--init",
        help="fine-tune: start a fresh run (epoch 0, new optimizer) from this checkpoint's "
        "weights; model.* keys come from it",
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
