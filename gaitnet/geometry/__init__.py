"""Geometry: quaternions, SO(3)/SE(3), pinhole camera, and differentiable torch rotations.

Conventions (see :mod:`gaitnet.geometry.quaternion` for the full statement):

* Quaternions are numpy arrays ``[w, x, y, z]`` (scalar first), Hamilton product.
* ``rotmat_from_quat(q) = R(q)``: active rotation, body-to-world, ``v_W = R v_B``,
  ``R(p ⊗ q) = R(p) R(q)``; equals scipy's ``Rotation.from_quat([x, y, z, w]).as_matrix()``.
* ``dcm_from_quat(q) = C(q) = R(q).T``: the thesis (D.-C. Dang) world-to-body direction cosine
  matrix, ``v_B = C v_W``, ``C(p ⊗ q) = C(q) C(p)``.
* Error state (thesis eq. (3.1)): ``q = q̂ ⊗ f_quat(q̄_e)``, ``dtheta = 2 q̄_e``,
  ``C(q) ≈ (I - 2[q̄_e×]) C(q̂)`` — :func:`quat_boxplus` / :func:`quat_boxminus`.
* TUM rows ``(tx ty tz qx qy qz qw)`` hold ``T_WfromS`` with the active ``R_WfromS`` quaternion in
  scalar-last order — :func:`tum_from_T` / :func:`T_from_tum`.
* Camera frame is OpenCV's (x right, y down, z forward).

The torch functions live in :mod:`gaitnet.geometry.torch_rotations` and are not re-exported
here, so importing the numpy geometry does not import torch.
"""

from gaitnet.geometry.camera import backproject, depth_to_points, project, projection_jacobian
from gaitnet.geometry.quaternion import (
    axis_angle_from_quat,
    dcm_from_quat,
    f_quat,
    quat_boxminus,
    quat_boxplus,
    quat_conjugate,
    quat_from_axis_angle,
    quat_from_dcm,
    quat_from_rotmat,
    quat_from_rotvec,
    quat_identity,
    quat_interpolate,
    quat_inverse,
    quat_make_continuous,
    quat_multiply,
    quat_normalize,
    quat_positive,
    quat_slerp,
    quat_wxyz_from_xyzw,
    quat_xyzw_from_wxyz,
    rotate_body_to_world,
    rotate_world_to_body,
    rotmat_from_quat,
    rotvec_from_quat,
)
from gaitnet.geometry.rotation import (
    skew,
    so3_exp,
    so3_left_jacobian,
    so3_left_jacobian_inv,
    so3_log,
    so3_right_jacobian,
    so3_right_jacobian_inv,
    unskew,
)
from gaitnet.geometry.se3 import (
    T_from_tum,
    compose,
    interpolate_poses,
    invert_T,
    make_T,
    se3_exp,
    se3_log,
    transform_points,
    tum_from_T,
)

__all__ = [
    "T_from_tum",
    "axis_angle_from_quat",
    "backproject",
    "compose",
    "dcm_from_quat",
    "depth_to_points",
    "f_quat",
    "interpolate_poses",
    "invert_T",
    "make_T",
    "project",
    "projection_jacobian",
    "quat_boxminus",
    "quat_boxplus",
    "quat_conjugate",
    "quat_from_axis_angle",
    "quat_from_dcm",
    "quat_from_rotmat",
    "quat_from_rotvec",
    "quat_identity",
    "quat_interpolate",
    "quat_inverse",
    "quat_make_continuous",
    "quat_multiply",
    "quat_normalize",
    "quat_positive",
    "quat_slerp",
    "quat_wxyz_from_xyzw",
    "quat_xyzw_from_wxyz",
    "rotate_body_to_world",
    "rotate_world_to_body",
    "rotmat_from_quat",
    "rotvec_from_quat",
    "se3_exp",
    "se3_log",
    "skew",
    "so3_exp",
    "so3_left_jacobian",
    "so3_left_jacobian_inv",
    "so3_log",
    "so3_right_jacobian",
    "so3_right_jacobian_inv",
    "transform_points",
    "tum_from_T",
    "unskew",
]
