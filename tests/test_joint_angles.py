"""Sagittal joint angles (gaitnet.pipeline.joint_angles): known answers from FK geometry."""

import numpy as np
import pytest

from gaitnet.motion.skeleton import builtin_skeleton, forward_kinematics
from gaitnet.pipeline.joint_angles import sagittal_angles_deg


def _angle_between(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.degrees(np.arccos(a @ b / np.linalg.norm(a) / np.linalg.norm(b))))


def test_signs_and_values_against_the_segment_geometry() -> None:
    """Hip flexion lifts the thigh forwards, knee flexion bends the shank backwards: the angles
    equal the angles between the segments computed from forward kinematics."""
    skel = builtin_skeleton(1.7)
    aa = np.zeros((1, 8, 3))
    aa[0, 0, 0] = -np.radians(30)  # L_hip about -x: flexion
    aa[0, 2, 0] = np.radians(50)  # L_knee about +x: flexion
    aa[0, 4, 0] = -np.radians(10)  # L_ankle about -x: dorsiflexion
    root = np.zeros((1, 3))
    p = forward_kinematics(skel, root, np.zeros((1, 3)), aa)[0]
    thigh, shank, foot = p[3] - p[1], p[5] - p[3], p[7] - p[5]
    assert thigh[2] > 0  # knee ahead of the hip: flexed hip
    angles = sagittal_angles_deg(aa[:, :6])[0]
    assert angles[0] == pytest.approx(_angle_between(thigh, [0, -1, 0]), abs=1e-6)
    assert angles[2] == pytest.approx(_angle_between(thigh, shank), abs=1e-6)
    rest_foot = skel.rest_joints[7] - skel.rest_joints[5]
    # dorsiflexion lifts the toes: the foot turns away from the (downward) shank direction
    rest_angle = _angle_between(skel.rest_joints[5] - skel.rest_joints[3], rest_foot)
    assert angles[4] == pytest.approx(_angle_between(shank, foot) - rest_angle, abs=1e-6)
    assert angles[4] == pytest.approx(10.0)
    assert angles[[1, 3, 5]] == pytest.approx([0, 0, 0])


def test_shape_is_checked() -> None:
    with pytest.raises(ValueError, match=r"\(n, 6, 3\)"):
        sagittal_angles_deg(np.zeros((4, 8, 3)))
