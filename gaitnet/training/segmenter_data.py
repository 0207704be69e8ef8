"""The segmenter's data sets for training and evaluation (config ``data.*``, ``eval.sets``).

A set is named by a path (:func:`resolve_set`): a split file (text, one frame id per line,
:func:`gaitnet.segmentation.folder_files.read_split`) whose frames lie in the file's folder, or
a folder (all its frames), read by :class:`~gaitnet.segmentation.dataset.SegmentationFolder`;
the training set is ``data.train`` joined by ``data.train_extra`` (:func:`build_training_set`).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import torch

from gaitnet.errors import InputError
from gaitnet.segmentation.dataset import SegmentationFolder
from gaitnet.segmentation.folder_files import read_split
from gaitnet.segmentation.hha import hha_stride

if TYPE_CHECKING:
    from gaitnet.training.segmenter import SegmenterTrainingConfig

__all__ = ["TrainingSets", "build_dataset", "build_training_set", "resolve_set", "set_name"]


def set_name(path: Path) -> str:
    """A set's name in reports: the split file's stem, or the folder's name."""
    path = Path(path)
    return path.stem if path.suffix == ".txt" else path.name


def resolve_set(path: Path) -> tuple[Path, list[str] | None]:
    """``(folder, ids)`` of a set given as a split file (its frames lie beside it) or a folder
    (``ids`` None: every frame)."""
    path = Path(path)
    if path.is_dir():
        return path, None
    if not path.exists():
        raise InputError(f"data set {path} does not exist (a split file or a frame folder)")
    ids = read_split(path)
    if not ids:
        raise InputError(f"split file {path} lists no frame")
    return path.parent, ids


def build_dataset(
    path: Path, cfg: SegmenterTrainingConfig, augment: bool, seed: int = 0
) -> SegmentationFolder:
    """The set at ``path`` (:func:`resolve_set`), with ``data.augment`` when ``augment``; HHA
    at the resolution the model's streams see (:func:`~gaitnet.segmentation.hha.hha_stride`)."""
    root, ids = resolve_set(path)
    params = cfg.data.augment if augment else None
    return SegmentationFolder(
        root,
        ids,
        augment=params,
        cache_hha=cfg.data.cache_hha,
        seed=seed,
        hha_stride=hha_stride(cfg.model.input_scale),
    )


class TrainingSets(torch.utils.data.ConcatDataset):
    """Several training sets as one (``data.train`` and ``data.train_extra``); the augmentation
    epoch reaches each (:meth:`SegmentationFolder.set_epoch`)."""

    def set_epoch(self, epoch: int) -> None:
        for ds in self.datasets:
            ds.set_epoch(epoch)


def build_training_set(
    cfg: SegmenterTrainingConfig, seed: int = 0
) -> SegmentationFolder | TrainingSets:
    """``data.train`` with ``data.augment``, joined by the sets of ``data.train_extra``; the
    k-th set draws its augmentations from ``seed + k`` (the frames of two sets with the same
    index are not augmented alike). Sets of different frame sizes need a fixed crop
    (``data.augment.crop_height`` and ``crop_width``) to be batched together."""
    sets = [
        build_dataset(path, cfg, augment=True, seed=seed + k)
        for k, path in enumerate(cfg.data.train_sets)
    ]
    if len(sets) == 1:
        return sets[0]
    aug = cfg.data.augment
    cropped = aug is not None and aug.crop_height > 0 and aug.crop_width > 0
    sizes = {(ds.intrinsics.height, ds.intrinsics.width) for ds in sets}
    if len(sizes) > 1 and not cropped:
        listing = ", ".join(
            f"{path} ({ds.intrinsics.width}×{ds.intrinsics.height})"
            for path, ds in zip(cfg.data.train_sets, sets, strict=True)
        )
        raise InputError(
            f"data.train and data.train_extra have frames of different sizes ({listing}): "
            "set data.augment.crop_height and crop_width to batch them together"
        )
    return TrainingSets(sets)
