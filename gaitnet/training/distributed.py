"""Distributed helpers: read torchrun's environment, set up the process group, reduce metrics.

As torchvision's ``references/*/utils.py``: a run started by ``torchrun`` has ``RANK``,
``WORLD_SIZE`` and ``LOCAL_RANK`` in its environment; a plain ``python train/X.py`` has none and
runs as rank 0 of 1 without a process group. The process group is created only when
``WORLD_SIZE > 1`` (backend ``gloo`` on CPU, ``nccl`` when the local rank has a CUDA device).
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass

import torch
import torch.distributed as dist

from gaitnet.errors import InputError

__all__ = [
    "DistInfo",
    "all_reduce_sum",
    "barrier",
    "cleanup_distributed",
    "dist_info_from_env",
    "init_distributed",
    "is_dist_initialized",
]

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class DistInfo:
    """Where this process sits: ``rank`` of ``world_size``, ``local_rank`` on its node."""

    rank: int = 0
    world_size: int = 1
    local_rank: int = 0
    backend: str | None = None

    @property
    def distributed(self) -> bool:
        """True when more than one process takes part (a process group exists)."""
        return self.world_size > 1

    @property
    def is_main(self) -> bool:
        """Rank 0: the only process that logs, writes metrics and saves checkpoints."""
        return self.rank == 0


def _env_int(name: str, default: int) -> int:
    raw = os.environ.get(name)
    if raw is None or raw == "":
        return default
    try:
        return int(raw)
    except ValueError as exc:
        raise InputError(f"environment variable {name}={raw!r} is not an integer") from exc


def dist_info_from_env() -> DistInfo:
    """``RANK``, ``WORLD_SIZE``, ``LOCAL_RANK`` from the environment (defaults 0, 1, 0)."""
    rank = _env_int("RANK", 0)
    world = _env_int("WORLD_SIZE", 1)
    local = _env_int("LOCAL_RANK", rank)
    if world < 1 or not 0 <= rank < world:
        raise InputError(f"inconsistent torchrun environment: RANK={rank}, WORLD_SIZE={world}")
    return DistInfo(rank=rank, world_size=world, local_rank=local)


def init_distributed(backend: str | None = None) -> DistInfo:
    """Initialise ``torch.distributed`` from torchrun's environment when ``WORLD_SIZE > 1``.

    ``backend`` defaults to ``nccl`` if CUDA is available and ``gloo`` otherwise. With one
    process nothing is initialised and :class:`DistInfo` says rank 0 of 1.
    """
    info = dist_info_from_env()
    if not info.distributed:
        return info
    if backend is None:
        backend = "nccl" if torch.cuda.is_available() else "gloo"
    if backend == "nccl":
        torch.cuda.set_device(info.local_rank)
    if not dist.is_initialized():
        dist.init_process_group(backend=backend, init_method="env://")
    logger.info("distributed: rank %d of %d (%s)", info.rank, info.world_size, backend)
    return DistInfo(info.rank, info.world_size, info.local_rank, backend)


def is_dist_initialized() -> bool:
    """Whether a process group exists."""
    return dist.is_available() and dist.is_initialized()


def barrier() -> None:
    """Wait for every rank (no-op without a process group)."""
    if is_dist_initialized():
        dist.barrier()


def all_reduce_sum(values: torch.Tensor) -> torch.Tensor:
    """Sum a tensor over ranks (returns it unchanged without a process group)."""
    if is_dist_initialized():
        values = values.clone()
        dist.all_reduce(values, op=dist.ReduceOp.SUM)
    return values


def cleanup_distributed() -> None:
    """Destroy the process group if one exists."""
    if is_dist_initialized():
        dist.destroy_process_group()
