"""Motion-type labels of evaluation windows: known answers for each rule, invariance."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from gaitnet.motion.motion_types import label_window

FPS, N_PAST, W = 30.0, 10, 20
UPRIGHT_FACING_X = Rotation.from_rotvec(np.full(3, 2 * np.pi / 3 / np.sqrt(3)))
t = np.arange(W) / FPS


def _root(yaw_deg: np.ndarray) -> np.ndarray:
    yaw = Rotation.from_rotvec(np.outer(np.radians(yaw_deg), [0.0, 0.0, 1.0]))
    return (yaw * UPRIGHT_FACING_X).as_rotvec()


def _walk(speed: np.ndarray, lateral_m: float = 0.0) -> np.ndarray:
    x = np.concatenate([[0.0], np.cumsum(speed[:-1] / FPS)])
    y = lateral_m * np.sin(2 * np.pi * t / 1.1)
    return np.stack([x, y, 0.9 + 0 * t], axis=1)


def test_standing_with_sway_is_standing() -> None:
    trans = np.stack([0.003 * np.sin(3 * t), 0.002 * np.cos(2 * t), 0.9 + 0 * t], axis=1)
    assert label_window(_root(np.zeros(W)), trans, FPS, N_PAST) == "standing"


def test_steady_walking_with_pelvis_rotation_and_sway_is_steady() -> None:
    speed = 1.2 * (1 + 0.15 * np.sin(2 * np.pi * t / 0.55))  # within-step speed fluctuation
    yaw = 5.0 * np.sin(2 * np.pi * t / 1.1)  # ±5° pelvis rotation in gait
    label = label_window(_root(yaw), _walk(speed, lateral_m=0.02), FPS, N_PAST)
    assert label == "steady_walking"


@pytest.mark.parametrize("ramp", ["start", "stop"])
def test_starting_and_stopping(ramp: str) -> None:
    speed = np.clip(1.5 * t, 0.0, 1.2) if ramp == "start" else np.clip(1.2 - 2.0 * t, 0.0, 1.2)
    assert label_window(_root(np.zeros(W)), _walk(speed), FPS, N_PAST) == "start_stop"


def test_turning_needs_a_heading_change_of_15_degrees() -> None:
    speed = np.full(W, 1.2)
    for total, expected in ((40.0, "turning"), (12.0, "steady_walking")):
        yaw = total * t / t[-1]
        assert label_window(_root(yaw), _walk(speed), FPS, N_PAST) == expected


def test_labels_do_not_depend_on_where_the_body_is_or_faces() -> None:
    speed = np.full(W, 1.0)
    yaw = 40.0 * t / t[-1]
    trans = _walk(speed)
    R = Rotation.from_rotvec([0.0, 0.0, 2.5])
    moved = R.apply(trans) + [3.0, -7.0, 0.0]
    root = (R * Rotation.from_rotvec(_root(yaw))).as_rotvec()
    assert label_window(root, moved, FPS, N_PAST) == label_window(_root(yaw), trans, FPS, N_PAST)
    with pytest.raises(ValueError, match="n_past"):
        label_window(root, moved, FPS, 0)
