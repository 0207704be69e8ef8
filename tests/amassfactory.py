"""Tiny AMASS clips and SMPL-family body-model files with the real keys, written in tests."""

from __future__ import annotations

import pickle
from pathlib import Path

import numpy as np
import scipy.sparse

# SMPL's 24-joint kinematic tree (kintree_table[0]; the root's entry is 2**32 - 1 as in SMPL).
SMPL_PARENTS = [-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19, 20, 21]
# SMPL+H: 22 body joints then 15 joints per hand hanging off the wrists (20, 21).
SMPLH_PARENTS = SMPL_PARENTS[:22] + [20] * 15 + [21] * 15


def write_smplh_poses(
    path: Path,
    poses: np.ndarray,
    trans: np.ndarray,
    fps: float,
    *,
    betas: np.ndarray | None = None,
    gender: str = "female",
    drop: tuple[str, ...] = (),
) -> Path:
    """An AMASS SMPL+H G ``*_poses.npz``: poses (T, 156), trans, betas (16), dmpls (T, 8)."""
    T = poses.shape[0]
    data = {
        "poses": poses,
        "trans": trans,
        "betas": np.zeros(16) if betas is None else betas,
        "dmpls": np.zeros((T, 8)),
        "gender": np.array(gender),
        "mocap_framerate": np.array(float(fps)),
    }
    for key in drop:
        data.pop(key)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez(path, **data)
    return path


def write_smplx_stageii(
    path: Path,
    root_orient: np.ndarray,
    pose_body: np.ndarray,
    trans: np.ndarray,
    fps: float,
    *,
    betas: np.ndarray | None = None,
    gender: str = "male",
    drop: tuple[str, ...] = (),
) -> Path:
    """An AMASS SMPL-X ``*_stageii.npz`` with the keys MoSh++ writes (markers left out)."""
    T = root_orient.shape[0]
    data = {
        "gender": np.array(gender),
        "surface_model_type": np.array("smplx"),
        "mocap_frame_rate": np.array(float(fps)),
        "mocap_time_length": np.array((T - 1) / fps),
        "root_orient": root_orient,
        "pose_body": pose_body,
        "pose_hand": np.zeros((T, 90)),
        "pose_jaw": np.zeros((T, 3)),
        "pose_eye": np.zeros((T, 6)),
        "trans": trans,
        "betas": np.zeros(16) if betas is None else betas,
        "num_betas": np.array(16),
        "poses": np.concatenate([root_orient, pose_body, np.zeros((T, 99))], axis=1),
    }
    for key in drop:
        data.pop(key)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez(path, **data)
    return path


def walking_like_clip(
    T: int, fps: float, rng: np.random.Generator, yaw0: float = 0.3
) -> tuple[np.ndarray, np.ndarray]:
    """SMPL+H ``poses`` (T, 156) and ``trans`` of an upright body turning slowly, z-up world.

    The root is ``Rz(yaw) Rx(90°)`` (SMPL's y-up body stood up in AMASS's z-up world, facing
    −y at yaw 0), legs swing sinusoidally.
    """
    from scipy.spatial.transform import Rotation

    t = np.arange(T) / fps
    yaw = yaw0 + 0.2 * t
    root = Rotation.from_rotvec(yaw[:, None] * [0.0, 0.0, 1.0]) * Rotation.from_euler(
        "x", np.pi / 2
    )
    poses = np.zeros((T, 156))
    poses[:, :3] = root.as_rotvec()
    phase = 2 * np.pi * 1.0 * t
    for k, amp in ((1, 0.4), (2, -0.4), (4, 0.6), (5, 0.6), (7, 0.2), (8, 0.2)):
        poses[:, 3 * k] = amp * np.sin(phase + (np.pi if k % 2 == 0 else 0.0))
    poses[:, 3:66] += 0.01 * rng.normal(size=(T, 63))
    trans = np.stack([1.2 * t * np.sin(yaw), -1.2 * t * np.cos(yaw), 0.9 + 0 * t], axis=1)
    return poses, trans


def make_body_model(
    rng: np.random.Generator,
    *,
    n_verts: int = 300,
    parents: list[int] = SMPL_PARENTS,
    n_betas: int = 10,
) -> dict[str, np.ndarray]:
    """Arrays of a small SMPL-style model in smplx's key layout (random but well-formed)."""
    J = len(parents)
    # A rough standing body about 1.7 m tall: random points in a box, y up.
    v_template = rng.uniform([-0.25, -1.0, -0.12], [0.25, 0.7, 0.12], size=(n_verts, 3))
    shapedirs = 0.02 * rng.normal(size=(n_verts, 3, n_betas))
    # Each joint regresses from ~8 vertices with positive weights summing to one.
    J_regressor = np.zeros((J, n_verts))
    for j in range(J):
        idx = rng.choice(n_verts, size=8, replace=False)
        w = rng.uniform(0.1, 1.0, size=8)
        J_regressor[j, idx] = w / w.sum()
    weights = rng.uniform(size=(n_verts, J))
    weights /= weights.sum(axis=1, keepdims=True)
    kintree = np.array([[2**32 - 1, *parents[1:]], list(range(J))], dtype=np.uint32)
    return {
        "v_template": v_template,
        "shapedirs": shapedirs,
        "J_regressor": J_regressor,
        "kintree_table": kintree,
        "weights": weights,
        "posedirs": 1e-3 * rng.normal(size=(n_verts, 3, 9 * (J - 1))),
        "f": rng.integers(0, n_verts, size=(2 * n_verts, 3)).astype(np.uint32),
    }


def write_model_npz(path: Path, model: dict[str, np.ndarray]) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez(path, **model)
    return path


def write_model_pkl(path: Path, model: dict[str, np.ndarray], *, sparse_regressor: bool) -> Path:
    """A chumpy-free pickle as smplx reads it (SMPL ships ``J_regressor`` as a csc matrix)."""
    data = dict(model)
    if sparse_regressor:
        data["J_regressor"] = scipy.sparse.csc_matrix(model["J_regressor"])
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "wb") as handle:
        pickle.dump(data, handle, protocol=2)
    return path


def write_chumpy_pickle(path: Path) -> Path:
    """A pickle that references ``chumpy.ch.Ch`` like the old SMPL releases (chumpy not needed)."""
    # PROTO 2, GLOBAL 'chumpy.ch Ch', EMPTY_TUPLE, NEWOBJ, STOP
    path.write_bytes(b"\x80\x02cchumpy.ch\nCh\n)\x81.")
    return path
