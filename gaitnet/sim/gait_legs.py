"""Legs by two-link inverse kinematics with a hinge knee, and the SMPL pose that reproduces them.

Frames: SMPL's canonical body frame (y up, z facing, x body-left) maps to the pelvis frame P
(x forward, y left, z up) by :data:`R_PfromSMPL` and to the shoe frame (x toe, y left, z up) by
the same matrix (the rest foot is flat and points forward). Hence
``root_orient = log(R_WfromP R_PfromSMPL)`` and the ankle's global rotation is
``G_ankle = R_WfromShoe R_PfromSMPL``.

Knee placement: with hip ``h``, ankle ``a``, ``e = (a − h)/|a − h|`` and the pelvis forward axis
``f`` made orthogonal to ``e``, the knee is ``h + L1 (cos β e + sin β f)`` (law of cosines for
``β``), so the knee bends forward in the plane of ``e`` and ``f``; the hinge axis is ``f × e``
(body-left). Global bone rotations align the rest bone direction and the rest hinge axis
(SMPL +x, made orthogonal to the bone) with the posed ones, so any rest skeleton (straight or
not) is reproduced exactly by the FK.
"""

from __future__ import annotations

import numpy as np

from gaitnet.geometry import so3_log
from gaitnet.motion.skeleton import LowerBodySkeleton

__all__ = ["R_PfromSMPL", "leg_chain", "smpl_pose_from_chain"]

R_PfromSMPL = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _frame(a: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Orthonormal frame with columns ``[a, h⊥, a × h⊥]`` (``h`` made orthogonal to unit ``a``)."""
    h = _unit(h - np.sum(h * a, axis=-1, keepdims=True) * a)
    return np.stack([a, h, np.cross(a, h)], axis=-1)


def _aligning_rotation(a_rest: np.ndarray, a: np.ndarray, hinge: np.ndarray) -> np.ndarray:
    """Rotation mapping rest bone ``a_rest`` to ``a`` and SMPL +x (⊥) to ``hinge`` (⊥)."""
    F_rest = _frame(_unit(a_rest), np.array([1.0, 0.0, 0.0]))
    F = _frame(a, hinge)
    return F @ np.swapaxes(F_rest, -1, -2)


def leg_chain(
    skel: LowerBodySkeleton,
    R_WfromP: np.ndarray,
    p_PinW: np.ndarray,
    R_WfromShoe: np.ndarray,
    ankle_W: np.ndarray,
    bend_W: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Joint positions ``(n, 9, 3)`` and global rotations of thighs and shanks ``(n, 2, 3, 3)``.

    ``R_WfromShoe`` (n, 2, 3, 3) and ``ankle_W`` (n, 2, 3) are per side (left, right).
    ``bend_W`` (n, 2, 3): the direction each knee bends towards (made orthogonal to the
    hip–ankle line; None: the pelvis forward axis ``f``, as the module docstring says). Raises
    if an ankle is out of reach (the generator keeps it within reach).
    """
    J = skel.rest_joints
    R_root = R_WfromP @ R_PfromSMPL
    n = len(p_PinW)
    joints = np.empty((n, 9, 3))
    joints[:, 0] = p_PinW
    hips = p_PinW[:, None, :] + np.einsum("nij,sj->nsi", R_root, J[1:3] - J[0])
    joints[:, 1:3] = hips
    L1 = np.linalg.norm(J[3:5] - J[1:3], axis=-1)
    L2 = np.linalg.norm(J[5:7] - J[3:5], axis=-1)
    d_vec = ankle_W - hips
    d = np.linalg.norm(d_vec, axis=-1)
    if np.any(d > L1 + L2 - 1e-9) or np.any(d < np.abs(L1 - L2) + 1e-9):
        raise ValueError("leg IK: ankle out of reach")
    e = d_vec / d[..., None]
    fwd = np.broadcast_to(R_WfromP[:, None, :, 0] if bend_W is None else bend_W, e.shape)
    f = _unit(fwd - np.sum(fwd * e, axis=-1, keepdims=True) * e)
    cos_b = (L1**2 + d**2 - L2**2) / (2 * L1 * d)
    sin_b = np.sqrt(np.clip(1.0 - cos_b**2, 0.0, None))
    knees = hips + L1[:, None] * (cos_b[..., None] * e + sin_b[..., None] * f)
    joints[:, 3:5] = knees
    joints[:, 5:7] = ankle_W
    hinge = np.cross(f, e)
    G_thigh = _aligning_rotation(J[3:5] - J[1:3], _unit(knees - hips), hinge)
    G_shank = _aligning_rotation(J[5:7] - J[3:5], _unit(ankle_W - knees), hinge)
    G_foot = R_WfromShoe @ R_PfromSMPL
    joints[:, 7:9] = ankle_W + np.einsum("nsij,sj->nsi", G_foot, J[7:9] - J[5:7])
    return joints, G_thigh, G_shank


def smpl_pose_from_chain(
    R_WfromP: np.ndarray, G_thigh: np.ndarray, G_shank: np.ndarray, R_WfromShoe: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``root_orient (n, 3)`` and ``joint_aa (n, 8, 3)`` (joints 1, 2, 4, 5, 7, 8, 10, 11)."""
    R_root = R_WfromP @ R_PfromSMPL
    G_foot = R_WfromShoe @ R_PfromSMPL
    Rt = np.swapaxes
    local_hip = Rt(R_root, -1, -2)[:, None] @ G_thigh
    local_knee = Rt(G_thigh, -1, -2) @ G_shank
    local_ankle = Rt(G_shank, -1, -2) @ G_foot
    aa = np.zeros((len(R_root), 8, 3))
    aa[:, 0:2] = so3_log(local_hip)
    aa[:, 2:4] = so3_log(local_knee)
    aa[:, 4:6] = so3_log(local_ankle)
    return so3_log(R_root), aa
