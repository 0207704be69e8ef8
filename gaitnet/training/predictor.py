"""Typed training config and data of the DCT-GCN motion predictor (thesis sec. 4.2).

:class:`PredictorTrainingConfig` is what ``configs/predictor/*.yaml`` hold (every key is
documented in ``docs/predictor.md``); ``train/predictor.py`` reads it with
:func:`gaitnet.config.load_config`. The defaults are the thesis's / LTD's training settings:
Adam 5e-4, ×0.96 every 2 epochs (StepLR), batch 32, 50 epochs, gradient-norm clip 1 (LTD),
10 past → 10 future poses at 30 fps, DCT depth 20, hidden 256, 12 blocks, dropout 0.5.

Data: a prepared file of :func:`gaitnet.motion.prepared.prepare_walking_subset` (from AMASS or
from the simulator's synthetic AMASS-format clips). The split mapping is a config
value (``data.split``, a :class:`~gaitnet.motion.amass.DatasetSplit`): when given, each
clip's split is recomputed from its sub-dataset, otherwise the split stored in the file is
used. Windows are heading-normalised (:class:`~gaitnet.motion.windows.WalkingWindows`) and, with
``data.preload``, materialised once as one float32 tensor.

Skeleton: with ``loss.per_clip_skeleton`` (default) the MPJPE term (eq. 4.5) of training and
validation uses each clip's own skeleton (:func:`clip_skeletons`): the rest joints stored in
the clip (the synthetic clips carry them), else the body model's skeleton of the clip's betas
when ``loss.body_model`` names an SMPL-family file, else the built-in skeleton of
``loss.skeleton_height_m``. The final per-horizon evaluation (``eval.json``) uses ONE skeleton
for every clip (:func:`loss_skeleton`: the body model's mean shape or the built-in one), as
LTD/HisRepItself use SMPL's mean shape on AMASS, so that numbers stay comparable between data
sets and with the baselines.

Augmentation (``augment.*``, training split only): mirror images and time-scaled copies of
the training clips (:mod:`gaitnet.motion.augment`), and Gaussian noise on the observed input
poses (``train/predictor.py``).
"""

from __future__ import annotations

import logging
import re
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Literal

import numpy as np
import torch
from torch.utils.data import Dataset

from gaitnet.checks import check_int_range, check_range
from gaitnet.motion.amass import DatasetSplit
from gaitnet.motion.augment import augment_split
from gaitnet.motion.gcn import DCTGCN, NODE_JOINTS, PredictorConfig
from gaitnet.motion.losses import baseline_window_weights
from gaitnet.motion.prepared import PreparedWalking, load_prepared
from gaitnet.motion.skeleton import LowerBodySkeleton, builtin_skeleton
from gaitnet.motion.windows import WalkingWindows

__all__ = [
    "AugmentConfig",
    "DataConfig",
    "EvalConfig",
    "LossConfig",
    "OptimConfig",
    "PoseWindows",
    "PredictorTrainingConfig",
    "TrainConfig",
    "augmented",
    "build_windows",
    "clip_skeletons",
    "loss_skeleton",
    "prepared_with_split",
    "window_weights",
]

logger = logging.getLogger(__name__)
SplitName = Literal["train", "val", "test"]
#: ``train.device`` values: ``auto``, ``cpu``, ``cuda``, ``cuda:N``, ``mps``.
DEVICE_PATTERN = re.compile(r"^(auto|cpu|mps|cuda(:\d{1,3})?)$")
_MAX_BATCH = 1 << 20


@dataclass(frozen=True)
class DataConfig:
    """Prepared walking file, split mapping and windowing."""

    prepared: Path = Path("data/cache/synthwalk_walking.npz")
    split: DatasetSplit | None = None
    train_stride: int = 2
    #: training-window stride per sub-dataset (case-insensitive name → stride), overriding
    #: ``train_stride`` for that sub-dataset's clips: a smaller stride weights a small data set
    #: (e.g. a few real walks beside many synthetic ones) up by giving it more windows.
    dataset_train_stride: dict[str, int] = field(default_factory=dict)
    eval_stride: int = 5
    normalise_heading: bool = True
    preload: bool = True
    num_workers: int = 0

    def __post_init__(self) -> None:
        if not str(self.prepared).strip():
            raise ValueError("data.prepared must name the prepared walking file")
        check_int_range("data.train_stride", self.train_stride, 1, 100_000)
        for name, stride in self.dataset_train_stride.items():
            if not isinstance(name, str) or not name.strip():
                raise ValueError(f"data.dataset_train_stride: {name!r} is not a sub-dataset name")
            check_int_range(f"data.dataset_train_stride.{name}", stride, 1, 100_000)
        check_int_range("data.eval_stride", self.eval_stride, 1, 100_000)
        check_int_range("data.num_workers", self.num_workers, 0, 256)


@dataclass(frozen=True)
class LossConfig:
    """``loss = w_mpjpe · MPJPE (4.5, m) + w_mae · MAE (4.6, rad)``, the FK skeleton and the
    window weights: with ``window_normalisation: baseline`` each window's loss is divided by
    ``e_b + normalisation_eps_m`` (times ``normalisation_eps_m``), ``e_b`` the MPJPE of the
    model's padding guess over its predicted frames (:func:`window_weights`)."""

    w_mpjpe: float = 1.0
    w_mae: float = 0.1
    skeleton_height_m: float = 1.75
    body_model: Path | None = None
    body_model_gender: str = "neutral"
    per_clip_skeleton: bool = True
    window_normalisation: Literal["none", "baseline"] = "none"
    normalisation_eps_m: float = 0.01

    def __post_init__(self) -> None:
        if self.window_normalisation not in ("none", "baseline"):
            raise ValueError(
                "loss.window_normalisation must be 'none' or 'baseline', "
                f"got {self.window_normalisation!r}"
            )
        check_range("loss.normalisation_eps_m", self.normalisation_eps_m, 1e-6, 1.0)
        check_range("loss.w_mpjpe", self.w_mpjpe, 0.0, 1e6)
        check_range("loss.w_mae", self.w_mae, 0.0, 1e6)
        if self.w_mpjpe + self.w_mae <= 0:
            raise ValueError("loss.w_mpjpe and loss.w_mae must not both be zero")
        check_range("loss.skeleton_height_m", self.skeleton_height_m, 0.5, 2.5)
        if self.body_model_gender not in ("neutral", "male", "female"):
            raise ValueError(
                "loss.body_model_gender must be 'neutral', 'male' or 'female', "
                f"got {self.body_model_gender!r}"
            )


@dataclass(frozen=True)
class AugmentConfig:
    """Training-split augmentation (:mod:`gaitnet.motion.augment`): mirror images, copies played
    at each factor of ``time_scales``, Gaussian noise of ``input_noise_rad`` (per component) on
    the observed input poses."""

    mirror: bool = False
    time_scales: tuple[float, ...] = ()
    input_noise_rad: float = 0.0

    def __post_init__(self) -> None:
        for f in self.time_scales:
            check_range("augment.time_scales", f, 0.25, 4.0)
        if len(self.time_scales) > 16:
            raise ValueError("augment.time_scales: at most 16 factors")
        check_range("augment.input_noise_rad", self.input_noise_rad, 0.0, 0.5)


@dataclass(frozen=True)
class OptimConfig:
    """Adam with a step decay (thesis: 5e-4, ×0.96 every 2 epochs) and gradient clipping."""

    lr: float = 5e-4
    weight_decay: float = 0.0
    lr_step_epochs: int = 2
    lr_gamma: float = 0.96
    grad_clip_norm: float = 1.0

    def __post_init__(self) -> None:
        check_range("optim.lr", self.lr, 0.0, 10.0)
        if self.lr == 0:
            raise ValueError("optim.lr must be > 0")
        check_range("optim.weight_decay", self.weight_decay, 0.0, 10.0)
        check_int_range("optim.lr_step_epochs", self.lr_step_epochs, 1, 1_000_000)
        check_range("optim.lr_gamma", self.lr_gamma, 0.0, 1.0)
        if self.lr_gamma == 0:
            raise ValueError("optim.lr_gamma must be > 0")
        check_range("optim.grad_clip_norm (0 disables clipping)", self.grad_clip_norm, 0.0)


@dataclass(frozen=True)
class TrainConfig:
    """Loop settings."""

    epochs: int = 50
    batch_size: int = 32
    eval_batch_size: int = 512
    seed: int = 0
    num_threads: int = 0
    device: str = "auto"
    tensorboard: bool = True

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


@dataclass(frozen=True)
class EvalConfig:
    """Final evaluation (``eval.json``) after training: split and window stride."""

    split: SplitName = "test"
    stride: int = 1
    batch_size: int = 2048

    def __post_init__(self) -> None:
        check_int_range("eval.stride", self.stride, 1, 100_000)
        check_int_range("eval.batch_size", self.batch_size, 1, _MAX_BATCH)


@dataclass(frozen=True)
class PredictorTrainingConfig:
    """A predictor training run: ``<output_dir>/<name>/`` holds its outputs."""

    name: str
    output_dir: Path = Path("runs/predictor")
    data: DataConfig = field(default_factory=DataConfig)
    model: PredictorConfig = field(default_factory=PredictorConfig)
    loss: LossConfig = field(default_factory=LossConfig)
    augment: AugmentConfig = field(default_factory=AugmentConfig)
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
        if self.model.n_nodes != 3 * len(NODE_JOINTS):
            raise ValueError(
                f"model.n_nodes must be {3 * len(NODE_JOINTS)} (7 joints × 3 axis-angle "
                f"components), got {self.model.n_nodes}"
            )

    @property
    def run_dir(self) -> Path:
        return self.output_dir / self.name


def prepared_with_split(prepared: PreparedWalking, split: DatasetSplit | None) -> PreparedWalking:
    """``prepared`` with each clip's split recomputed from its sub-dataset by ``split``."""
    if split is None:
        return prepared
    splits = np.array([split.split_of(str(d)) for d in prepared.clip_dataset], dtype=str)
    return replace(prepared, clip_split=splits)


class PoseWindows(Dataset):
    """Pose windows (W, 21) float32 tensors; preloaded into one tensor or served lazily.

    With ``skeletons`` (C, 9, 3) (one per clip, :func:`clip_skeletons`) item ``i`` is the pair
    ``(poses, rest_joints)`` of window ``i`` and its clip's skeleton; without, the poses only.
    """

    def __init__(
        self, windows: WalkingWindows, preload: bool, skeletons: np.ndarray | None = None
    ) -> None:
        self.windows = windows
        self.poses: torch.Tensor | None = None
        self.skeletons = None
        if skeletons is not None:
            self.skeletons = torch.as_tensor(np.asarray(skeletons), dtype=torch.float32)
            self.clip_of = torch.as_tensor(windows.index[:, 0])
        if preload:
            self.poses = torch.stack([windows[i]["poses"] for i in range(len(windows))])

    def __len__(self) -> int:
        return len(self.windows)

    def __getitem__(self, i: int) -> torch.Tensor | tuple[torch.Tensor, torch.Tensor]:
        poses = self.poses[i] if self.poses is not None else self.windows[i]["poses"]
        if self.skeletons is None:
            return poses
        return poses, self.skeletons[self.clip_of[i]]

    def as_array(self) -> np.ndarray:
        """All windows (N, W, 21) as a float64 array (for :mod:`gaitnet.motion.evaluation`)."""
        if self.poses is not None:
            return self.poses.numpy().astype(np.float64)
        return np.stack([self.windows[i]["poses"].numpy() for i in range(len(self))]).astype(
            np.float64
        )


def build_windows(
    cfg: PredictorTrainingConfig,
    split: SplitName,
    stride: int,
    prepared: PreparedWalking | None = None,
    skeletons: np.ndarray | None = None,
    dataset_stride: dict[str, int] | None = None,
) -> PoseWindows:
    """Windows of ``n_past + n_future`` frames of ``split`` from the configured prepared file;
    items are (poses, clip skeleton) pairs (:class:`PoseWindows`), ``skeletons`` (C, 9, 3)
    defaulting to :func:`clip_skeletons`; ``dataset_stride`` overrides ``stride`` per
    sub-dataset (:attr:`DataConfig.dataset_train_stride`)."""
    if prepared is None:
        prepared = prepared_with_split(load_prepared(cfg.data.prepared), cfg.data.split)
    if skeletons is None:
        skeletons = clip_skeletons(prepared, cfg.loss)
    windows = WalkingWindows(
        prepared,
        split,
        n_past=cfg.model.n_past,
        n_future=cfg.model.n_future,
        stride=stride,
        normalise_heading=cfg.data.normalise_heading,
        dataset_stride=dataset_stride,
    )
    logger.info(
        "%s: %d windows from %d clips (stride %d)",
        split,
        len(windows),
        int(np.sum(prepared.clip_split == split)),
        stride,
    )
    return PoseWindows(windows, cfg.data.preload, skeletons)


def loss_skeleton(cfg: LossConfig) -> LowerBodySkeleton:
    """The skeleton of the MPJPE term and of the evaluation (module docstring)."""
    if cfg.body_model is not None:
        from gaitnet.motion.body_model import lower_body_skeleton

        return lower_body_skeleton(cfg.body_model, cfg.body_model_gender)
    return builtin_skeleton(cfg.skeleton_height_m)


def clip_skeletons(prepared: PreparedWalking, cfg: LossConfig) -> np.ndarray:
    """Rest joints (C, 9, 3) of each clip's skeleton for the MPJPE loss (module docstring).

    Without ``per_clip_skeleton`` every row is :func:`loss_skeleton`.
    """
    common = loss_skeleton(cfg).rest_joints
    out = np.repeat(common[None], prepared.n_clips, axis=0)
    if not cfg.per_clip_skeleton:
        return out
    model = None
    if cfg.body_model is not None:
        from gaitnet.motion.body_model import load_shape_model

        model = load_shape_model(cfg.body_model, cfg.body_model_gender)
    for i in range(prepared.n_clips):
        own = prepared.rest_joints_of(i)
        if own is not None:
            out[i] = own
        elif model is not None:
            out[i] = model.skeleton(prepared.betas[i]).rest_joints
    return out


def augmented(prepared: PreparedWalking, cfg: AugmentConfig) -> PreparedWalking:
    """``prepared`` with the mirrored / time-scaled copies of its training clips appended."""
    if not cfg.mirror and not cfg.time_scales:
        return prepared
    out = augment_split(prepared, "train", mirror=cfg.mirror, time_scales=cfg.time_scales)
    logger.info(
        "augmentation: %d training clips → %d (mirror %s, time scales %s)",
        int(np.sum(prepared.clip_split == "train")),
        int(np.sum(out.clip_split == "train")),
        cfg.mirror,
        list(cfg.time_scales),
    )
    return out


def window_weights(
    cfg: LossConfig, model: DCTGCN, poses: torch.Tensor, skeleton: torch.Tensor
) -> torch.Tensor | None:
    """Per-window loss weights (B,) of ``loss.window_normalisation`` for (B, W, 21) windows, or
    None (``none``). ``baseline``: ``ε / (e_b + ε)``
    (:func:`gaitnet.motion.losses.baseline_window_weights`), ``e_b`` the MPJPE on the window's
    ``skeleton`` of ``model``'s padding guess (:meth:`DCTGCN.pad`, from the clean observed
    poses) over the predicted frames, ``ε = loss.normalisation_eps_m``."""
    if cfg.window_normalisation == "none":
        return None
    n_past = model.config.n_past
    guess = model.pad(poses[:, :n_past])[:, n_past:]
    return baseline_window_weights(guess, poses[:, n_past:], skeleton, cfg.normalisation_eps_m)
