"""Training windows of the motion predictor: a torch Dataset over a prepared walking file.

:class:`WalkingWindows` serves windows of ``n_past + n_future`` frames from a prepared file
(:mod:`gaitnet.motion.prepared`), each heading-normalised (:mod:`gaitnet.motion.heading`) with
its last observed frame as reference, as 21-node pose vectors (:mod:`gaitnet.motion.gcn`).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np
import torch
from torch.utils.data import Dataset

from gaitnet.errors import InputError
from gaitnet.motion.amass import AmassError, Split
from gaitnet.motion.gcn import pose_features
from gaitnet.motion.heading import normalise_heading
from gaitnet.motion.prepared import SPLITS, PreparedWalking, load_prepared

__all__ = ["WalkingWindows"]


class WalkingWindows(Dataset):
    """Heading-normalised windows of ``n_past + n_future`` frames from a prepared file.

    Windows start every ``stride`` frames inside each clip of ``split``. Item ``i`` is a dict
    of float32 tensors: ``poses`` (W, 21) in the node layout of :mod:`gaitnet.motion.gcn`,
    ``trans`` (W, 3), ``betas`` (B,), and ``clip`` (int index into the prepared file). With
    ``normalise_heading`` (default) each window goes through :func:`normalise_heading` with
    the last observed frame (``n_past − 1``) as reference. ``dataset_stride`` maps sub-dataset
    names (any case) to their own stride; each must name a sub-dataset of ``split``.
    """

    def __init__(
        self,
        prepared: str | Path | PreparedWalking,
        split: Split = "train",
        *,
        n_past: int = 10,
        n_future: int = 10,
        stride: int = 5,
        normalise_heading: bool = True,
        dataset_stride: Mapping[str, int] | None = None,
    ):
        self.data = prepared if isinstance(prepared, PreparedWalking) else load_prepared(prepared)
        if split not in SPLITS:
            raise InputError(f"split must be 'train', 'val' or 'test', got {split!r}")
        strides = {str(k).lower(): int(v) for k, v in (dataset_stride or {}).items()}
        if n_past < 1 or n_future < 0 or min([stride, *strides.values()]) < 1:
            raise InputError(
                f"need n_past >= 1, n_future >= 0, strides >= 1; got {n_past}, {n_future}, "
                f"{stride}, {strides}"
            )
        self.split = split
        self.n_past = int(n_past)
        self.window = int(n_past + n_future)
        self.normalise = bool(normalise_heading)
        clips = np.flatnonzero(self.data.clip_split == split)
        datasets = {str(self.data.clip_dataset[c]).lower() for c in clips}
        missing = sorted(set(strides) - datasets)
        if missing:
            raise InputError(
                f"{self.data.path}: no clip of sub-dataset {missing[0]!r} in split {split!r} "
                f"(sub-datasets there: {', '.join(sorted(datasets)) or 'none'})"
            )
        index = []
        for c in clips:
            step = strides.get(str(self.data.clip_dataset[c]).lower(), int(stride))
            a, b = int(self.data.clip_offset[c]), int(self.data.clip_offset[c + 1])
            for start in range(a, b - self.window + 1, step):
                index.append((int(c), start))
        if not index:
            raise AmassError(
                f"{self.data.path}: no windows of {self.window} frames in split {split!r}"
            )
        self.index = np.array(index, dtype=np.int64)

    @property
    def fps(self) -> float:
        return self.data.fps

    def __len__(self) -> int:
        return int(self.index.shape[0])

    def __getitem__(self, i: int) -> dict[str, torch.Tensor]:
        clip, start = (int(v) for v in self.index[i])
        sl = slice(start, start + self.window)
        root = self.data.root_orient[sl].astype(np.float64)
        trans = self.data.trans[sl].astype(np.float64)
        if self.normalise:
            root, trans, _ = normalise_heading(root, trans, self.n_past - 1)
        poses = pose_features(root, self.data.joint_aa[sl])
        return {
            "poses": torch.from_numpy(poses.astype(np.float32)),
            "trans": torch.from_numpy(trans.astype(np.float32)),
            "betas": torch.from_numpy(self.data.betas[clip].astype(np.float32)),
            "clip": torch.tensor(clip),
        }
