"""Loop pieces every training script needs, whatever it trains.

* :func:`resolve_device`: ``train.device`` as a torch device, a device the machine lacks being
  a one-line :class:`~gaitnet.errors.InputError`;
* :func:`checkpoint_to_resume`: which checkpoint ``--resume`` / ``--checkpoint`` name, and the
  refusal to overwrite a finished run without ``--resume``;
* :func:`gather_rng_states` / :func:`restore_rank_rng`: every rank's generator states in a
  checkpoint, and this rank's back (:mod:`gaitnet.training.seeding`);
* :class:`SkipSampler`: a sampler's epoch order without its first samples, so that a run
  resumed from a checkpoint written in the middle of an epoch sees exactly the batches the
  uninterrupted run would have.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import torch
from torch.utils.data import Sampler

from gaitnet.errors import InputError
from gaitnet.training.checkpoint import CheckpointError
from gaitnet.training.distributed import DistInfo
from gaitnet.training.seeding import restore_rng_state, rng_state

__all__ = [
    "SkipSampler",
    "checkpoint_to_resume",
    "gather_rng_states",
    "resolve_device",
    "restore_rank_rng",
]


def resolve_device(name: str) -> torch.device:
    """``auto`` (CUDA if available, else CPU), ``cpu``, ``cuda[:N]``, ``mps``; a device this
    machine lacks is an :class:`InputError` naming ``train.device``."""
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


def checkpoint_to_resume(run_dir: Path, resume: bool, checkpoint: str | None) -> Path | None:
    """The checkpoint a run continues from (``<run_dir>/last.pt`` or ``checkpoint``), or None
    for a fresh run; a fresh run into a folder holding ``last.pt`` is refused."""
    if resume:
        return run_dir / "last.pt" if checkpoint is None else Path(checkpoint)
    if checkpoint is not None:
        raise InputError("--checkpoint goes with --resume or --eval-only")
    if (run_dir / "last.pt").exists():
        raise InputError(
            f"{run_dir} already holds a checkpoint; pass --resume to continue it, or choose "
            "another run name (name=...)"
        )
    return None


def gather_rng_states(info: DistInfo, loader_generator: torch.Generator | None) -> list[Any]:
    """Every rank's :func:`~gaitnet.training.seeding.rng_state` (rank order), on every rank."""
    state = rng_state(loader_generator)
    if not info.distributed:
        return [state]
    states: list[Any] = [None] * info.world_size
    torch.distributed.all_gather_object(states, state)
    return states


def restore_rank_rng(
    ckpt: dict[str, Any], rank: int, path: Path, loader_generator: torch.Generator | None
) -> None:
    """Restore this rank's generator states from ``ckpt["rng"]``."""
    states = ckpt.get("rng")
    if not isinstance(states, list) or rank >= len(states):
        raise CheckpointError(f"checkpoint {path}: no random-generator state for rank {rank}")
    try:
        restore_rng_state(states[rank], loader_generator)
    except ValueError as exc:
        raise CheckpointError(f"checkpoint {path}: {exc}") from exc


class SkipSampler(Sampler[int]):
    """``sampler``'s order for the current epoch without its first ``skip`` indices.

    ``set_epoch`` is passed on (a ``DistributedSampler`` permutes from ``(seed, epoch)``);
    :meth:`skip_next` sets how many indices the NEXT iteration drops (then it is reset to 0).
    """

    def __init__(self, sampler: Any) -> None:
        self.sampler = sampler
        self._skip = 0

    def set_epoch(self, epoch: int) -> None:
        if hasattr(self.sampler, "set_epoch"):
            self.sampler.set_epoch(epoch)

    def skip_next(self, n: int) -> None:
        if n < 0:
            raise ValueError(f"cannot skip {n} samples")
        self._skip = int(n)

    def __iter__(self) -> Iterator[int]:
        skip, self._skip = self._skip, 0
        for i, index in enumerate(self.sampler):
            if i >= skip:
                yield index

    def __len__(self) -> int:
        return len(self.sampler)
