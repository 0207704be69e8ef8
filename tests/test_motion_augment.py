"""Augmentation keeps kinematics: mirror images (FK), time scaling, appended copies."""

from __future__ import annotations

import numpy as np
import pytest

from gaitnet.motion.amass import MotionClip
from gaitnet.motion.augment import (
    MIRROR_WORLD,
    augment_split,
    find_loop,
    loop_clip,
    mirror_clip,
    mirror_rest_joints,
    mirror_rotations,
    time_scale_clip,
)
from gaitnet.motion.heading import heading_angle
from gaitnet.motion.prepared import PreparedWalking
from gaitnet.motion.skeleton import LowerBodySkeleton, builtin_skeleton, forward_kinematics

#: L/R swap of the 9 skeleton joints (pelvis, L/R hip, knee, ankle, foot), written out here.
SWAP = [0, 2, 1, 4, 3, 6, 5, 8, 7]
#: Upright, facing +x: 120° about (1, 1, 1)/√3 (columns [0,1,0], [0,0,1], [1,0,0]).
UPRIGHT_FACING_X = np.full(3, 2 * np.pi / 3 / np.sqrt(3))


def _asymmetric_skeleton(rng: np.random.Generator) -> LowerBodySkeleton:
    J = builtin_skeleton(1.7).rest_joints.copy()
    J[1:] += rng.normal(0.0, 0.02, size=(8, 3))  # left and right differ; pelvis at the origin
    return LowerBodySkeleton(J)


def test_mirrored_pose_gives_mirrored_joint_positions() -> None:
    rng = np.random.default_rng(0)
    skel = _asymmetric_skeleton(rng)
    root, aa = rng.normal(0, 1.0, (50, 3)), rng.normal(0, 0.6, (50, 8, 3))
    trans = rng.normal(0, 1.0, (50, 3))
    joints = forward_kinematics(skel, root, trans, aa)
    root_m, aa_m = mirror_rotations(root, aa)
    mirrored = LowerBodySkeleton(mirror_rest_joints(skel.rest_joints))
    joints_m = forward_kinematics(mirrored, root_m, trans @ MIRROR_WORLD.T, aa_m)
    expected = (joints @ MIRROR_WORLD.T)[:, SWAP]  # y → −y in the world, left ↔ right
    np.testing.assert_allclose(joints_m, expected, atol=1e-12)


def test_mirror_is_an_involution_and_keeps_an_upright_body_facing_x() -> None:
    rng = np.random.default_rng(1)
    root, aa = rng.normal(0, 1.0, (20, 3)), rng.normal(0, 0.6, (20, 8, 3))
    back_root, back_aa = mirror_rotations(*mirror_rotations(root, aa))
    skel = builtin_skeleton(1.8)
    np.testing.assert_allclose(
        forward_kinematics(skel, back_root, np.zeros(3), back_aa),
        forward_kinematics(skel, root, np.zeros(3), aa),
        atol=1e-12,
    )
    up, _ = mirror_rotations(UPRIGHT_FACING_X, np.zeros((8, 3)))
    np.testing.assert_allclose(up, UPRIGHT_FACING_X, atol=1e-6)
    # a body turned 30° left of +x faces 30° right after mirroring
    yaw = np.radians(30.0)
    from scipy.spatial.transform import Rotation

    turned = (
        Rotation.from_rotvec([0, 0, yaw]) * Rotation.from_rotvec(UPRIGHT_FACING_X)
    ).as_rotvec()
    m, _ = mirror_rotations(turned, np.zeros((8, 3)))
    assert heading_angle(m) == pytest.approx(-yaw, abs=1e-9)


def _clip(n: int = 61, fps: float = 30.0, rest: bool = True) -> MotionClip:
    t = np.arange(n) / fps
    aa = np.zeros((n, 8, 3))
    aa[:, 2, 0] = 0.5 + 0.4 * np.sin(2 * np.pi * t)  # left knee
    trans = np.stack([1.2 * t, 0.1 * t, 0.9 + 0 * t], axis=1)
    return MotionClip(
        name="c", dataset="D", fps=fps, root_orient=np.tile(UPRIGHT_FACING_X, (n, 1)),
        joint_aa=aa, trans=trans, betas=np.zeros(4), gender="neutral", source_fps=120.0,
        rest_joints=builtin_skeleton(1.6).rest_joints if rest else None,
    )  # fmt: skip


def test_mirror_clip_swaps_legs_and_mirrors_the_path() -> None:
    clip = _clip()
    m = mirror_clip(clip)
    np.testing.assert_allclose(m.joint_aa[:, 3, 0], clip.joint_aa[:, 2, 0])  # right knee now
    assert not np.any(m.joint_aa[:, 2])
    np.testing.assert_allclose(m.trans[:, 1], -clip.trans[:, 1])
    np.testing.assert_allclose(m.rest_joints, mirror_rest_joints(clip.rest_joints))
    assert m.name == "c#mirror"


def test_time_scaling_plays_the_same_poses_faster() -> None:
    clip = _clip(n=61)
    fast = time_scale_clip(clip, 2.0)  # integer ratio: frame n is the original frame 2n
    assert fast.fps == 30.0 and fast.n_frames == 31
    np.testing.assert_allclose(fast.joint_aa, clip.joint_aa[::2], atol=1e-9)
    np.testing.assert_allclose(np.diff(fast.trans[:, 0]) * 30.0, 2.4, atol=1e-9)  # 2 × speed
    slow = time_scale_clip(clip, 0.5)
    assert slow.n_frames == 121
    np.testing.assert_allclose(slow.joint_aa[::2], clip.joint_aa, atol=1e-9)
    with pytest.raises(ValueError, match="time-scale"):
        time_scale_clip(clip, 0.0)


def _gait_clip(n: int, drift: float = 0.0) -> MotionClip:
    """A walk whose legs repeat every second (30 frames), walking +x at 1.2 m/s; ``drift``
    adds a slow change of knee flexion, heading and pelvis height the loop must take off."""
    from scipy.spatial.transform import Rotation

    t = np.arange(n) / 30.0
    aa = np.zeros((n, 8, 3))
    aa[:, 0, 0] = 0.4 * np.sin(2 * np.pi * t)  # hips
    aa[:, 1, 0] = -0.4 * np.sin(2 * np.pi * t)
    aa[:, 2, 0] = 0.6 + 0.5 * np.sin(2 * np.pi * t + 1.0) + drift * t  # knees
    aa[:, 3, 0] = 0.6 + 0.5 * np.sin(2 * np.pi * t + 1.0 + np.pi)
    root = (
        Rotation.from_rotvec(np.outer(drift * t, [0.0, 0.0, 1.0]))
        * Rotation.from_rotvec(UPRIGHT_FACING_X)
    ).as_rotvec()
    trans = np.stack([1.2 * t, 0 * t, 0.9 + 0.02 * np.cos(4 * np.pi * t) + drift * t], axis=1)
    return MotionClip(
        name="g", dataset="D", fps=30.0, root_orient=root, joint_aa=aa, trans=trans,
        betas=np.zeros(4), gender="neutral", source_fps=30.0,
        rest_joints=builtin_skeleton(1.7).rest_joints,
    )  # fmt: skip


def test_a_periodic_walk_loops_into_its_own_continuation() -> None:
    """Known answer: a clip of a walk that repeats every second, looped, is the same walk
    played for longer (frame ``i + k`` of the long walk, to 1e-9)."""
    short, long = _gait_clip(61), _gait_clip(400)
    i, j = find_loop(short)
    assert (j - i) % 30 == 0 and j - i >= 27  # whole cycles, at least 0.9 s
    looped = loop_clip(short, 10.0)
    assert looped.n_frames == 301 and looped.name == "g#loop10s"
    np.testing.assert_allclose(looped.joint_aa, long.joint_aa[i : i + 301], atol=1e-9)
    np.testing.assert_allclose(looped.root_orient, long.root_orient[i : i + 301], atol=1e-9)
    np.testing.assert_allclose(looped.trans, long.trans[i : i + 301], atol=1e-9)


def test_a_drifting_walk_loops_without_a_jump_at_the_seams() -> None:
    """Heading, knee and pelvis-height drift are taken off within each loop: the joints move
    no more from one frame to the next across a seam than inside the clip, and the walk
    goes on straight at the clip's speed."""
    clip = _gait_clip(61, drift=0.15)
    skel = builtin_skeleton(1.7)
    inside = np.linalg.norm(
        np.diff(forward_kinematics(skel, clip.root_orient, clip.trans, clip.joint_aa), axis=0),
        axis=-1,
    ).max()
    looped = loop_clip(clip, 8.0)
    joints = forward_kinematics(skel, looped.root_orient, looped.trans, looped.joint_aa)
    assert np.linalg.norm(np.diff(joints, axis=0), axis=-1).max() < 1.05 * inside
    np.testing.assert_allclose((looped.trans[-1, 0] - looped.trans[0, 0]) / 8.0, 1.2, rtol=0.02)
    assert abs(looped.trans[-1, 1]) < 1e-6
    assert np.ptp(looped.trans[:, 2]) < 0.05  # the height's drift does not pile up


def test_a_clip_shorter_than_a_loop_is_refused() -> None:
    with pytest.raises(ValueError, match="too short to loop"):
        loop_clip(_gait_clip(20), 5.0)


def _prepared(clips: list[MotionClip], splits: list[str]) -> PreparedWalking:
    off = np.concatenate([[0], np.cumsum([c.n_frames for c in clips])])
    return PreparedWalking(
        path=None, fps=30.0,  # type: ignore[arg-type]
        clip_name=np.array([c.name for c in clips]), clip_dataset=np.array(["D"] * len(clips)),
        clip_split=np.array(splits), clip_gender=np.array(["neutral"] * len(clips)),
        clip_source_fps=np.full(len(clips), 120.0), clip_offset=off,
        betas=np.zeros((len(clips), 4), np.float32),
        root_orient=np.concatenate([c.root_orient for c in clips]).astype(np.float32),
        joint_aa=np.concatenate([c.joint_aa for c in clips]).astype(np.float32),
        trans=np.concatenate([c.trans for c in clips]).astype(np.float32),
    )  # fmt: skip


def test_augment_split_appends_copies_of_the_training_clips_only() -> None:
    prepared = _prepared([_clip(), _clip(n=40)], ["train", "val"])
    out = augment_split(prepared, "train", mirror=True, time_scales=(0.5, 2.0))
    # train clip: original, mirror, and each of both at ×0.5 and ×2 → 6; the val clip untouched
    assert list(out.clip_split) == ["train", "val", *["train"] * 4 + ["train"]]
    assert sorted(out.clip_name[2:].tolist()) == sorted(
        ["c#mirror", "c#x0.5", "c#mirror#x0.5", "c#x2", "c#mirror#x2"]
    )
    lengths = np.diff(out.clip_offset)
    assert lengths[:2].tolist() == [61, 40] and sorted(lengths[2:].tolist()) == [
        31,
        31,
        61,
        121,
        121,
    ]
    np.testing.assert_array_equal(out.joint_aa[:101], prepared.joint_aa)  # originals unchanged
    assert out.clip_has_rest_joints is not None
    assert not out.clip_has_rest_joints.any()  # the prepared file had no rest joints
    assert augment_split(prepared, "train") is prepared  # nothing asked: nothing appended
