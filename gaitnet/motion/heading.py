"""Heading of a body and heading normalisation of motion windows (pure math, z-up world).

AMASS's world is z up. Each training window is rotated about the world vertical so that the
body's heading at the LAST OBSERVED frame is +x (docs/design.md: x forward), and its translation is
taken relative to that frame horizontally (:func:`normalise_heading`). The heading is the
body's forward axis (SMPL's canonical +z, the way the rest pose faces) mapped by the root
orientation and projected onto the floor. This also keeps the root axis-angle far from the ±π
wrap (about 120° about (1, 1, 1)/√3 when upright and facing +x).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

__all__ = ["FORWARD_IN_BODY", "heading_angle", "normalise_heading"]

#: The body's forward axis in SMPL's canonical frame: the rest pose faces +z.
FORWARD_IN_BODY = np.array([0.0, 0.0, 1.0])


def heading_angle(root_orient: np.ndarray) -> np.ndarray:
    """Heading (yaw about world +z) [rad] of the body's forward axis for (..., 3) axis-angles.

    Forward is SMPL's canonical +z mapped by the root orientation, projected on the floor;
    0 means facing +x.
    """
    root_orient = np.asarray(root_orient, dtype=np.float64)
    flat = root_orient.reshape(-1, 3)
    f = Rotation.from_rotvec(flat).apply(FORWARD_IN_BODY)
    return np.arctan2(f[:, 1], f[:, 0]).reshape(root_orient.shape[:-1])


def normalise_heading(
    root_orient: np.ndarray, trans: np.ndarray, ref: int
) -> tuple[np.ndarray, np.ndarray, float]:
    """Rotate a window about world z so the heading at frame ``ref`` is +x.

    Returns ``(root_orient', trans', yaw)`` with ``R' = Rz(−yaw) R`` and
    ``trans' = Rz(−yaw) (trans − [trans_ref,x, trans_ref,y, 0])``. Joint positions from forward
    kinematics then equal ``Rz(−yaw)`` times the original ones plus a constant offset
    (``(I − Rz) J_0`` minus the reference shift), so the motion is unchanged relative to any of
    its frames; the pelvis at frame ``ref`` sits at the rest pelvis's x, y (a few mm).
    """
    root_orient = np.asarray(root_orient, dtype=np.float64)
    trans = np.asarray(trans, dtype=np.float64)
    yaw = float(heading_angle(root_orient[ref]))
    Rz = Rotation.from_rotvec([0.0, 0.0, -yaw])
    root_n = (Rz * Rotation.from_rotvec(root_orient)).as_rotvec()
    shift = np.array([trans[ref, 0], trans[ref, 1], 0.0])
    trans_n = Rz.apply(trans - shift)
    return root_n, trans_n, yaw
