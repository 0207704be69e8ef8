"""Sagittal joint angles of the lower body from the pose's local rotations.

The local rotation of each joint (SMPL convention: relative to its parent segment, in the body's
canonical axes x left, y up, z forward) is decomposed as intrinsic x–y–z Euler angles; the first
one, about the proximal segment's medio-lateral axis, is the flexion angle, as in the joint
coordinate systems of Grood & Suntay (J. Biomech. Eng. 1983) used by gait labs. Signs follow the
clinical convention (docs/ecosystem.md): hip flexion, knee flexion and ankle dorsiflexion
positive. With SMPL's x axis pointing left, a positive rotation about x swings a segment
backwards: hip flexion is ``−θx``, knee flexion ``+θx``, ankle dorsiflexion ``−θx``.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

__all__ = ["ANGLE_NAMES", "sagittal_angles_deg"]

ANGLE_NAMES = (
    "hip_flexion_left",
    "hip_flexion_right",
    "knee_flexion_left",
    "knee_flexion_right",
    "ankle_dorsiflexion_left",
    "ankle_dorsiflexion_right",
)
_SIGN = np.array([-1.0, -1.0, 1.0, 1.0, -1.0, -1.0])


def sagittal_angles_deg(joint_aa: np.ndarray) -> np.ndarray:
    """(n, 6) angles [deg] in :data:`ANGLE_NAMES` order from local rotations (n, 6, 3) of
    L_hip, R_hip, L_knee, R_knee, L_ankle, R_ankle (axis-angle)."""
    aa = np.asarray(joint_aa, dtype=np.float64)
    if aa.ndim != 3 or aa.shape[1:] != (6, 3):
        raise ValueError(f"joint_aa must be (n, 6, 3), got {aa.shape}")
    euler = Rotation.from_rotvec(aa.reshape(-1, 3)).as_euler("XYZ").reshape(len(aa), 6, 3)
    return np.degrees(euler[:, :, 0]) * _SIGN
