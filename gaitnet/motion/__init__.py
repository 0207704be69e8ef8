"""Lower-body motion: SMPL-convention skeleton and forward kinematics, motion prediction.

The numpy kinematics are re-exported here; torch-based modules (``gcn``, ``dct``) and
:func:`gaitnet.motion.skeleton.forward_kinematics_torch` import torch only when used.
"""

from gaitnet.motion.skeleton import (
    JOINT_NAMES,
    N_JOINTS,
    N_ROTATED,
    PARENTS,
    ROTATED_SMPL_INDICES,
    SMPL_JOINT_INDICES,
    LowerBodySkeleton,
    builtin_skeleton,
    forward_kinematics,
    from_rest_joints,
)

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
    "from_rest_joints",
]
