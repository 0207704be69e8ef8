"""The body's axes seen from a waist-worn camera: its forward made horizontal, and its left.

A lone foot is sided by its position along the body's left (:mod:`gaitnet.segmentation.
postprocess`, step 4), ``up × forward`` with ``up`` from gravity and ``forward`` the body's
forward in the camera frame (``feet.forward_in_camera``, estimated from the standing frames by
:mod:`gaitnet.segmentation.midline`; else the optical axis).
"""

from __future__ import annotations

import numpy as np

__all__ = ["horizontal_forward", "left_axis"]


def horizontal_forward(up_C: np.ndarray, forward_C: np.ndarray | None = None) -> np.ndarray:
    """``forward_C`` (default: the optical axis) made horizontal (perpendicular to ``up_C``) and
    unit, in the camera frame; the image's up where that is nearly vertical (a camera looking
    straight down)."""
    up = up_C / np.linalg.norm(up_C)
    forward = np.array([0.0, 0.0, 1.0]) if forward_C is None else np.asarray(forward_C, float)
    forward = forward - (forward @ up) * up
    if np.linalg.norm(forward) < 0.05:  # looking straight down: image up is forward
        forward = np.array([0.0, -1.0, 0.0]) - (-up[1]) * up
    return forward / np.linalg.norm(forward)


def left_axis(up_C: np.ndarray | None, forward_C: np.ndarray | None = None) -> np.ndarray:
    """The body's left in the camera frame: ``up × forward`` (module docstring); ``forward_C``
    the body's forward in the camera frame (``forward_in_camera``), else the optical axis."""
    if up_C is None:
        return np.array([-1.0, 0.0, 0.0])
    up = up_C / np.linalg.norm(up_C)
    return np.cross(up, horizontal_forward(up, forward_C))
