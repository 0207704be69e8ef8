"""Mip-mapped textures: image pyramids and their filtered lookup (floors and tag sheets).

Level 0 is the texture; level ``l`` is ``cv2.pyrDown`` applied ``l`` times, so a level-0 texel
coordinate ``c`` is ``c / 2**l`` on level ``l``. Pyramids stop at texels of about
:data:`COARSEST_TEXEL_M`.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

F32 = NDArray[np.float32]
COARSEST_TEXEL_M = 0.02


def build_pyramid(img: NDArray, texel_m: float) -> tuple[NDArray, ...]:
    """Mip levels by repeated ``cv2.pyrDown`` until texels reach ~2 cm or the image is tiny.

    3-channel images become RGBA (cv2.remap samples 4 channels twice as fast as 3);
    single-channel images stay single-channel."""
    if img.ndim == 3 and img.shape[2] == 3:
        img = cv2.cvtColor(img, cv2.COLOR_RGB2RGBA)
    levels = [img]
    texel = texel_m
    while texel * 2 <= COARSEST_TEXEL_M * 1.01 and min(levels[-1].shape[:2]) >= 8:
        levels.append(cv2.pyrDown(levels[-1]))
        texel *= 2
    return tuple(levels)


MIP_BLEND = 0.15  # width (in levels) of the cross-fade between two mip levels


def sample_mipmapped(
    levels: tuple[NDArray, ...],
    map_x: F32,
    map_y: F32,
    lod: F32,
    border: int = cv2.BORDER_REFLECT_101,
) -> NDArray:
    """Mip-mapped bilinear lookup: the level nearest to ``lod``, cross-faded with the next one
    over :data:`MIP_BLEND` levels around each half-way point (cheaper than full trilinear).

    ``map_x``, ``map_y`` (H, W) are level-0 texel coordinates (texel centres at integers);
    ``lod`` (H, W) the fractional level; returns RGB (H, W, 3) for RGBA levels, else the
    levels' channels, in the levels' type (uint8 or float32). Each level samples only the rows
    it contributes to, and weights are only computed in rows that mix two levels.
    """
    top = len(levels) - 1
    lod = np.clip(lod, 0.0, top)
    row_lo, row_hi = lod.min(axis=1), lod.max(axis=1)
    reach = 0.5 + MIP_BLEND / 2  # a level contributes to lods within this distance
    out = np.zeros(lod.shape + levels[0].shape[2:], levels[0].dtype)  # 0 · garbage may be NaN
    acc = np.zeros(lod.shape, np.float32)
    for lvl, tex in enumerate(levels):
        lo = -np.inf if lvl == 0 else lvl - reach
        hi = np.inf if lvl == top else lvl + reach
        rows = np.flatnonzero((row_hi > lo) & (row_lo < hi))
        if rows.size == 0:
            continue
        r0, r1 = int(rows[0]), int(rows[-1]) + 1
        mx, my = map_x[r0:r1], map_y[r0:r1]
        if lvl:
            mx, my = mx * np.float32(0.5**lvl), my * np.float32(0.5**lvl)
        img = cv2.remap(tex, mx, my, cv2.INTER_LINEAR, borderMode=border)
        pure = (row_lo[r0:r1] >= lo + MIP_BLEND) & (row_hi[r0:r1] <= hi - MIP_BLEND)
        out[r0:r1][pure] = img[pure]
        mixed = np.flatnonzero(~pure)
        if mixed.size:
            b0, b1 = int(mixed[0]), int(mixed[-1]) + 1
            w = 0.5 + (0.5 - np.abs(lod[r0 + b0 : r0 + b1] - np.float32(lvl))) / MIP_BLEND
            w = np.clip(w, 0.0, 1.0, dtype=np.float32)
            if lvl == top:
                w[lod[r0 + b0 : r0 + b1] >= top] = 1.0
            if lvl == 0:
                w[lod[r0 + b0 : r0 + b1] <= 0] = 1.0
            rows_mix = np.s_[r0 + b0 : r0 + b1]
            out[rows_mix] = cv2.blendLinear(out[rows_mix], img[b0:b1], acc[rows_mix], w)
            acc[rows_mix] += w
    return cv2.cvtColor(out, cv2.COLOR_RGBA2RGB) if out.ndim == 3 and out.shape[2] == 4 else out
