"""Kinematics-preserving augmentation of motion clips for the predictor's training (issue 12).

* :func:`mirror_clip`: the left/right mirror image of a clip. The world is reflected across its
  x–z plane, ``M_w = diag(1, −1, 1)`` (z up), and the body across its sagittal plane,
  ``M_b = diag(−1, 1, 1)`` in SMPL's canonical frame (x is the body's left). A rotation ``R``
  of a proper frame becomes ``M R M`` under a reflection ``M``; for the local joint rotations
  (body frame on both sides) that is ``M_b R M_b``, whose axis-angle is ``−M_b ω = (ω_x, −ω_y,
  −ω_z)``, and the left and right joints swap places; the root orientation (world from
  pelvis) becomes ``M_w R M_b`` (an upright body facing +x stays upright facing +x);
  ``trans`` becomes ``M_w trans`` and the rest joints ``M_b J`` with left and right swapped.
  Forward kinematics of the mirrored clip on the mirrored skeleton gives ``M_w`` times the
  joints of the original with left and right swapped, plus the constant
  ``(M_w − M_b) J_pelvis`` (zero when the rest pelvis is the origin, as in the simulator's
  skeleton; the predictor never sees positions, only rotations): tested.
* :func:`time_scale_clip`: the clip played ``factor`` times faster (or slower), resampled by
  time at its own rate with the loader's slerp (:func:`gaitnet.motion.amass.resample_clip`):
  the same poses in the same order, only the speed of the motion changes.
* :func:`loop_clip`: a longer walk made of the clip's own gait cycles played again and again
  (:func:`find_loop`); for trying long sessions on real motion that was captured in short
  pieces, never for training.
* :func:`augment_split`: a prepared file with the mirrored and time-scaled copies of every
  clip of one split appended (same sub-dataset and split, names tagged ``#mirror`` /
  ``#x1.2``).

Input noise (small Gaussian noise on the observed poses only, never on the targets) is applied
per batch in ``train/predictor.py``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from gaitnet.geometry import so3_exp, so3_log
from gaitnet.motion.amass import MotionClip, resample_clip
from gaitnet.motion.prepared import PreparedWalking
from gaitnet.motion.skeleton import JOINT_NAMES, ROTATED_SMPL_INDICES

__all__ = [
    "MIRROR_BODY",
    "MIRROR_WORLD",
    "augment_split",
    "find_loop",
    "loop_clip",
    "mirror_clip",
    "mirror_rest_joints",
    "mirror_rotations",
    "time_scale_clip",
]

#: Reflection of the world across its x–z plane (z up; after heading normalisation the body
#: faces +x, so this is its sagittal plane).
MIRROR_WORLD = np.diag([1.0, -1.0, 1.0])
#: Reflection of SMPL's canonical body frame across its sagittal plane (x is the body's left).
MIRROR_BODY = np.diag([-1.0, 1.0, 1.0])
#: ``joint_aa`` rows (SMPL 1, 2, 4, 5, 7, 8, 10, 11) after swapping left and right.
_SWAP_ROTATED = (1, 0, 3, 2, 5, 4, 7, 6)
#: Rows of the 9 skeleton joints (pelvis, L/R hip, knee, ankle, foot) after the swap.
_SWAP_JOINTS = (0, 2, 1, 4, 3, 6, 5, 8, 7)
assert len(_SWAP_ROTATED) == len(ROTATED_SMPL_INDICES) and len(_SWAP_JOINTS) == len(JOINT_NAMES)


def mirror_rotations(root_orient: np.ndarray, joint_aa: np.ndarray) -> tuple[np.ndarray, ...]:
    """Mirrored ``root_orient`` (..., 3) and ``joint_aa`` (..., 8, 3) (module docstring)."""
    root = so3_log(MIRROR_WORLD @ so3_exp(np.asarray(root_orient, np.float64)) @ MIRROR_BODY)
    aa = np.asarray(joint_aa, dtype=np.float64)[..., list(_SWAP_ROTATED), :]
    aa = aa * np.array([1.0, -1.0, -1.0])
    return root, aa


def mirror_rest_joints(rest_joints: np.ndarray) -> np.ndarray:
    """Mirrored rest joints (9, 3): ``M_b J`` with left and right swapped."""
    J = np.asarray(rest_joints, dtype=np.float64) @ MIRROR_BODY.T
    return J[list(_SWAP_JOINTS)]


def mirror_clip(clip: MotionClip) -> MotionClip:
    """The left/right mirror image of ``clip`` (its rest joints mirrored too, if it has them)."""
    root, aa = mirror_rotations(clip.root_orient, clip.joint_aa)
    rest = None if clip.rest_joints is None else mirror_rest_joints(clip.rest_joints)
    return replace(
        clip,
        name=f"{clip.name}#mirror",
        root_orient=root,
        joint_aa=aa,
        trans=np.asarray(clip.trans, dtype=np.float64) @ MIRROR_WORLD.T,
        rest_joints=rest,
    )


def time_scale_clip(clip: MotionClip, factor: float) -> MotionClip:
    """``clip`` played ``factor`` times as fast, at its own frame rate (slerp by time)."""
    if not (np.isfinite(factor) and 0.25 <= factor <= 4.0):
        raise ValueError(f"time-scale factor must be in [0.25, 4], got {factor}")
    faster = resample_clip(replace(clip, fps=clip.fps * float(factor)), clip.fps)
    return replace(faster, name=f"{clip.name}#x{factor:g}", source_fps=clip.source_fps)


def _pose_distance(clip: MotionClip) -> np.ndarray:
    """(T, T) squared distance between the clip's poses: joint axis-angles [rad²], the
    root's tilt and yaw rate left aside (the pair's root difference is removed by the loop)."""
    aa = np.asarray(clip.joint_aa, dtype=np.float64).reshape(clip.n_frames, -1)
    sq = np.sum(aa**2, axis=1)
    return np.maximum(sq[:, None] + sq[None, :] - 2.0 * aa @ aa.T, 0.0)


def find_loop(clip: MotionClip, min_loop_s: float = 0.9) -> tuple[int, int]:
    """Frames ``(i, j)``, ``j − i`` at least ``min_loop_s``, whose joint rotations agree best:
    the clip's frames ``i … j − 1`` repeat as a whole number of gait cycles. Among pairs whose
    mismatch is within 1.5 times the best, the longest loop is taken (more of the clip's
    own step-to-step variation)."""
    n_min = int(np.ceil(min_loop_s * clip.fps))
    if clip.n_frames <= n_min + 1:
        raise ValueError(
            f"{clip.name}: {clip.duration_s:.2f} s is too short to loop "
            f"(a loop holds at least {min_loop_s:g} s)"
        )
    dist = _pose_distance(clip)
    i, j = np.triu_indices(clip.n_frames, k=n_min)
    cost = dist[i, j]
    near_best = cost <= 1.5 * cost.min() + 1e-12
    k = np.flatnonzero(near_best)[np.argmax((j - i)[near_best])]
    return int(i[k]), int(j[k])


def loop_clip(clip: MotionClip, duration_s: float, min_loop_s: float = 0.9) -> MotionClip:
    """``clip``'s loop (:func:`find_loop`) played until ``duration_s``, walking straight on.

    Frames ``i … j − 1`` are made to join end to start: the root's rotation from frame ``i``
    to ``j``, ``Δ = R_j R_iᵀ``, is taken off gradually, ``R'_t = Exp(−s_t log Δ) R_t`` with
    ``s_t = (t − i)/(j − i)``, and so are the joint rotations' and the pelvis height's
    differences (``a'_t = a_t − s_t (a_j − a_i)``). Repetition ``k`` is the loop moved
    ``k`` times the pelvis's horizontal advance ``p_j − p_i`` (``p`` the pelvis, ``trans``
    plus the rest pelvis). A stance foot slides by the rotation taken off, a few millimetres
    on the CMU walks; the rest of the motion is the clip's, cycle after cycle."""
    i, j = find_loop(clip, min_loop_s)
    length = j - i
    s = (np.arange(length) / length)[:, None]
    R = so3_exp(np.asarray(clip.root_orient, dtype=np.float64))
    omega = so3_log(R[j] @ R[i].T)
    root = so3_log(so3_exp(-s * omega) @ R[i:j])
    aa = np.asarray(clip.joint_aa, dtype=np.float64)
    joint = aa[i:j] - s[:, :, None] * (aa[j] - aa[i])[None]
    rest_pelvis = np.zeros(3) if clip.rest_joints is None else np.asarray(clip.rest_joints)[0]
    trans = np.asarray(clip.trans, dtype=np.float64)
    pelvis = trans[i:j] + rest_pelvis
    pelvis[:, 2] -= s[:, 0] * (trans[j, 2] - trans[i, 2])
    advance = np.array([*(trans[j, :2] - trans[i, :2]), 0.0])
    n_out = int(round(duration_s * clip.fps)) + 1
    reps = -(-n_out // length)
    offsets = np.repeat(np.arange(reps), length)[:n_out, None] * advance
    tile = np.arange(n_out) % length
    return replace(
        clip,
        name=f"{clip.name}#loop{duration_s:g}s",
        root_orient=root[tile],
        joint_aa=joint[tile],
        trans=pelvis[tile] + offsets - rest_pelvis,
    )


def augment_split(
    prepared: PreparedWalking,
    split: str = "train",
    *,
    mirror: bool = False,
    time_scales: Sequence[float] = (),
    min_frames: int = 2,
) -> PreparedWalking:
    """``prepared`` plus, for every clip of ``split``, its mirror image (``mirror``) and a copy
    played at each factor of ``time_scales`` (of the original and, with ``mirror``, of the
    mirror image). Copies shorter than ``min_frames`` are dropped. Other splits are unchanged.
    """
    base = [prepared.clip(i) for i in np.flatnonzero(prepared.clip_split == split)]
    extra: list[MotionClip] = []
    originals = base + ([mirror_clip(c) for c in base] if mirror else [])
    extra += originals[len(base) :]
    for factor in time_scales:
        extra += [time_scale_clip(c, factor) for c in originals]
    extra = [c for c in extra if c.n_frames >= min_frames]
    if not extra:
        return prepared
    return _append(prepared, extra, split)


def _append(prepared: PreparedWalking, clips: list[MotionClip], split: str) -> PreparedWalking:
    """``prepared`` with ``clips`` appended (all in ``split``)."""
    C = prepared.n_clips
    lengths = np.array([c.n_frames for c in clips], dtype=np.int64)
    offset = np.concatenate([prepared.clip_offset, prepared.clip_offset[-1] + np.cumsum(lengths)])
    betas = np.zeros((C + len(clips), max(prepared.betas.shape[1], 1)), dtype=np.float32)
    betas[:C, : prepared.betas.shape[1]] = prepared.betas
    for i, c in enumerate(clips):
        b = np.asarray(c.betas, dtype=np.float32).reshape(-1)[: betas.shape[1]]
        betas[C + i, : b.shape[0]] = b
    rest = np.zeros((C + len(clips), 9, 3), dtype=np.float32)
    has = np.zeros(C + len(clips), dtype=bool)
    if prepared.clip_has_rest_joints is not None:
        rest[:C], has[:C] = prepared.clip_rest_joints, prepared.clip_has_rest_joints
    for i, c in enumerate(clips):
        if c.rest_joints is not None:
            rest[C + i], has[C + i] = c.rest_joints, True

    def cat(old: np.ndarray, new: list) -> np.ndarray:
        return np.concatenate([old, np.asarray(new, dtype=old.dtype)])

    return replace(
        prepared,
        clip_name=np.array([*prepared.clip_name.tolist(), *[c.name for c in clips]], dtype=str),
        clip_dataset=np.array(
            [*prepared.clip_dataset.tolist(), *[c.dataset for c in clips]], dtype=str
        ),
        clip_split=np.array([*prepared.clip_split.tolist(), *[split] * len(clips)], dtype=str),
        clip_gender=np.array(
            [*prepared.clip_gender.tolist(), *[c.gender for c in clips]], dtype=str
        ),
        clip_source_fps=cat(prepared.clip_source_fps, [c.source_fps for c in clips]),
        clip_offset=offset,
        betas=betas,
        root_orient=np.concatenate([prepared.root_orient, *[c.root_orient for c in clips]]).astype(
            np.float32
        ),
        joint_aa=np.concatenate([prepared.joint_aa, *[c.joint_aa for c in clips]]).astype(
            np.float32
        ),
        trans=np.concatenate([prepared.trans, *[c.trans for c in clips]]).astype(np.float32),
        clip_rest_joints=rest,
        clip_has_rest_joints=has,
    )
