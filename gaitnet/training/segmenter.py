"""Typed training config, optimiser and metrics of the foot/leg segmenter (sec. 4.1).

:class:`SegmenterTrainingConfig` is what ``configs/segmenter/*.yaml`` hold (every key in
``docs/configs.md``, *Segmenter training*); ``train/segmenter.py`` reads it with
:func:`gaitnet.config.load_config`.

Data sets (built by :mod:`gaitnet.training.segmenter_data`) are named by a path
(:func:`~gaitnet.training.segmenter_data.resolve_set`): a split file (text, one frame id per
line, :func:`gaitnet.segmentation.folder_files.read_split`) whose frames lie in the file's folder,
or a folder (every frame in it). Such a folder is a ``gaitnet simulate-dataset`` output or a
labelme folder (``data/README.md``); :class:`~gaitnet.segmentation.dataset.SegmentationFolder`
reads it. The HHA encoding is always :class:`~gaitnet.segmentation.hha.HhaParams`'s defaults,
the encoding ``gaitnet segment`` and the ONNX model's users compute.

Training (thesis sec. 4.1.3): the softmax focal loss (:class:`~gaitnet.segmentation.
focal_loss.FocalLoss`, per-class ``alpha``, ``gamma``, ignore label 255) averaged over labelled
pixels; SGD with momentum (the FCN authors' and the thesis's optimiser) or Adam; the learning
rate follows a schedule stepped once per batch (``poly``: ``lr·(1 − i/N)^power`` over the
``N`` batches of the run, as DeepLab; ``step``: ×``step_gamma`` every ``step_epochs`` epochs;
``constant``). Model selection and the final report use the three metrics of the thesis
(:mod:`gaitnet.evaluation.segmentation`: pixel accuracy, mean IoU, frequency-weighted IoU) and
per-class IoU from one confusion matrix accumulated over a whole set.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Literal

import numpy as np
import torch

from gaitnet.checks import check_int_range, check_range
from gaitnet.errors import ConfigError
from gaitnet.evaluation.segmentation import confusion_matrix, segmentation_scores
from gaitnet.segmentation.augment import AugmentParams
from gaitnet.segmentation.channels import ARCHS
from gaitnet.segmentation.fcn import PADDINGS, check_output_stride
from gaitnet.segmentation.focal_loss import FocalLoss
from gaitnet.segmentation.segmenter_net import (
    SegmenterNet,
    build_segmenter,
    check_logit_bias,
    segmenter_from_checkpoint,
)
from gaitnet.training.checkpoint import load_checkpoint
from gaitnet.training.checkpoint import with_checkpoint_model as checkpoint_model
from gaitnet.training.onnx_weights import segmenter_from_onnx
from gaitnet.training.predictor import DEVICE_PATTERN
from gaitnet.training.segmenter_data import set_name

__all__ = [
    "CLASS_NAMES",
    "DataConfig",
    "EvalConfig",
    "LossConfig",
    "ModelConfig",
    "OptimConfig",
    "SegmenterTrainingConfig",
    "TrainConfig",
    "architecture_only",
    "with_checkpoint_model",
    "build_loss",
    "build_model",
    "build_optimizer",
    "build_scheduler",
    "confusion_of",
    "scores_of",
    "start_from_checkpoint",
]

logger = logging.getLogger(__name__)

#: Label values 0, 1, 2 (docs/design.md, *Conventions*); 255 is ignored.
CLASS_NAMES: tuple[str, ...] = ("background", "foot", "leg")
_MAX_BATCH = 1 << 16


@dataclass(frozen=True)
class DataConfig:
    """Training and validation sets (split files or folders), augmentation, loading."""

    train: Path = Path("data/cache/seg/train/train.txt")
    val: Path = Path("data/cache/seg/val/val.txt")
    train_extra: tuple[Path, ...] = ()
    augment: AugmentParams | None = field(default_factory=AugmentParams)
    cache_hha: bool = True
    num_workers: int = 0

    def __post_init__(self) -> None:
        for name in ("train", "val"):
            if not str(getattr(self, name)).strip():
                raise ValueError(f"data.{name} must name a split file or a folder")
        check_int_range("data.num_workers", self.num_workers, 0, 256)

    @property
    def train_sets(self) -> tuple[Path, ...]:
        """Every training set: ``train``, then ``train_extra``."""
        return (self.train, *self.train_extra)


@dataclass(frozen=True)
class ModelConfig:
    """The net (:func:`gaitnet.segmentation.segmenter_net.build_segmenter`)."""

    arch: Literal["rgb", "hha", "fusion"] = "fusion"
    width: float = 1.0
    input_scale: float = 1.0
    num_classes: int = 3
    vgg16_weights: Path | None = None
    padding: Literal["published", "same"] = "published"
    output_stride: int = 8
    init_checkpoint: Path | None = None
    logit_bias: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        if self.arch not in ARCHS:
            raise ValueError(f"model.arch must be one of {ARCHS}, got {self.arch!r}")
        if self.padding not in PADDINGS:
            raise ValueError(f"model.padding must be one of {PADDINGS}, got {self.padding!r}")
        check_range("model.width", self.width, 1e-3, 1.0)
        check_range("model.input_scale", self.input_scale, 0.05, 1.0)
        check_int_range("model.num_classes", self.num_classes, 2, 255)
        try:
            check_output_stride(self.output_stride, "model.output_stride")
            check_logit_bias(self.logit_bias, self.num_classes, "model.logit_bias")
        except ConfigError as exc:
            raise ValueError(str(exc)) from exc
        if self.vgg16_weights is not None and self.width != 1.0:
            raise ValueError(
                "model.vgg16_weights needs model.width 1 (ImageNet weights fit the published "
                f"width only), got width {self.width:g}"
            )
        if self.vgg16_weights is not None and self.init_checkpoint is not None:
            raise ValueError(
                "model.vgg16_weights and model.init_checkpoint exclude each other (both "
                "initialise the net)"
            )


@dataclass(frozen=True)
class LossConfig:
    """Softmax focal loss (Lin et al. 2017; thesis sec. 4.1.3)."""

    alpha: tuple[float, ...] | None = None
    gamma: float = 2.0
    ignore_index: int = 255

    def __post_init__(self) -> None:
        if self.alpha is not None:
            if not self.alpha:
                raise ValueError("loss.alpha must list one weight per class (or be null)")
            for a in self.alpha:
                check_range("loss.alpha", a, 0.0, 1e3)
            if sum(self.alpha) <= 0:
                raise ValueError("loss.alpha must not be all zero")
        check_range("loss.gamma", self.gamma, 0.0, 10.0)
        check_int_range("loss.ignore_index", self.ignore_index, 0, 255)


@dataclass(frozen=True)
class OptimConfig:
    """Optimiser and learning-rate schedule (stepped once per batch)."""

    name: Literal["sgd", "adam"] = "sgd"
    lr: float = 1e-3
    momentum: float = 0.9
    weight_decay: float = 5e-4
    schedule: Literal["poly", "step", "constant"] = "poly"
    poly_power: float = 0.9
    step_epochs: int = 10
    step_gamma: float = 0.1
    grad_clip_norm: float = 0.0

    def __post_init__(self) -> None:
        check_range("optim.lr", self.lr, 0.0, 10.0)
        if self.lr == 0:
            raise ValueError("optim.lr must be > 0")
        check_range("optim.momentum", self.momentum, 0.0, 0.999)
        check_range("optim.weight_decay", self.weight_decay, 0.0, 1.0)
        check_range("optim.poly_power", self.poly_power, 0.0, 10.0)
        check_int_range("optim.step_epochs", self.step_epochs, 1, 1_000_000)
        check_range("optim.step_gamma", self.step_gamma, 1e-6, 1.0)
        check_range("optim.grad_clip_norm (0 disables clipping)", self.grad_clip_norm, 0.0)


@dataclass(frozen=True)
class TrainConfig:
    """Loop settings."""

    epochs: int = 30
    batch_size: int = 8
    eval_batch_size: int = 8
    seed: int = 0
    num_threads: int = 0
    device: str = "auto"
    tensorboard: bool = True
    checkpoint_every: int = 0
    max_steps_per_epoch: int = 0

    def __post_init__(self) -> None:
        check_int_range("train.epochs", self.epochs, 1, 1_000_000)
        check_int_range("train.batch_size", self.batch_size, 1, _MAX_BATCH)
        check_int_range("train.eval_batch_size", self.eval_batch_size, 1, _MAX_BATCH)
        check_int_range("train.seed", self.seed, 0, 2**32 - 1)
        check_int_range("train.num_threads (0: torch's default)", self.num_threads, 0, 1024)
        if not isinstance(self.device, str) or not DEVICE_PATTERN.match(self.device):
            raise ValueError(
                f"train.device must be auto, cpu, cuda, cuda:N or mps, got {self.device!r}"
            )
        check_int_range("train.checkpoint_every (0: at epoch ends only)", self.checkpoint_every,
                        0, 1_000_000_000)  # fmt: skip
        check_int_range("train.max_steps_per_epoch (0: the whole set)", self.max_steps_per_epoch,
                        0, 1_000_000_000)  # fmt: skip


@dataclass(frozen=True)
class EvalConfig:
    """Final evaluation (``eval.json``) of ``best.pt`` on each set (split file or folder)."""

    sets: tuple[Path, ...] = (
        Path("data/cache/seg/test/test.txt"),
        Path("data/cache/seg/heldout/heldout.txt"),
    )
    batch_size: int = 4

    def __post_init__(self) -> None:
        check_int_range("eval.batch_size", self.batch_size, 1, _MAX_BATCH)
        names = [set_name(p) for p in self.sets]
        if len(set(names)) != len(names):
            raise ValueError(f"eval.sets must have distinct names (file stems), got {names}")


@dataclass(frozen=True)
class SegmenterTrainingConfig:
    """A segmenter training run: ``<output_dir>/<name>/`` holds its outputs."""

    name: str
    output_dir: Path = Path("runs/segmenter")
    data: DataConfig = field(default_factory=DataConfig)
    model: ModelConfig = field(default_factory=ModelConfig)
    loss: LossConfig = field(default_factory=LossConfig)
    optim: OptimConfig = field(default_factory=OptimConfig)
    train: TrainConfig = field(default_factory=TrainConfig)
    eval: EvalConfig = field(default_factory=EvalConfig)

    def __post_init__(self) -> None:
        if (
            not isinstance(self.name, str)
            or not self.name.strip()
            or len(self.name) > 200
            or any(c in self.name for c in "/\\\0")
            or self.name.startswith(".")
        ):
            raise ValueError(f"name must be a plain folder name, got {self.name!r}")
        if self.loss.alpha is not None and len(self.loss.alpha) != self.model.num_classes:
            raise ValueError(
                f"loss.alpha has {len(self.loss.alpha)} weights, model.num_classes is "
                f"{self.model.num_classes}"
            )
        if self.loss.ignore_index < self.model.num_classes:
            raise ValueError(
                f"loss.ignore_index {self.loss.ignore_index} is a class label "
                f"(model.num_classes {self.model.num_classes})"
            )

    @property
    def run_dir(self) -> Path:
        return self.output_dir / self.name


# --------------------------------------------------------------------------- model, optim


def build_model(cfg: ModelConfig) -> SegmenterNet:
    """The net of ``cfg``: VGG16 ImageNet initialisation from ``vgg16_weights``, or the
    matching layers of a trained segmenter from ``init_checkpoint``, if given."""
    net = build_segmenter(
        cfg.arch,
        width=cfg.width,
        num_classes=cfg.num_classes,
        input_scale=cfg.input_scale,
        vgg16_weights=cfg.vgg16_weights,
        padding=cfg.padding,
        output_stride=cfg.output_stride,
        logit_bias=cfg.logit_bias,
    )
    if cfg.init_checkpoint is not None:
        new = start_from_checkpoint(net, cfg.init_checkpoint)
        logger.info("started from %s; new layers: %s", cfg.init_checkpoint, ", ".join(new))
    return net


def with_checkpoint_model(
    cfg: SegmenterTrainingConfig, ckpt: dict[str, Any], path: Path
) -> SegmenterTrainingConfig:
    """``cfg`` with the segmenter architecture of the checkpoint ``ckpt`` read from ``path``
    (:func:`gaitnet.training.checkpoint.with_checkpoint_model`)."""
    return checkpoint_model(cfg, ckpt, path, ModelConfig, "segmenter architecture")


def architecture_only(cfg: ModelConfig) -> ModelConfig:
    """``cfg`` without its initialisation keys: the net a checkpoint's weights then fill."""
    return replace(cfg, vgg16_weights=None, init_checkpoint=None)


def start_from_checkpoint(net: SegmenterNet, path: Path) -> list[str]:
    """Copy every tensor of a trained segmenter checkpoint whose name and shape match into
    ``net``; the rest keep their initialisation (their names are returned). This is the FCN
    authors' staged training (FCN-16s started from FCN-32s, FCN-8s from FCN-16s): a net with a
    finer ``output_stride`` starts from a coarser one, its new score layers at zero. The
    checkpoint's arch, width, padding and classes must be ``net``'s. A segmenter ONNX export
    (``.onnx``, e.g. the committed model) serves as well: its weights are read back from the
    graph (:func:`~gaitnet.training.onnx_weights.segmenter_from_onnx`), for fine-tuning."""
    if Path(path).suffix.lower() == ".onnx":
        source = segmenter_from_onnx(path)
    else:
        source = segmenter_from_checkpoint(load_checkpoint(path), str(path))
    theirs, ours = source.config(), net.config()
    for key in ("arch", "width", "padding", "num_classes"):
        if theirs[key] != ours[key]:
            raise ConfigError(
                f"model.init_checkpoint {path}: its model.{key} is {theirs[key]!r}, this "
                f"config's is {ours[key]!r}"
            )
    own = net.state_dict()
    copied = {k: v for k, v in source.state_dict().items() if k in own and v.shape == own[k].shape}
    net.load_state_dict({**own, **copied})
    return [k for k in own if k not in copied]


def build_loss(cfg: LossConfig) -> FocalLoss:
    return FocalLoss(alpha=cfg.alpha, gamma=cfg.gamma, ignore_index=cfg.ignore_index)


def build_optimizer(params: Any, cfg: OptimConfig) -> torch.optim.Optimizer:
    if cfg.name == "sgd":
        return torch.optim.SGD(
            params, lr=cfg.lr, momentum=cfg.momentum, weight_decay=cfg.weight_decay
        )
    return torch.optim.Adam(
        params, lr=cfg.lr, betas=(cfg.momentum, 0.999), weight_decay=cfg.weight_decay
    )


def build_scheduler(
    optimizer: torch.optim.Optimizer, cfg: OptimConfig, epochs: int, steps_per_epoch: int
) -> torch.optim.lr_scheduler.LRScheduler:
    """The per-batch schedule of ``cfg.schedule`` over ``epochs × steps_per_epoch`` batches."""
    total = max(1, epochs * steps_per_epoch)
    if cfg.schedule == "poly":
        return torch.optim.lr_scheduler.PolynomialLR(
            optimizer, total_iters=total, power=cfg.poly_power
        )
    if cfg.schedule == "step":
        return torch.optim.lr_scheduler.StepLR(
            optimizer, step_size=cfg.step_epochs * max(1, steps_per_epoch), gamma=cfg.step_gamma
        )
    return torch.optim.lr_scheduler.ConstantLR(optimizer, factor=1.0, total_iters=0)


# -------------------------------------------------------------------------------- metrics


def confusion_of(
    logits: torch.Tensor, target: torch.Tensor, num_classes: int, ignore_index: int
) -> torch.Tensor:
    """(C, C) int64 confusion matrix [true, predicted] of one batch (argmax of ``logits``)."""
    pred = logits.argmax(dim=1).cpu().numpy()
    conf = confusion_matrix(pred, target.cpu().numpy(), num_classes, ignore_index=ignore_index)
    return torch.from_numpy(np.asarray(conf, dtype=np.int64))


def scores_of(conf: torch.Tensor | np.ndarray, class_names: Sequence[str] | None = None) -> dict:
    """Pixel accuracy, mIoU, FW-IoU, per-class IoU (:func:`~gaitnet.evaluation.segmentation.
    segmentation_scores`; class names default to :data:`CLASS_NAMES` for 3 classes) and the
    confusion matrix ``[true][predicted]`` itself, as plain data."""
    matrix = np.asarray(conf, dtype=np.int64)
    if class_names is None and matrix.shape[0] == len(CLASS_NAMES):
        class_names = CLASS_NAMES
    out = {k: _plain(v) for k, v in segmentation_scores(matrix, class_names).items()}
    out["confusion"] = matrix.tolist()
    return out


def _plain(value: Any) -> Any:
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, (np.floating, float)):
        v = float(value)
        return v if math.isfinite(v) else None
    if isinstance(value, np.integer):
        return int(value)
    return value
