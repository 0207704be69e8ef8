"""Seeding: the same seed and config give the same run (DESIGN.md conventions)."""

from __future__ import annotations

import random

import numpy as np
import torch

__all__ = ["seed_everything"]


def seed_everything(seed: int, rank: int = 0) -> int:
    """Seed python's ``random``, numpy's legacy global state and torch with ``seed + rank``.

    Each rank gets its own stream (dropout masks differ between ranks as they should); data
    order comes from ``DistributedSampler(seed=seed)`` and is the same on every rank.
    Returns the seed used.
    """
    s = int(seed) + int(rank)
    random.seed(s)
    np.random.seed(s % 2**32)
    torch.manual_seed(s)
    return s
