"""Checkpoints: atomic ``last.pt`` / ``best.pt`` that load with ``weights_only=True``.

A checkpoint is a plain dict (as in torchvision's ``references/``): ``model``, ``optimizer``,
``scheduler`` (state dicts), ``epoch`` (the last COMPLETED epoch, 0-based), ``best_metric``
and ``best_epoch`` (model selection on the validation split), ``config`` (the resolved config
as plain data, :func:`gaitnet.config.config_to_dict`), ``git_hash`` and ``rng`` (one dict per
rank of :func:`gaitnet.training.seeding.rng_state`: python, numpy, torch CPU, torch CUDA on
every device, DataLoader generator, so a resumed run draws the same numbers as an
uninterrupted one, on a GPU too). Everything in it is a tensor, a number, a string, ``None`` or
a dict/list of those, which is what ``torch.load(..., weights_only=True)`` admits;
:func:`save_checkpoint` refuses anything else, and any non-finite number, before writing, and
writes atomically (:func:`gaitnet.io.atomic.atomic_save`: a temporary sibling named with the
writer's pid, renamed into place; the leftover of a run killed mid-save is removed by the next
save of the same file).

Loading (:func:`load_checkpoint`) is always ``weights_only=True``; a file that is missing,
truncated, not a checkpoint, or holds pickled Python objects (which could run code) is a
one-line :class:`CheckpointError`. :func:`load_state` puts a checkpoint's state dict into a
model, optimizer or scheduler and turns a mismatch (another architecture) into the same.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import pickle
import re
import subprocess
import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Protocol, TypeVar

import torch

from gaitnet.config import parse_config
from gaitnet.errors import ConfigError, InputError, one_line
from gaitnet.io.atomic import atomic_save

__all__ = [
    "CHECKPOINT_KEYS",
    "CheckpointError",
    "check_weights_only_safe",
    "git_hash",
    "load_checkpoint",
    "load_state",
    "save_checkpoint",
    "with_checkpoint_model",
]

logger = logging.getLogger(__name__)
_Config = TypeVar("_Config")

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


class CheckpointError(InputError):
    """A checkpoint is missing, unreadable, unsafe, lacks a key or does not fit the model; the
    one-line message names the file."""


class _Stateful(Protocol):
    def load_state_dict(self, state_dict: Any, /) -> Any: ...


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
    """Raise ``TypeError`` naming the path of the first value ``weights_only`` would refuse,
    ``ValueError`` for the first non-finite float (a checkpoint never records a NaN)."""
    if isinstance(obj, float) and not math.isfinite(obj):
        raise ValueError(f"{where} is {obj}: a checkpoint never records a non-finite number")
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
    """``torch.load(path, weights_only=True)`` with one-line errors and a key check."""
    path = Path(path)
    if path.is_dir():
        raise CheckpointError(f"checkpoint {path} is a folder, expected a .pt file")
    if not path.is_file():
        raise CheckpointError(f"checkpoint {path} does not exist")
    try:
        with warnings.catch_warnings():  # a foreign pickle's protocol: the error below says it
            warnings.filterwarnings("ignore", message="Detected pickle protocol")
            state = torch.load(path, map_location=map_location, weights_only=True)
    except pickle.UnpicklingError as exc:
        # torch's message is several lines and suggests weights_only=False: never do that.
        found = re.search(r"(?:GLOBAL|global:?)\s+([\w.]+)", str(exc))
        what = f" ({found.group(1)})" if found else ""
        raise CheckpointError(
            f"checkpoint {path} refused: it holds pickled Python objects{what}, not only "
            "tensors and plain data; gaitnet loads checkpoints with weights_only=True and "
            "never runs code from a file"
        ) from exc
    except Exception as exc:  # truncated or foreign files raise many kinds (OSError too)
        text = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        reason = one_line(text.split(". ")[0], limit=300) or type(exc).__name__
        raise CheckpointError(
            f"checkpoint {path} cannot be read: empty, truncated or not a checkpoint ({reason})"
        ) from exc
    if not isinstance(state, dict):
        raise CheckpointError(f"checkpoint {path} holds a {type(state).__name__}, not a dict")
    missing = [k for k in CHECKPOINT_KEYS if k not in state]
    if missing:
        raise CheckpointError(f"checkpoint {path} lacks key(s) {missing}")
    for key in ("epoch", "best_epoch"):
        if not isinstance(state[key], int) or isinstance(state[key], bool) or state[key] < -1:
            raise CheckpointError(f"checkpoint {path}: key {key!r} must be an epoch number")
    if not isinstance(state["best_metric"], (int, float)) or not math.isfinite(
        state["best_metric"]
    ):
        raise CheckpointError(f"checkpoint {path}: key 'best_metric' must be a finite number")
    if not isinstance(state["config"], dict):
        raise CheckpointError(f"checkpoint {path}: key 'config' must be a mapping")
    return state


def load_state(target: _Stateful, state: Any, path: str | Path, what: str) -> None:
    """``target.load_state_dict(state)``; a mismatch is a one-line :class:`CheckpointError`.

    ``what`` names the part (``"model"``, ``"optimizer"``, ...) in the message.
    """
    if not isinstance(state, dict):
        raise CheckpointError(f"checkpoint {path}: key {what!r} must be a state dict")
    try:
        target.load_state_dict(state)
    except (RuntimeError, ValueError, KeyError, TypeError, IndexError, AttributeError) as exc:
        raise CheckpointError(
            f"checkpoint {path}: its {what} state does not fit "
            f"(another architecture?): {one_line(exc, limit=300)}"
        ) from exc


def with_checkpoint_model(
    cfg: _Config, ckpt: Mapping[str, Any], path: str | Path, model_type: type, what: str
) -> _Config:
    """The training config ``cfg`` with its architecture keys (``model.*``) from the checkpoint
    ``ckpt`` read from ``path``, as nanoGPT does on resume: ``ckpt["config"]["model"]`` parsed
    as ``model_type``. A checkpoint without a usable one is a :class:`CheckpointError` naming
    ``what`` (e.g. "segmenter architecture"); keys that differ from ``cfg``'s are logged."""
    try:
        model = parse_config(model_type, ckpt["config"]["model"], f"{path} (config)")
    except (ConfigError, KeyError, TypeError) as exc:
        raise CheckpointError(f"checkpoint {path}: no usable {what} in its config ({exc})") from exc
    current = cfg.model  # type: ignore[attr-defined]
    if model != current:
        logger.warning("model keys taken from %s: %s (config had %s)", path, model, current)
    try:
        return dataclasses.replace(cfg, model=model)  # type: ignore[type-var]
    except ValueError as exc:
        raise ConfigError(f"{path} (config): {exc}") from exc
