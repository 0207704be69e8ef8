"""Lower-body skeleton and forward kinematics (numpy and torch) in the SMPL convention."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation

from gaitnet.motion.skeleton import (
    N_JOINTS,
    PARENTS,
    SMPL_JOINT_INDICES,
    builtin_skeleton,
    forward_kinematics,
    forward_kinematics_torch,
    from_rest_joints,
)

# SMPL parents of the 24-joint body, to check our (9-joint) parent table against.
SMPL_PARENTS_24 = [-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19, 20, 21]


@pytest.fixture
def skel():
    return builtin_skeleton(1.75)


def _random_pose(rng: np.random.Generator, n: int, scale: float = 1.0):
    return (
        rng.normal(scale=scale, size=(n, 3)),
        rng.normal(size=(n, 3)),
        rng.normal(scale=scale, size=(n, 8, 3)),
    )


def _reference_fk(J: np.ndarray, root: np.ndarray, trans: np.ndarray, aa: np.ndarray) -> np.ndarray:
    """Independent FK: a per-joint chain of 4×4 homogeneous matrices (scipy rotations)."""
    T = [None] * N_JOINTS
    out = np.zeros((N_JOINTS, 3))
    for j in range(N_JOINTS):
        rotvec = root if j == 0 else aa[j - 1]
        local = np.eye(4)
        local[:3, :3] = Rotation.from_rotvec(rotvec).as_matrix()
        parent = PARENTS[j]
        local[:3, 3] = J[j] if parent < 0 else J[j] - J[parent]
        T[j] = local if parent < 0 else T[parent] @ local
        out[j] = T[j][:3, 3]
    return out + trans


def test_parent_table_matches_smpl():
    for j, smpl_j in enumerate(SMPL_JOINT_INDICES[1:], start=1):
        assert SMPL_JOINT_INDICES[PARENTS[j]] == SMPL_PARENTS_24[smpl_j]


def test_zero_pose_gives_rest_joints_plus_trans(skel):
    trans = np.array([0.3, -1.2, 2.0])
    out = forward_kinematics(skel, np.zeros(3), trans, np.zeros((8, 3)))
    np.testing.assert_allclose(out, skel.rest_joints + trans, atol=1e-15)


def test_matches_independent_homogeneous_chain(skel):
    rng = np.random.default_rng(0)
    root, trans, aa = _random_pose(rng, 20)
    out = forward_kinematics(skel, root, trans, aa)
    for i in range(20):
        ref = _reference_fk(skel.rest_joints, root[i], trans[i], aa[i])
        np.testing.assert_allclose(out[i], ref, atol=1e-12)


def test_bone_lengths_preserved(skel):
    rng = np.random.default_rng(1)
    out = forward_kinematics(skel, *_random_pose(rng, 50, scale=2.0))
    parents = np.array(PARENTS[1:])
    rest = np.linalg.norm(skel.rest_joints[1:] - skel.rest_joints[parents], axis=-1)
    posed = np.linalg.norm(out[:, 1:] - out[:, parents], axis=-1)
    np.testing.assert_allclose(posed, np.broadcast_to(rest, posed.shape), atol=1e-12)


def test_known_answer_hip_rotation_about_x(skel):
    """+90° about SMPL x (body-left) swings the straight thigh from down to backwards (−z)."""
    aa = np.zeros((8, 3))
    aa[0] = [np.pi / 2, 0.0, 0.0]  # L_hip
    out = forward_kinematics(skel, np.zeros(3), np.zeros(3), aa)
    J = skel.rest_joints
    thigh = skel.thigh_lengths[0]
    np.testing.assert_allclose(out[3], J[1] + [0.0, 0.0, -thigh], atol=1e-12)  # L_knee
    np.testing.assert_allclose(out[4], J[4], atol=1e-15)  # R_knee untouched
    aa[0] = [-np.pi / 2, 0.0, 0.0]  # hip flexion: the knee comes forward
    out = forward_kinematics(skel, np.zeros(3), np.zeros(3), aa)
    np.testing.assert_allclose(out[3], J[1] + [0.0, 0.0, thigh], atol=1e-12)


def test_root_orientation_maps_smpl_frame_to_world(skel):
    """Columns [0,1,0], [0,0,1], [1,0,0]: SMPL forward (z) → world x, up (y) → world z."""
    R_root = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    root = Rotation.from_matrix(R_root).as_rotvec()
    out = forward_kinematics(skel, root, -skel.rest_joints[0], np.zeros((8, 3)))
    assert out[1, 1] > 0 > out[2, 1]  # left hip at world +y
    assert np.all(out[5:7, 2] < out[3:5, 2])  # ankles below knees
    assert np.all(out[7:9, 0] > out[5:7, 0])  # feet joints in front of the ankles (+x)


def test_broadcasting_and_shapes(skel):
    rng = np.random.default_rng(2)
    root, trans, aa = _random_pose(rng, 6)
    out = forward_kinematics(skel, root.reshape(2, 3, 3), trans[0], aa.reshape(2, 3, 8, 3))
    assert out.shape == (2, 3, 9, 3)
    np.testing.assert_allclose(out.reshape(6, 9, 3), forward_kinematics(skel, root, trans[0], aa))
    with pytest.raises(ValueError):
        forward_kinematics(skel, root, trans, aa[:, :7])


@pytest.mark.parametrize("dtype,tol", [(torch.float64, 1e-12), (torch.float32, 2e-5)])
def test_torch_matches_numpy(skel, dtype, tol):
    rng = np.random.default_rng(3)
    root, trans, aa = _random_pose(rng, 32)
    ref = forward_kinematics(skel, root, trans, aa)
    out = forward_kinematics_torch(skel, *(torch.tensor(x, dtype=dtype) for x in (root, trans, aa)))
    assert out.dtype == dtype and out.shape == (32, 9, 3)
    np.testing.assert_allclose(out.double().numpy(), ref, atol=tol)


def test_torch_gradients_finite_at_zero_and_gradcheck(skel):
    zero = torch.zeros(4, 8, 3, dtype=torch.float64, requires_grad=True)
    out = forward_kinematics_torch(
        skel, torch.zeros(4, 3, dtype=torch.float64), torch.zeros(3), zero
    )
    out.sum().backward()
    assert torch.all(torch.isfinite(zero.grad)) and zero.grad.abs().sum() > 0
    rng = np.random.default_rng(4)
    args = tuple(
        torch.tensor(x, dtype=torch.float64, requires_grad=True) for x in _random_pose(rng, 2, 0.5)
    )
    assert torch.autograd.gradcheck(lambda r, t, a: forward_kinematics_torch(skel, r, t, a), args)


def test_torch_accepts_rest_joint_tensor(skel):
    J = torch.tensor(np.array(skel.rest_joints), requires_grad=True)
    aa = torch.zeros(8, 3, dtype=torch.float64)
    out = forward_kinematics_torch(J, torch.zeros(3, dtype=torch.float64), torch.zeros(3), aa)
    out[5, 1].backward()  # L_ankle height depends on the L_ankle rest joint, not the right one
    assert J.grad[5, 1] == 1.0 and J.grad[6, 1] == 0.0


def test_from_rest_joints_accepts_full_smpl_array(skel):
    full = np.zeros((24, 3))
    full[list(SMPL_JOINT_INDICES)] = skel.rest_joints
    np.testing.assert_array_equal(from_rest_joints(full).rest_joints, skel.rest_joints)
    np.testing.assert_array_equal(from_rest_joints(skel.rest_joints).rest_joints, skel.rest_joints)
    with pytest.raises(ValueError):
        from_rest_joints(np.zeros((8, 3)))
    with pytest.raises(ValueError):
        from_rest_joints(np.zeros((9, 3)))  # zero-length bones


def test_builtin_proportions():
    s = builtin_skeleton(1.80)
    assert s.thigh_lengths[0] == pytest.approx(0.245 * 1.80)
    assert s.shank_lengths[1] == pytest.approx(0.246 * 1.80)
    J = s.rest_joints
    assert J[1, 0] > 0 > J[2, 0]  # left hip on SMPL +x
    assert J[1, 0] - J[2, 0] == pytest.approx(0.10 * 1.8)
    assert J[0, 1] > J[1, 1] and J[0, 2] < J[1, 2]  # pelvis above and behind the hips
    assert J[7, 2] > J[5, 2] and J[7, 1] < J[5, 1]  # foot joint forward of and below the ankle
    s2 = builtin_skeleton(1.80, thigh_m=0.5, shank_m=0.4)
    assert s2.thigh_lengths == pytest.approx((0.5, 0.5))
    assert s2.shank_lengths == pytest.approx((0.4, 0.4))
