"""Depth in metres → uint16 depth units, against a plain per-pixel computation."""

from __future__ import annotations

import math
import warnings

import numpy as np

from gaitnet.io.images import depth_to_units


def _one(depth_m: float, scale: float) -> int:
    if not math.isfinite(depth_m):
        return 0
    units = round(depth_m / scale)  # Python rounds half to even too
    return units if 0 < units <= 65535 else 0


def test_matches_a_per_pixel_computation() -> None:
    rng = np.random.default_rng(3)
    depth = rng.uniform(-1.0, 70.0, (40, 50)).astype(np.float32)
    depth[::7, ::5] = np.nan
    depth[::11, ::3] = np.inf
    depth[::13] = -np.inf
    depth[1, :6] = [0.0, 65.535, 65.5355, 65.536, 0.0004, 0.0006]
    scale = 0.001
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no cast warning for the invalid pixels
        units = depth_to_units(depth, scale)
    expected = np.array([[_one(float(d), scale) for d in row] for row in depth], np.uint16)
    assert units.dtype == np.uint16
    np.testing.assert_array_equal(units, expected)
    assert units[1, 1] == 65535 and units[1, 3] == 0 and units[1, 4] == 0 and units[1, 5] == 1
