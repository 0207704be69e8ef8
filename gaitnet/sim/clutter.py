"""Boxes and cylinders standing on the floor around the walking path (scene clutter)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gaitnet.sim.floor import Extent

__all__ = ["Clutter", "ClutterBox", "ClutterCylinder", "make_clutter"]


@dataclass(frozen=True)
class ClutterBox:
    """A box standing on the floor: centre of its footprint, yaw about z, size (x, y, z) [m]."""

    centre_xy: tuple[float, float]
    yaw_rad: float
    size_m: tuple[float, float, float]
    rgb: tuple[float, float, float]


@dataclass(frozen=True)
class ClutterCylinder:
    """An upright cylinder standing on the floor (a bin, a cone base, a stool leg)."""

    centre_xy: tuple[float, float]
    radius_m: float
    height_m: float
    rgb: tuple[float, float, float]


Clutter = ClutterBox | ClutterCylinder


def make_clutter(
    rng: np.random.Generator,
    extent_xy: Extent,
    n: int = 6,
    path_y_m: float = 0.0,
    keep_out_m: float = 0.7,
) -> tuple[Clutter, ...]:
    """``n`` boxes and cylinders placed inside ``extent_xy`` but ≥ ``keep_out_m`` from the
    walking path (the line y = ``path_y_m``)."""
    (x0, x1), (y0, y1) = extent_xy
    colours = [
        (0.45, 0.05, 0.03),
        (0.05, 0.12, 0.4),
        (0.5, 0.4, 0.08),
        (0.06, 0.25, 0.08),
        (0.3, 0.3, 0.3),
        (0.6, 0.58, 0.55),
        (0.2, 0.12, 0.06),
    ]
    out: list[Clutter] = []
    for _ in range(20 * n):
        if len(out) == n:
            break
        cy = float(rng.uniform(y0 + 0.2, y1 - 0.2))
        size = float(rng.uniform(0.15, 0.5))
        if abs(cy - path_y_m) < keep_out_m + size:
            continue
        centre = (float(rng.uniform(x0 + 0.3, x1 - 0.3)), cy)
        rgb = colours[int(rng.integers(len(colours)))]
        if rng.random() < 0.6:
            dims = (size, size * float(rng.uniform(0.5, 1.5)), float(rng.uniform(0.1, 0.6)))
            out.append(ClutterBox(centre, float(rng.uniform(0, np.pi)), dims, rgb))
        else:
            out.append(ClutterCylinder(centre, size / 2, float(rng.uniform(0.2, 0.9)), rgb))
    return tuple(out)
