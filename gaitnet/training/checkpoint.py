"""Checkpoints: atomic ``last.pt`` / ``best.pt`` that load with ``weights_only=True``.

A checkpoint is a plain dict (torchvision references, STYLE.md): ``model``, ``optimizer``,
``scheduler`` (state dicts), ``epoch`` (the last COMPLETED epoch, 0-based), ``best_metric``
and ``best_epoch`` (model selection on the validation split), ``config`` (the resolved config
as plain data, :func:`gaitnet.config.config_to_dict`), ``git_hash`` and ``rng`` (torch's CPU
generator state, so a resumed run draws the same dropout masks as an uninterrupted one).
Everything in it is a tensor, a number, a string, ``None`` or a dict/list of those, which is
what ``torch.load(..., weights_only=True)`` admits; :func:`save_checkpoint` refuses anything
else before writing, and writes atomically (:func:`gaitnet.io.atomic.atomic_save`).
"""

from __future__ import annotations

import subprocess
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import torch

from gaitnet.errors import GaitnetError
from gaitnet.io.atomic import atomic_save

__all__ = [
    "CHECKPOINT_KEYS",
    "CheckpointError",
    "check_weights_only_safe",
    "git_hash",
    "load_checkpoint",
    "save_checkpoint",
]

#: Keys every checkpoint written by the training scripts has.
CHECKPOINT_KEYS: tuple[str, ...] = (
    "model",
    "optimizer",
    "scheduler",
    "epoch",
    "best_metric",
    "best_epoch",
    "config",
    "git_hash",
)

_SAFE_SCALARS = (bool, int, float, str, type(None), torch.dtype, torch.device, torch.Size)


class CheckpointError(GaitnetError):
    """A checkpoint is missing, unreadable or lacks a key; the message names the file."""


def git_hash(cwd: str | Path | None = None) -> str:
    """The current commit (``+dirty`` if the tree has changes), or ``"unknown"``."""
    where = Path(__file__).parent if cwd is None else Path(cwd)
    try:
        head = subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=where, capture_output=True, text=True, timeout=10
        )
        if head.returncode != 0:
            return "unknown"
        status = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=where,
            capture_output=True,
            text=True,
            timeout=10,
        )
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    dirty = "+dirty" if status.returncode == 0 and status.stdout.strip() else ""
    return head.stdout.strip() + dirty


def check_weights_only_safe(obj: Any, where: str = "checkpoint") -> None:
    """Raise ``TypeError`` naming the path of the first value ``weights_only`` would refuse."""
    if isinstance(obj, (torch.Tensor, *_SAFE_SCALARS)):
        return
    if isinstance(obj, Mapping):
        for key, value in obj.items():
            if not isinstance(key, (str, int)):
                raise TypeError(f"{where}: key {key!r} is a {type(key).__name__}")
            check_weights_only_safe(value, f"{where}[{key!r}]")
        return
    if isinstance(obj, (list, tuple)):
        for i, value in enumerate(obj):
            check_weights_only_safe(value, f"{where}[{i}]")
        return
    raise TypeError(
        f"{where} is a {type(obj).__name__}, which torch.load(weights_only=True) cannot read"
    )


def save_checkpoint(state: Mapping[str, Any], path: str | Path) -> Path:
    """Check ``state`` (:func:`check_weights_only_safe`) and ``torch.save`` it atomically."""
    check_weights_only_safe(state)
    path = Path(path)
    atomic_save(path, lambda tmp: torch.save(dict(state), tmp))
    return path


def load_checkpoint(path: str | Path, map_location: str | torch.device = "cpu") -> dict[str, Any]:
    """``torch.load(path, weights_only=True)`` with clear errors and a key check."""
    path = Path(path)
    if not path.is_file():
        raise CheckpointError(f"checkpoint {path} does not exist")
    try:
        state = torch.load(path, map_location=map_location, weights_only=True)
    except Exception as exc:  # unpickling raises many kinds
        raise CheckpointError(f"checkpoint {path} cannot be read ({exc})") from exc
    if not isinstance(state, dict):
        raise CheckpointError(f"checkpoint {path} holds a {type(state).__name__}, not a dict")
    missing = [k for k in CHECKPOINT_KEYS if k not in state]
    if missing:
        raise CheckpointError(f"checkpoint {path} lacks key(s) {missing}")
    return state
