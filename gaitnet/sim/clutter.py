"""Boxes and cylinders standing on the floor around the walking path (scene clutter)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gaitnet.sim.floor import Extent

__all__ = ["Clutter", "ClutterBox", "ClutterCylinder", "distance_to_path", "make_clutter"]


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


def distance_to_path(point_xy: np.ndarray, path_xy: np.ndarray) -> float:
    """Distance [m] from a point (2,) to the polyline ``path_xy`` (m, 2), m ≥ 1."""
    p = np.asarray(point_xy, dtype=np.float64)
    path = np.asarray(path_xy, dtype=np.float64).reshape(-1, 2)
    if len(path) == 1:
        return float(np.linalg.norm(p - path[0]))
    a, b = path[:-1], path[1:]
    ab = b - a
    length2 = np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-18)
    s = np.clip(np.einsum("ij,ij->i", p - a, ab) / length2, 0.0, 1.0)
    return float(np.min(np.linalg.norm(a + s[:, None] * ab - p, axis=1)))


def make_clutter(
    rng: np.random.Generator,
    extent_xy: Extent,
    n: int = 6,
    path_y_m: float = 0.0,
    keep_out_m: float = 0.7,
    path_xy: np.ndarray | None = None,
) -> tuple[Clutter, ...]:
    """``n`` boxes and cylinders placed inside ``extent_xy`` but ≥ ``keep_out_m`` (plus their
    size) from the walking path: the line y = ``path_y_m`` (the start's direction) and, when
    given, the polyline ``path_xy`` (m, 2) the walk follows (a turning walk leaves that line; a
    box on its path would be walked through, and its edges seen as stance feet). A straight
    walk's path lies on the line, so the polyline only moves clutter off turning walks."""
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
        if path_xy is not None and distance_to_path(np.array(centre), path_xy) < keep_out_m + size:
            continue
        rgb = colours[int(rng.integers(len(colours)))]
        if rng.random() < 0.6:
            dims = (size, size * float(rng.uniform(0.5, 1.5)), float(rng.uniform(0.1, 0.6)))
            out.append(ClutterBox(centre, float(rng.uniform(0, np.pi)), dims, rgb))
        else:
            out.append(ClutterCylinder(centre, size / 2, float(rng.uniform(0.2, 0.9)), rgb))
    return tuple(out)
