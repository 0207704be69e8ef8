"""Lower-body skeleton in the SMPL convention and its forward kinematics (numpy and torch).

Joints (SMPL indices and names, docs/design.md): pelvis 0, L_hip 1, R_hip 2, L_knee 4, R_knee 5,
L_ankle 7, R_ankle 8, L_foot 10, R_foot 11. Arrays of joints here always hold them in the order
of :data:`SMPL_JOINT_INDICES`; "local" index ``i`` means position ``i`` in that order.

Convention (identical to ``smplx``'s ``batch_rigid_transform`` followed by ``+ transl``):
rest joints ``J`` live in SMPL's canonical body frame (y up, z forward/facing, x to the body's
LEFT). Each joint ``k`` has a local rotation ``R_k`` (axis-angle) relative to its parent; the
root's is ``root_orient``. Global rotations ``G_0 = R_root``, ``G_k = G_parent(k) R_k``; posed
joints ``p_0 = J_0 + trans``, ``p_k = p_parent(k) + G_parent(k) (J_k − J_parent(k))``.

With SMPL's axes a positive rotation about +x (body-left) swings a bone that points down
(−y) backwards (−z): hip extension / knee flexion. Hip flexion is a negative x rotation.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gaitnet.geometry import so3_exp

if TYPE_CHECKING:
    import torch

FloatArray = NDArray[np.float64]

__all__ = [
    "JOINT_NAMES",
    "N_JOINTS",
    "N_ROTATED",
    "PARENTS",
    "ROTATED_SMPL_INDICES",
    "SMPL_JOINT_INDICES",
    "LowerBodySkeleton",
    "builtin_skeleton",
    "forward_kinematics",
    "forward_kinematics_torch",
    "from_rest_joints",
]

SMPL_JOINT_INDICES: tuple[int, ...] = (0, 1, 2, 4, 5, 7, 8, 10, 11)
JOINT_NAMES: tuple[str, ...] = (
    "pelvis",
    "L_hip",
    "R_hip",
    "L_knee",
    "R_knee",
    "L_ankle",
    "R_ankle",
    "L_foot",
    "R_foot",
)
# Parent of each joint as a local index (−1: root).
PARENTS: tuple[int, ...] = (-1, 0, 0, 1, 2, 3, 4, 5, 6)
# SMPL indices of the joints whose local rotations ``joint_aa`` holds, in that order.
ROTATED_SMPL_INDICES: tuple[int, ...] = (1, 2, 4, 5, 7, 8, 10, 11)
N_JOINTS = len(SMPL_JOINT_INDICES)
N_ROTATED = len(ROTATED_SMPL_INDICES)

# Chain levels: children (local indices) at each depth; joint_aa row of joint j is j − 1.
_LEVELS: tuple[tuple[int, int], ...] = ((1, 2), (3, 4), (5, 6), (7, 8))


@dataclass(frozen=True, eq=False)
class LowerBodySkeleton:
    """Rest joints ``(9, 3)`` [m] in SMPL's canonical frame, order :data:`SMPL_JOINT_INDICES`."""

    rest_joints: FloatArray

    def __post_init__(self) -> None:
        J = np.array(self.rest_joints, dtype=np.float64)
        if J.shape != (N_JOINTS, 3):
            raise ValueError(f"rest_joints must have shape ({N_JOINTS}, 3), got {J.shape}")
        if not np.all(np.isfinite(J)):
            raise ValueError("rest_joints must be finite")
        bones = np.linalg.norm(J[1:] - J[np.array(PARENTS[1:])], axis=-1)
        if np.any(bones < 1e-4):
            raise ValueError("rest_joints has a zero-length bone")
        J.setflags(write=False)
        object.__setattr__(self, "rest_joints", J)

    @property
    def offsets(self) -> FloatArray:
        """``J_k − J_parent(k)`` (9, 3); the root row is ``J_0``."""
        J = self.rest_joints
        off = J - J[np.array([0, *PARENTS[1:]])]
        off[0] = J[0]
        return off

    @property
    def thigh_lengths(self) -> tuple[float, float]:
        """Hip→knee lengths (left, right) [m]."""
        return self._bone(3), self._bone(4)

    @property
    def shank_lengths(self) -> tuple[float, float]:
        """Knee→ankle lengths (left, right) [m]."""
        return self._bone(5), self._bone(6)

    def _bone(self, j: int) -> float:
        return float(np.linalg.norm(self.rest_joints[j] - self.rest_joints[PARENTS[j]]))

    def to_smpl_array(self, n_smpl_joints: int = 24) -> FloatArray:
        """Rest joints scattered into an ``(n_smpl_joints, 3)`` array (others NaN)."""
        out = np.full((n_smpl_joints, 3), np.nan)
        out[list(SMPL_JOINT_INDICES)] = self.rest_joints
        return out


def from_rest_joints(joints: ArrayLike) -> LowerBodySkeleton:
    """Skeleton from rest joints: ``(9, 3)`` in our order, or a full SMPL ``(≥12, 3)`` array."""
    J = np.asarray(joints, dtype=np.float64)
    if J.ndim == 2 and J.shape[0] >= 12 and J.shape[1] == 3:
        J = J[list(SMPL_JOINT_INDICES)]
    return LowerBodySkeleton(J)


def builtin_skeleton(
    height_m: float,
    *,
    thigh_m: float | None = None,
    shank_m: float | None = None,
    hip_width_m: float | None = None,
    ankle_height_m: float | None = None,
    pelvis_above_hip_m: float | None = None,
    pelvis_behind_hip_m: float | None = None,
    foot_joint_forward_m: float | None = None,
    foot_joint_height_m: float | None = None,
) -> LowerBodySkeleton:
    """Anthropometric skeleton (Winter's ratios) standing upright with straight legs.

    Defaults as fractions of ``height_m``: thigh 0.245, shank 0.246, hip-joint separation
    0.10, ankle height 0.039, pelvis joint 0.05 above and 0.006 behind the hip joints (like
    SMPL's template), foot joint (SMPL L_foot, near the ball of the foot) 0.079 in front of
    the ankle and 0.012 above the sole. Give explicit lengths so a simulated subject and the
    FK agree exactly. Rest pelvis joint at the origin; barefoot sole at
    ``y = −(pelvis_above_hip + thigh + shank + ankle_height)``.
    """
    H = float(height_m)
    if not 0.5 <= H <= 2.5:
        raise ValueError(f"height_m must be a plausible body height, got {H}")
    thigh = 0.245 * H if thigh_m is None else float(thigh_m)
    shank = 0.246 * H if shank_m is None else float(shank_m)
    hip_w = 0.10 * H if hip_width_m is None else float(hip_width_m)
    ankle_h = 0.039 * H if ankle_height_m is None else float(ankle_height_m)
    up = 0.05 * H if pelvis_above_hip_m is None else float(pelvis_above_hip_m)
    back = 0.006 * H if pelvis_behind_hip_m is None else float(pelvis_behind_hip_m)
    fwd = 0.079 * H if foot_joint_forward_m is None else float(foot_joint_forward_m)
    foot_h = 0.012 * H if foot_joint_height_m is None else float(foot_joint_height_m)
    if min(thigh, shank, hip_w, ankle_h, fwd) <= 0 or not 0 <= foot_h < ankle_h:
        raise ValueError("segment lengths must be positive and the foot joint below the ankle")
    J = np.zeros((N_JOINTS, 3))
    for side, sign in ((0, 1.0), (1, -1.0)):  # left is +x in SMPL's canonical frame
        hip = np.array([sign * hip_w / 2, -up, back])
        knee = hip + [0.0, -thigh, 0.0]
        ankle = knee + [0.0, -shank, 0.0]
        foot = ankle + [0.0, -(ankle_h - foot_h), fwd]
        J[1 + side], J[3 + side], J[5 + side], J[7 + side] = hip, knee, ankle, foot
    return LowerBodySkeleton(J)


def _check_pose_shapes(root: tuple[int, ...], trans: tuple[int, ...], aa: tuple[int, ...]) -> None:
    if root[-1:] != (3,) or trans[-1:] != (3,) or aa[-2:] != (N_ROTATED, 3):
        raise ValueError(
            f"expected root_orient (...,3), trans (...,3), joint_aa (...,{N_ROTATED},3); "
            f"got {root}, {trans}, {aa}"
        )


def forward_kinematics(
    skel: LowerBodySkeleton, root_orient: ArrayLike, trans: ArrayLike, joint_aa: ArrayLike
) -> FloatArray:
    """World joint positions ``(..., 9, 3)`` (float64) of a batch of SMPL-style poses.

    ``root_orient`` (..., 3) and ``joint_aa`` (..., 8, 3) are axis-angle rotations (the latter
    for SMPL joints :data:`ROTATED_SMPL_INDICES`), ``trans`` (..., 3) the SMPL translation.
    """
    root = np.asarray(root_orient, dtype=np.float64)
    t = np.asarray(trans, dtype=np.float64)
    aa = np.asarray(joint_aa, dtype=np.float64)
    _check_pose_shapes(root.shape, t.shape, aa.shape)
    batch = np.broadcast_shapes(root.shape[:-1], t.shape[:-1], aa.shape[:-2])
    R_local = so3_exp(aa)  # (..., 8, 3, 3)
    off = skel.offsets
    G_pair = np.broadcast_to(so3_exp(root)[..., None, :, :], (*batch, 2, 3, 3))
    p0 = np.broadcast_to(skel.rest_joints[0] + t, (*batch, 3))
    p_pair = np.broadcast_to(p0[..., None, :], (*batch, 2, 3))
    out = [p0[..., None, :]]
    for a, b in _LEVELS:
        p_pair = p_pair + np.einsum("...ij,...j->...i", G_pair, off[a : b + 1])
        out.append(p_pair)
        G_pair = G_pair @ np.broadcast_to(R_local[..., a - 1 : b, :, :], (*batch, 2, 3, 3))
    return np.concatenate(out, axis=-2)


def forward_kinematics_torch(
    skel: LowerBodySkeleton | torch.Tensor,
    root_orient: torch.Tensor,
    trans: torch.Tensor,
    joint_aa: torch.Tensor,
) -> torch.Tensor:
    """Differentiable torch twin of :func:`forward_kinematics`: joints ``(..., 9, 3)``.

    ``skel`` may also be a rest-joint tensor ``(9, 3)`` (e.g. to optimise bone lengths) or a
    batch of them ``(..., 9, 3)`` whose leading axes broadcast with the poses' (one skeleton per
    clip or window). The output has the dtype/device of ``joint_aa``. torch is imported here,
    not at module load.
    """
    import torch

    from gaitnet.geometry.torch_rotations import so3_exp_torch

    _check_pose_shapes(tuple(root_orient.shape), tuple(trans.shape), tuple(joint_aa.shape))
    dtype, device = joint_aa.dtype, joint_aa.device
    if isinstance(skel, LowerBodySkeleton):
        J = torch.tensor(np.array(skel.rest_joints), dtype=dtype, device=device)
    else:
        J = skel.to(dtype=dtype, device=device)
        if J.shape[-2:] != (N_JOINTS, 3):
            raise ValueError(f"rest joints must have shape (..., {N_JOINTS}, 3), got {J.shape}")
    parents = torch.tensor([0, *PARENTS[1:]], device=device)
    off = J - J[..., parents, :]
    batch = torch.broadcast_shapes(
        root_orient.shape[:-1], trans.shape[:-1], joint_aa.shape[:-2], J.shape[:-2]
    )
    R_local = so3_exp_torch(joint_aa)
    G_pair = so3_exp_torch(root_orient)[..., None, :, :].expand(*batch, 2, 3, 3)
    p0 = (J[..., 0, :] + trans).expand(*batch, 3)
    p_pair = p0[..., None, :].expand(*batch, 2, 3)
    out = [p0[..., None, :]]
    for a, b in _LEVELS:
        p_pair = p_pair + (G_pair @ off[..., a : b + 1, :, None])[..., 0]
        out.append(p_pair)
        G_pair = G_pair @ R_local[..., a - 1 : b, :, :].expand(*batch, 2, 3, 3)
    return torch.cat(out, dim=-2)
