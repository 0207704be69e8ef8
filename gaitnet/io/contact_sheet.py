"""Contact sheets: a grid of frames (RGB | depth | labels) to look at a session at a glance."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np

from gaitnet.io.atomic import atomic_write_bytes
from gaitnet.io.images import encode_png

# Label colours (RGB): background dark grey, foot orange, leg blue, ignore white.
LABEL_COLOURS = {0: (40, 40, 40), 1: (255, 140, 0), 2: (60, 120, 255), 255: (255, 255, 255)}


def colourise_depth(depth_m: np.ndarray, near_m: float = 0.3, far_m: float = 3.0) -> np.ndarray:
    """Turbo colour map of depth (RGB uint8); invalid (0) pixels black."""
    scaled = np.clip((depth_m - near_m) / (far_m - near_m), 0.0, 1.0)
    rgb = cv2.applyColorMap((255 * scaled).astype(np.uint8), cv2.COLORMAP_TURBO)[:, :, ::-1]
    rgb = rgb.copy()
    rgb[~(depth_m > 0)] = 0
    return rgb


def colourise_labels(labels: np.ndarray) -> np.ndarray:
    """Label map (0 background, 1 foot, 2 leg, 255 ignore) as RGB uint8."""
    out = np.zeros((*labels.shape, 3), np.uint8)
    for value, colour in LABEL_COLOURS.items():
        out[labels == value] = colour
    return out


def contact_sheet(
    rows: Sequence[Sequence[np.ndarray]], captions: Sequence[str] = (), scale: float = 0.5
) -> np.ndarray:
    """Tile rows of RGB images (each row the panels of one frame) into one RGB image."""
    tiles = []
    for i, row in enumerate(rows):
        panels = [
            cv2.resize(p, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA) for p in row
        ]
        strip = np.concatenate(panels, axis=1)
        if i < len(captions):
            strip = strip.copy()
            cv2.putText(
                strip,
                captions[i],
                (6, 18),
                cv2.FONT_HERSHEY_SIMPLEX,
                0.5,
                (255, 255, 255),
                1,
                cv2.LINE_AA,
            )
        tiles.append(strip)
    return np.concatenate(tiles, axis=0)


def write_png(path: str | Path, rgb: np.ndarray) -> None:
    """Write an RGB image as PNG atomically."""
    atomic_write_bytes(path, encode_png(rgb))
