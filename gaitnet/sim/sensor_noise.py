"""Fast random images for the sensor models (colour: :mod:`gaitnet.sim.sensor_model`, depth:
:mod:`gaitnet.sim.sensor_depth`): one random byte (or two) per sample, mapped by a table."""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy.special import ndtri

from gaitnet.sim.render_types import F32

__all__ = ["gaussian_noise", "uniform16"]


def _gauss_table() -> np.ndarray:
    q = ndtri((np.arange(256) + 0.5) / 256.0)
    return (q / q.std()).astype(np.float32).reshape(256, 1)


# 256 equiprobable Gaussian quantiles (unit std, tails cut at ±2.9σ): one random byte per
# sample, mapped by cv2.LUT, is ~9× faster than numpy's standard_normal.
_GAUSS_LUT = _gauss_table()


def gaussian_noise(rng: np.random.Generator, shape: tuple[int, ...]) -> F32:
    """Unit-variance, zero-mean noise of ``shape`` (256-level quantised Gaussian)."""
    n = int(np.prod(shape))
    raw = np.frombuffer(rng.bytes(n), np.uint8).reshape(shape)
    return cv2.LUT(raw, _GAUSS_LUT).reshape(shape)


def uniform16(rng: np.random.Generator, shape: tuple[int, ...]) -> NDArray[np.uint16]:
    """Uniform integers 0–65535 of ``shape``."""
    return np.frombuffer(rng.bytes(2 * int(np.prod(shape))), np.uint16).reshape(shape)
