"""Seeding, and the state of every random generator a run uses (for a bit-exact resume).

The same seed and config give the same run (docs/design.md, *Conventions*). A resumed run must also
draw the same numbers as an uninterrupted one, so a checkpoint holds the state of every
generator the training scripts use (:func:`rng_state`), restored by :func:`restore_rng_state`:

* python's ``random`` and numpy's legacy global generator (``np.random``);
* torch's CPU generator (initialisation, dropout masks, the DataLoader's base seed when it has
  no generator of its own);
* torch's CUDA generator of every visible device, when CUDA is available (dropout on a GPU);
* the DataLoader's own ``torch.Generator`` when the script gives it one (worker seeds).

The data order needs no state: ``DistributedSampler(seed=seed)`` with ``set_epoch(epoch)``
permutes deterministically from ``(seed, epoch)``. Every state is stored as tensors, ints,
floats and lists/dicts of them, which ``torch.load(..., weights_only=True)`` reads.
"""

from __future__ import annotations

import logging
import random
from collections.abc import Mapping
from typing import Any

import numpy as np
import torch

__all__ = ["RNG_KEYS", "restore_rng_state", "rng_state", "seed_everything"]

logger = logging.getLogger(__name__)

#: Keys of :func:`rng_state`'s dict.
RNG_KEYS: tuple[str, ...] = ("python", "numpy", "torch", "cuda", "loader")


def seed_everything(seed: int, rank: int = 0) -> int:
    """Seed python's ``random``, numpy's legacy global state and torch with ``seed + rank``.

    Each rank gets its own stream (dropout masks differ between ranks as they should); data
    order comes from ``DistributedSampler(seed=seed)`` and is the same on every rank.
    ``torch.manual_seed`` also seeds every CUDA device. Returns the seed used.
    """
    s = int(seed) + int(rank)
    random.seed(s)
    np.random.seed(s % 2**32)
    torch.manual_seed(s)
    return s


def rng_state(loader_generator: torch.Generator | None = None) -> dict[str, Any]:
    """The state of every generator of this process (module docstring), weights-only safe."""
    version, mt, gauss = random.getstate()
    kind, keys, pos, has_gauss, cached = np.random.get_state(legacy=True)
    python = {"version": int(version), "state": torch.tensor(mt, dtype=torch.int64), "gauss": gauss}
    numpy = {
        "kind": str(kind),
        "keys": torch.from_numpy(keys.astype(np.int64)),
        "pos": int(pos),
        "has_gauss": int(has_gauss),
        "cached": float(cached),
    }
    return {
        "python": python,
        "numpy": numpy,
        "torch": torch.get_rng_state(),
        "cuda": list(torch.cuda.get_rng_state_all()) if torch.cuda.is_available() else [],
        "loader": None if loader_generator is None else loader_generator.get_state(),
    }


def _byte_tensor(value: Any, name: str) -> torch.Tensor:
    if not isinstance(value, torch.Tensor) or value.dtype != torch.uint8 or value.ndim != 1:
        raise ValueError(f"rng state {name!r} must be a 1-D uint8 tensor")
    return value


def restore_rng_state(
    state: Mapping[str, Any], loader_generator: torch.Generator | None = None
) -> None:
    """Set every generator from a :func:`rng_state` dict.

    CUDA states are restored for the devices both the checkpoint and this machine have (a
    warning says when the counts differ, e.g. a CPU checkpoint resumed on a GPU). A malformed
    state raises ``ValueError`` naming the part; callers name the checkpoint file.
    """
    if not isinstance(state, Mapping) or set(state) != set(RNG_KEYS):
        raise ValueError(f"rng state must be a dict with keys {list(RNG_KEYS)}")
    try:
        py, npy = state["python"], state["numpy"]
        mt = tuple(int(v) for v in py["state"].tolist())
        gauss = py["gauss"]
        if not (gauss is None or isinstance(gauss, float)) or len(mt) != 625:
            raise ValueError("rng state 'python' is malformed")
        keys = npy["keys"].numpy()
        if keys.shape != (624,) or keys.min() < 0 or keys.max() >= 2**32:
            raise ValueError("rng state 'numpy' keys must be 624 uint32 values")
        np_state = (str(npy["kind"]), keys.astype(np.uint32), int(npy["pos"]),
                    int(npy["has_gauss"]), float(npy["cached"]))  # fmt: skip
        torch_state = _byte_tensor(state["torch"], "torch")
        cuda = [_byte_tensor(s, "cuda") for s in state["cuda"]]
        loader = state["loader"]
        if loader is not None:
            loader = _byte_tensor(loader, "loader")
        random.setstate((int(py["version"]), mt, gauss))
        np.random.set_state(np_state)
        torch.set_rng_state(torch_state)
        if loader_generator is not None and loader is not None:
            loader_generator.set_state(loader)
    except (KeyError, TypeError, AttributeError, IndexError, RuntimeError) as exc:
        raise ValueError(f"rng state is malformed ({exc})") from exc
    if loader_generator is not None and loader is None:
        logger.warning("the checkpoint has no DataLoader generator state; it keeps its seed")
    n_here = torch.cuda.device_count() if torch.cuda.is_available() else 0
    if n_here != len(cuda):
        logger.warning(
            "the checkpoint has CUDA generator states of %d device(s), this machine %d: "
            "restoring %d",
            len(cuda),
            n_here,
            min(n_here, len(cuda)),
        )
    for device, cuda_state in enumerate(cuda[:n_here]):
        torch.cuda.set_rng_state(cuda_state, device)
