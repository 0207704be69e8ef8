"""SMPL lower-body poses on a uniform time grid: interpolation, low-pass, forward kinematics.

The common currency of clip playback (:mod:`gaitnet.sim.clip_walk`): a motion-capture clip,
the standing lead-in and lead-out built around it (:mod:`gaitnet.sim.clip_lead`) and the
session's motion are all :class:`PoseSamples`. Conventions are :mod:`gaitnet.motion.skeleton`'s
(SMPL joints 0, 1, 2, 4, 5, 7, 8, 10, 11; ``p_pelvis = J_rest[0] + trans``) and
:mod:`gaitnet.sim.gait_legs`'s frames (pelvis frame P: x forward, y left, z up; shoe frame: x
toe, y left, z up; ``R_WfromP = R_root R_PfromSMPLᵀ``, ``R_WfromShoe = G_ankle R_PfromSMPLᵀ``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike

from gaitnet.geometry import (
    quat_from_rotvec,
    quat_interpolate,
    quat_make_continuous,
    quat_normalize,
    rotvec_from_quat,
    so3_exp,
)
from gaitnet.motion.skeleton import LowerBodySkeleton, forward_kinematics
from gaitnet.sim.gait_legs import R_PfromSMPL

__all__ = [
    "BodyChain",
    "PoseSamples",
    "ShoeGeometry",
    "body_chain",
    "lowpass_poses",
    "poses_chain",
    "shoe_mounting",
]

_FILTER_ORDER = 4  # Butterworth order of :func:`lowpass_poses` (applied forwards and backwards)
_PLANTED_SPEED_MPS = 0.15  # an ankle slower than this, ...
_PLANTED_HEIGHT_M = 0.03  # ... within this of its lowest (10th-percentile) height, is planted


@dataclass(frozen=True, eq=False)
class PoseSamples:
    """Poses at times ``t`` (n,) [s], strictly increasing: ``root_orient`` (n, 3), ``trans``
    (n, 3) [m] and ``joint_aa`` (n, 8, 3) (SMPL joints 1, 2, 4, 5, 7, 8, 10, 11)."""

    t: np.ndarray
    root_orient: np.ndarray
    trans: np.ndarray
    joint_aa: np.ndarray

    def __len__(self) -> int:
        return int(self.t.shape[0])

    def at(self, t: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Poses at times ``t`` (clamped to the samples' span): rotations slerped, the
        translation linear; exact at the sample times."""
        t = np.clip(np.atleast_1d(np.asarray(t, dtype=np.float64)), self.t[0], self.t[-1])
        quats = self._quats
        out = np.stack(
            [quat_interpolate(self.t, quats[:, j], t, out_of_range="clamp") for j in range(9)],
            axis=1,
        )
        rv = rotvec_from_quat(out)
        trans = np.stack([np.interp(t, self.t, self.trans[:, k]) for k in range(3)], axis=1)
        return rv[:, 0], trans, rv[:, 1:]

    @cached_property
    def _quats(self) -> np.ndarray:
        """Root and joint rotations as quaternions (n, 9, 4), signs continuous in time."""
        return _continuous_quats(self.root_orient, self.joint_aa)

    def select(self, mask: np.ndarray) -> PoseSamples:
        """The samples where ``mask`` is True."""
        return PoseSamples(
            self.t[mask], self.root_orient[mask], self.trans[mask], self.joint_aa[mask]
        )


def _continuous_quats(root_orient: np.ndarray, joint_aa: np.ndarray) -> np.ndarray:
    rot = np.concatenate([root_orient[:, None], joint_aa], axis=1)  # (n, 9, 3)
    return quat_make_continuous(quat_from_rotvec(rot))


def lowpass_poses(poses: PoseSamples, cutoff_hz: float) -> PoseSamples:
    """A zero-phase Butterworth low-pass (order 4, forwards and backwards) of the translation
    and of every rotation (as sign-continuous unit quaternions, renormalised), on uniformly
    spaced samples. Motion capture carries millimetres of marker noise, which the IMU's
    double derivative would turn into metres per second squared; gait kinematics are
    commonly filtered at 6–10 Hz (Winter, *Biomechanics and Motor Control of Human
    Movement*). ``cutoff_hz`` 0 returns ``poses`` unchanged."""
    if cutoff_hz <= 0:
        return poses
    # imported here: scipy.signal takes 0.3–0.6 s to import, which every `gaitnet simulate`
    # (this module comes with the scene set-up) would pay for clips it does not play
    from scipy.signal import butter, sosfiltfilt

    fs = (len(poses) - 1) / (poses.t[-1] - poses.t[0])
    sos = butter(_FILTER_ORDER, min(cutoff_hz / (0.5 * fs), 0.99), output="sos")
    pad = min(len(poses) - 1, 3 * (2 * len(sos) + 1))

    def smooth(x: np.ndarray) -> np.ndarray:
        return sosfiltfilt(sos, x, axis=0, padlen=pad)

    quats = _continuous_quats(poses.root_orient, poses.joint_aa)
    rv = rotvec_from_quat(quat_normalize(smooth(quats)))
    return PoseSamples(poses.t, rv[:, 0], smooth(poses.trans), rv[:, 1:])


@dataclass(frozen=True, eq=False)
class BodyChain:
    """What forward kinematics gives of a batch of poses: ``joints`` (n, 9, 3), the pelvis
    frame ``R_WfromP`` (n, 3, 3) and ``p_P`` (n, 3), and the shoes' rotations
    ``R_WfromShoe`` (n, 2, 3, 3) (left, right)."""

    joints: np.ndarray
    R_WfromP: np.ndarray
    R_WfromShoe: np.ndarray

    @property
    def p_P(self) -> np.ndarray:
        return self.joints[:, 0]

    def shoe_points(self, ankle_in_shoe: np.ndarray, points_S: ArrayLike) -> np.ndarray:
        """World positions ``(n, 2, k, 3)`` of shoe-frame points ``(k, 3)``: each shoe is the
        rigid frame whose fixed point ``ankle_in_shoe`` is the ankle joint."""
        P = np.asarray(points_S, dtype=np.float64).reshape(-1, 3) - ankle_in_shoe
        return self.joints[:, 5:7, None, :] + np.einsum("nsij,kj->nski", self.R_WfromShoe, P)


def body_chain(
    skel: LowerBodySkeleton,
    root_orient: np.ndarray,
    trans: np.ndarray,
    joint_aa: np.ndarray,
    R_AnkleFromShoe: np.ndarray | None = None,
) -> BodyChain:
    """Joints by :func:`gaitnet.motion.skeleton.forward_kinematics` and the pelvis and shoe
    frames of the same poses. The shoe turns with the SMPL ankle, mounted on it by
    ``R_AnkleFromShoe`` (2, 3, 3) per side (None: identity, the generator's mounting,
    ``R_WfromShoe = G_ankle R_PfromSMPLᵀ``); the foot joints' own rotations (zero in the
    generator's clips) are not part of the rigid shoe."""
    joints = forward_kinematics(skel, root_orient, trans, joint_aa)
    R_root = so3_exp(root_orient)
    R_local = so3_exp(joint_aa)
    G_ankle = R_root[:, None] @ R_local[:, 0:2] @ R_local[:, 2:4] @ R_local[:, 4:6]
    R_shoe = G_ankle @ R_PfromSMPL.T
    if R_AnkleFromShoe is not None:
        R_shoe = R_shoe @ R_AnkleFromShoe
    return BodyChain(joints, R_root @ R_PfromSMPL.T, R_shoe)


@dataclass(frozen=True, eq=False)
class ShoeGeometry:
    """A subject's rigid shoe: the ankle point in the shoe frame, the sole length (heel and
    toe at ``(∓L/2, 0, 0)``) and how each shoe is mounted on its SMPL ankle
    (``ankle_from_shoe`` (2, 3, 3), :func:`shoe_mounting`; identity: the generator's)."""

    ankle_in_shoe: np.ndarray
    length_m: float
    ankle_from_shoe: np.ndarray = field(default_factory=lambda: np.stack([np.eye(3)] * 2))

    def sole_points(self) -> np.ndarray:
        """Heel, toe and sole centre in the shoe frame (3, 3)."""
        half = 0.5 * self.length_m
        return np.array([[-half, 0.0, 0.0], [half, 0.0, 0.0], [0.0, 0.0, 0.0]])


def poses_chain(poses: PoseSamples, skel: LowerBodySkeleton, shoe: ShoeGeometry) -> BodyChain:
    """:func:`body_chain` of every sample of ``poses`` with ``shoe``'s mounting."""
    return body_chain(skel, poses.root_orient, poses.trans, poses.joint_aa, shoe.ankle_from_shoe)


def shoe_mounting(poses: PoseSamples, skel: LowerBodySkeleton) -> np.ndarray:
    """Per side, the rotation ``R_AnkleFromShoe`` (2, 3, 3) that levels the shoe where the
    clip's foot is planted.

    A body model's rest foot is not level (SMPL's points down; a converted clip's may point
    up), so the ankle rotation of a foot flat on the floor is not the identity. The planted
    samples are those whose ankle moves horizontally slower than 0.15 m/s within 3 cm of its
    lowest height (10th percentile); the shoe is mounted so that it has there its median
    pitch and roll removed (Z-Y-X angles of ``G_ankle R_PfromSMPLᵀ``): zero for the
    generator's own clips, up to 7° of pitch and 8° of roll on the converted CMU walks."""
    chain = body_chain(skel, poses.root_orient, poses.trans, poses.joint_aa)
    out = np.empty((2, 3, 3))
    for s in range(2):
        ankle = chain.joints[:, 5 + s]
        speed = np.linalg.norm(np.gradient(ankle[:, :2], poses.t, axis=0), axis=1)
        low = ankle[:, 2] < np.percentile(ankle[:, 2], 10) + _PLANTED_HEIGHT_M
        planted = (speed < _PLANTED_SPEED_MPS) & low
        R = chain.R_WfromShoe[planted if planted.sum() >= 3 else low, s]
        pitch = float(np.median(-np.arcsin(np.clip(R[:, 2, 0], -1.0, 1.0))))
        roll = float(np.median(np.arctan2(R[:, 2, 1], R[:, 2, 2])))
        out[s] = so3_exp(np.array([-roll, 0.0, 0.0])) @ so3_exp(np.array([0.0, -pitch, 0.0]))
    return out
