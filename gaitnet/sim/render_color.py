"""Colour encodings shared by the floor textures, the renderer and the sensor model.

Textures are stored 8-bit sRGB-encoded (like image files, 4× less memory than float) and turned
into linear radiance with a 256-entry table after sampling; :func:`encode_srgb8` goes back
through a 4096-level table. Tables use the exact sRGB transfer function (IEC 61966-2-1).
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

ENCODE_LEVELS = 4096


def srgb_to_linear(x: NDArray) -> NDArray:
    """Linear value of sRGB-encoded values ``x`` in [0, 1]."""
    x = np.asarray(x, dtype=np.float64)
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(x: NDArray) -> NDArray:
    """sRGB-encoded value of linear values ``x`` in [0, 1]."""
    x = np.clip(np.asarray(x, dtype=np.float64), 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1.0 / 2.4) - 0.055)


# uint8 sRGB code -> linear float32 (use with cv2.LUT, whose output takes the table's depth).
DECODE_LUT = srgb_to_linear(np.arange(256) / 255.0).astype(np.float32).reshape(256, 1)
# linear value quantised to ENCODE_LEVELS steps -> uint8 sRGB code.
ENCODE_LUT = np.round(
    255.0 * linear_to_srgb(np.arange(ENCODE_LEVELS) / (ENCODE_LEVELS - 1))
).astype(np.uint8)


def decode_srgb8(
    img: NDArray[np.uint8], tint: tuple[float, float, float] | None = None
) -> NDArray[np.float32]:
    """uint8 sRGB image -> linear float32 image of the same shape, optionally multiplied per
    channel by ``tint`` (for (H, W, 3) images) in the same table lookup."""
    if tint is None:
        return cv2.LUT(np.ascontiguousarray(img), DECODE_LUT).reshape(img.shape)
    lut = (DECODE_LUT[:, :, None] * np.asarray(tint, np.float32)[None, None]).astype(np.float32)
    return cv2.LUT(np.ascontiguousarray(img), lut)


def encode_srgb8(linear: NDArray) -> NDArray[np.uint8]:
    """Linear image (values clipped to [0, 1]) -> uint8 sRGB, via a 4096-level table."""
    scaled = np.asarray(linear, dtype=np.float32) * np.float32(ENCODE_LEVELS - 1)
    np.clip(scaled, 0.0, ENCODE_LEVELS - 1, out=scaled)
    idx = (scaled + np.float32(0.5)).astype(np.uint16)
    return ENCODE_LUT[idx]
