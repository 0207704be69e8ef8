"""A standing start and end around a clip that walks from its first frame to its last.

The filter starts from a second of standing (docs/vio.md, thesis sec. 5.1) and a recording
protocol asks the subject to stand still at both ends; motion-capture walks (the CMU clips,
most of AMASS) start and end mid-stride. So the session is built as

    standing ─ lead-in ─ the clip at its own speed ─ lead-out ─ standing

and every sample outside the clip's own timing is marked synthetic in the ground truth
(``groundtruth/motion_frames.csv``, docs/groundtruth.md).

Lead-in (gait initiation), ``motion.lead_in_s`` = R:
- *Entry*: the first clip time ``c0`` at which one foot S stands on the floor while the other
  foot O swings, in the middle of O's time in the air (mid-stance of S;
  :mod:`gaitnet.sim.clip_events` finds the contacts).
- *Standing pose*: S exactly where the clip has it at ``c0``; O flat beside it,
  ``gait.stand_width_m`` (default 16.5 cm) across the heading, toed out as S mirrored; the
  pelvis at the clip's median tilt, level, over the feet, as high as straight legs
  (``gait.knee_extended_deg``) allow. The heading is the direction of S's next stride.
- *Time warp*: the clip is played from ``c0`` at a rate rising from 0 to 1 over R
  (``smoothstep7``, C³), so the body accelerates from rest on the clip's own path: no foot
  slides that the clip does not slide. It reaches full speed at ``c0 + R/2``.
- *Blend*: meanwhile the pose moves from the standing pose to the clip's (weight ``w`` from
  1 to 0, ``smoothstep7``) before O lands in the clip (at 80 % of the clip time to its
  landing), so the blend never drags a foot planted in the clip (S's own pose only blends
  its pose at ``c0`` with the clip's later ones, which stand on the same spot): the
  pelvis pose and each shoe's pose are interpolated (positions linearly, rotations by slerp),
  O lifted where its sole would dip under the floor, and the legs placed by two-link IK
  (:func:`gaitnet.sim.gait_legs.leg_chain`) with each knee bending towards where the clip's
  knee bends, so the legs meet the clip's exactly when ``w`` reaches 0.
The pelvis (hence the IMU) is C² throughout; joints move continuously.

Lead-out (gait termination), ``motion.lead_out_s``: the lead-in of the clip played backwards,
played forwards again, so it slows down on the clip's path into a standing pose built around
the last mid-stance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gaitnet.errors import InputError
from gaitnet.geometry import quat_from_rotmat, quat_slerp, rotmat_from_quat, so3_exp
from gaitnet.motion.skeleton import LowerBodySkeleton
from gaitnet.sim.clip_events import FootContacts, foot_contacts
from gaitnet.sim.clip_pose import BodyChain, PoseSamples, ShoeGeometry, body_chain, poses_chain
from gaitnet.sim.gait_legs import R_PfromSMPL, leg_chain, smpl_pose_from_chain
from gaitnet.sim.gait_plan import smoothstep7

__all__ = [
    "SessionMotion",
    "median_pelvis_tilt",
    "StandingSpec",
    "build_session_motion",
    "warp_advance",
]

_BLEND_SHARE = 0.8  # the blend ends at this share of the clip time to O's landing
_MIN_BLEND_CLIP_S = 0.08  # prefer entries with at least this much clip time to blend in
_REACH_MARGIN = 1e-6  # relative: an interpolated ankle is kept this far inside the leg's reach


@dataclass(frozen=True)
class StandingSpec:
    """The standing phases: their lengths [s], the distance between the standing feet's sole
    centres [m] and the standing knees' flexion [deg]."""

    start_s: float
    end_s: float
    width_m: float
    knee_deg: float


@dataclass(frozen=True, eq=False)
class SessionMotion:
    """The session's motion on its own clock (``poses.t`` from 0, the clip's sample spacing)
    and, per sample, the clip time shown (``clip_time_s``), the blend weight of the standing
    pose (``blend_weight``, 0 = the clip's pose), the clip's playback rate (``time_rate``,
    1 = real time) and whether the sample is synthetic (standing, blended or slowed)."""

    poses: PoseSamples
    clip_time_s: np.ndarray
    blend_weight: np.ndarray
    time_rate: np.ndarray

    @property
    def synthetic(self) -> np.ndarray:
        return (self.blend_weight > 0) | (self.time_rate < 1.0 - 1e-12)


def warp_advance(u: np.ndarray) -> np.ndarray:
    """``∫₀ᵘ smoothstep7`` (the clip time advanced per unit of ramp time; 1/2 at ``u`` = 1,
    then ``u − 1/2``)."""
    u = np.asarray(u, dtype=np.float64)
    v = np.clip(u, 0.0, 1.0)
    inner = 7 * v**5 - 14 * v**6 + 10 * v**7 - 2.5 * v**8
    return inner + np.maximum(u - 1.0, 0.0)


def _warp_inverse(advance: float) -> float:
    """The ``u`` at which :func:`warp_advance` reaches ``advance`` (≥ 0)."""
    if advance >= 0.5:
        return advance + 0.5
    lo, hi = 0.0, 1.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if warp_advance(mid) < advance else (lo, mid)
    return 0.5 * (lo + hi)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _yaw_matrix(yaw: float) -> np.ndarray:
    return so3_exp(np.array([0.0, 0.0, yaw]))


class _Track:
    """A clip on its own clock, with its body chain and the feet's contacts at its samples."""

    def __init__(
        self,
        poses: PoseSamples,
        skel: LowerBodySkeleton,
        shoe: ShoeGeometry,
        backwards: bool = False,
    ):
        self.poses, self.skel, self.shoe = poses, skel, shoe
        self.backwards = backwards  # played backwards: the body faces against its motion
        self.chain = poses_chain(poses, skel, shoe)
        pts = self.chain.shoe_points(shoe.ankle_in_shoe, shoe.sole_points())
        self.contacts: tuple[FootContacts, FootContacts] = tuple(
            foot_contacts(poses.t, pts[:, s, 0], pts[:, s, 1]) for s in range(2)
        )  # type: ignore[assignment]
        self.soles = pts[:, :, 2]

    def reversed(self) -> _Track:
        p = self.poses
        rev = PoseSamples(-p.t[::-1], p.root_orient[::-1], p.trans[::-1], p.joint_aa[::-1])
        return _Track(rev, self.skel, self.shoe, not self.backwards)

    def at(self, c: np.ndarray) -> tuple[tuple[np.ndarray, np.ndarray, np.ndarray], BodyChain]:
        pose = self.poses.at(c)
        return pose, body_chain(self.skel, *pose, self.shoe.ankle_from_shoe)


@dataclass(frozen=True)
class _Entry:
    stance_side: int
    k0: int  # sample index of c0
    blend_clip_s: float  # clip time over which the blend may run
    next_sole_xy: np.ndarray | None  # S's next foot-flat sole centre (the heading)


def _entries(track: _Track) -> list[_Entry]:
    """Every (S, c0) candidate: S on the floor while O is in the air (the middle of that
    time: S's mid-stance), O landing afterwards."""
    t = track.poses.t
    out = []
    for s in range(2):
        stance, other = track.contacts[s], track.contacts[1 - s]
        other_down = other.heel | other.toe
        for i, (a, b) in enumerate(stance.stances):
            air = np.flatnonzero(~other_down[a : b + 1])
            if len(air) < 2:
                continue
            k0 = a + int(air[len(air) // 2])
            landing = [a1 for a1, _ in other.stances if a1 > k0]
            if not landing:
                continue
            nxt = None
            if i + 1 < len(stance.stances):
                a1, b1 = stance.stances[i + 1]
                f0, f1 = stance.flat(a1, b1) or (a1, b1)
                nxt = track.soles[f0 : f1 + 1, s, :2].mean(axis=0)
            out.append(_Entry(s, k0, float(t[landing[0]] - t[k0]), nxt))
    return sorted(out, key=lambda e: e.k0)


def _choose_entry(track: _Track, name: str) -> _Entry:
    entries = _entries(track)
    if not entries:
        raise InputError(
            f"motion.{name}: the clip segment has no moment with one foot flat on the floor "
            "and the other in the air to start from (is it walking?)"
        )
    good = [e for e in entries if e.blend_clip_s >= _MIN_BLEND_CLIP_S]
    return good[0] if good else max(entries, key=lambda e: e.blend_clip_s)


def median_pelvis_tilt(chain: BodyChain) -> float:
    """The median anterior tilt [rad] of the pelvis frames of ``chain`` (Z-Y-X Euler)."""
    R = chain.R_WfromP
    return float(np.median(-np.arcsin(np.clip(R[:, 2, 0], -1.0, 1.0))))


@dataclass(frozen=True, eq=False)
class _Standing:
    R_P: np.ndarray
    p_P: np.ndarray
    ankles: np.ndarray  # (2, 3)
    R_S: np.ndarray  # (2, 3, 3)


def _standing_pose(track: _Track, entry: _Entry, spec: StandingSpec) -> _Standing:
    k0, s = entry.k0, entry.stance_side
    ch = track.chain
    sole_S = track.soles[k0, s]
    if entry.next_sole_xy is not None and np.linalg.norm(entry.next_sole_xy - sole_S[:2]) > 0.1:
        d = entry.next_sole_xy - sole_S[:2]
    else:
        d = ch.p_P[-1, :2] - ch.p_P[k0, :2]
    heading = float(np.arctan2(d[1], d[0])) + (np.pi if track.backwards else 0.0)
    left = np.array([-np.sin(heading), np.cos(heading), 0.0])
    R_S = ch.R_WfromShoe[k0].copy()
    ankles = ch.joints[k0, 5:7].copy()
    yaw_S = float(np.arctan2(R_S[s, 1, 0], R_S[s, 0, 0]))
    R_O = _yaw_matrix(2 * heading - yaw_S)
    sign_O = 1.0 if s == 1 else -1.0  # O is the left foot (+left) when S is the right one
    sole_O = sole_S + sign_O * spec.width_m * left
    R_S[1 - s] = R_O
    ankles[1 - s] = sole_O + R_O @ track.shoe.ankle_in_shoe

    tilt = median_pelvis_tilt(ch)
    R_P = _yaw_matrix(heading) @ so3_exp(np.array([0.0, tilt, 0.0]))
    J = track.skel.rest_joints
    hips_P = (J[1:3] - J[0]) @ R_PfromSMPL.T  # hip joints in the pelvis frame
    hips_W = hips_P @ R_P.T
    mid = ankles.mean(axis=0) - hips_W.mean(axis=0)
    L1 = np.linalg.norm(J[3:5] - J[1:3], axis=1)
    L2 = np.linalg.norm(J[5:7] - J[3:5], axis=1)
    knee = np.deg2rad(spec.knee_deg)
    reach = np.sqrt(L1**2 + L2**2 + 2 * L1 * L2 * np.cos(knee))
    p = np.array([mid[0], mid[1], 0.0])
    horiz = np.linalg.norm(p[:2] + hips_W[:, :2] - ankles[:, :2], axis=1)
    rise = np.sqrt(np.maximum(reach**2 - horiz**2, 1e-6))
    p[2] = float(np.min(ankles[:, 2] + rise - hips_W[:, 2]))
    return _Standing(R_P, p, ankles, R_S)


def _bend_directions(chain: BodyChain) -> np.ndarray:
    """Where each knee of ``chain`` bends (n, 2, 3): the knee's offset from the hip–ankle
    line, or the pelvis forward axis where the leg is straight."""
    hips, knees, ankles = chain.joints[:, 1:3], chain.joints[:, 3:5], chain.joints[:, 5:7]
    e = _unit(ankles - hips)
    off = knees - hips
    off = off - np.sum(off * e, axis=-1, keepdims=True) * e
    norm = np.linalg.norm(off, axis=-1, keepdims=True)
    fwd = np.broadcast_to(chain.R_WfromP[:, None, :, 0], off.shape)
    return np.where(norm > 1e-6, off / np.maximum(norm, 1e-12), fwd)


def _blended_poses(
    track: _Track,
    stand: _Standing,
    swing_side: int,
    c: np.ndarray,
    w: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Poses blending ``stand`` (weight ``w``) with the clip at times ``c`` (module docstring)."""
    (_, _, aa_c), ch = track.at(c)
    n = len(c)
    a = (1.0 - w)[:, None]
    q_s = quat_from_rotmat(stand.R_P)
    q_c = quat_from_rotmat(ch.R_WfromP)
    R_P = rotmat_from_quat(quat_slerp(np.broadcast_to(q_s, q_c.shape), q_c, 1.0 - w))
    p_P = w[:, None] * stand.p_P + a * ch.p_P
    ankles = w[:, None, None] * stand.ankles + a[:, None] * ch.joints[:, 5:7]
    qs_s = quat_from_rotmat(stand.R_S)
    qs_c = quat_from_rotmat(ch.R_WfromShoe)
    R_S = rotmat_from_quat(
        quat_slerp(np.broadcast_to(qs_s, qs_c.shape), qs_c, np.repeat((1.0 - w)[:, None], 2, 1))
    )
    # the swinging foot never dips under the floor
    sole = track.shoe.sole_points()[:2] - track.shoe.ankle_in_shoe
    low = np.min(np.einsum("nij,kj->nki", R_S[:, swing_side], sole)[..., 2], axis=1)
    ankles[:, swing_side, 2] += np.maximum(0.0, -(ankles[:, swing_side, 2] + low))
    J = track.skel.rest_joints
    hips = p_P[:, None] + np.einsum("nij,sj->nsi", R_P @ R_PfromSMPL, J[1:3] - J[0])
    L = np.linalg.norm(J[3:5] - J[1:3], axis=1) + np.linalg.norm(J[5:7] - J[3:5], axis=1)
    d = ankles - hips
    dist = np.linalg.norm(d, axis=-1)
    too_far = dist > L * (1 - _REACH_MARGIN)
    scale = np.where(too_far, L * (1 - _REACH_MARGIN) / np.maximum(dist, 1e-12), 1.0)
    ankles = hips + d * scale[..., None]
    bend_s = np.broadcast_to(stand.R_P[:, 0], (n, 2, 3))
    bend = _unit(w[:, None, None] * bend_s + a[:, None] * _bend_directions(ch))
    R_SA = R_S @ np.swapaxes(track.shoe.ankle_from_shoe, -1, -2)  # the ankles' own shoe frames
    _, G_thigh, G_shank = leg_chain(track.skel, R_P, p_P, R_SA, ankles, bend_W=bend)
    root, aa = smpl_pose_from_chain(R_P, G_thigh, G_shank, R_SA)
    aa[:, 6:8] = a[:, None] * aa_c[:, 6:8]
    return root, p_P - J[0], aa


@dataclass(frozen=True, eq=False)
class _Lead:
    """A lead-in on a track's clock: poses at session samples ``0 … K`` (the last one the
    clip's pose at ``k_clip``, played at full speed from there)."""

    poses: PoseSamples
    clip_time_s: np.ndarray
    blend_weight: np.ndarray
    time_rate: np.ndarray
    k_clip: int


def _lead_in(track: _Track, ramp_s: float, spec: StandingSpec, stand_s: float, name: str) -> _Lead:
    t = track.poses.t
    dt = float(t[1] - t[0])
    entry = _choose_entry(track, name)
    n_ramp = 2 * max(1, int(round(ramp_s / (2 * dt))))
    ramp = n_ramp * dt
    n_stand = int(round(stand_s / dt))
    k_clip = entry.k0 + n_ramp // 2
    if k_clip >= len(t):
        raise InputError(
            f"motion.{name}: the clip segment ends {t[-1] - t[entry.k0]:.2f} s after its first "
            f"mid-stance, too soon for a {ramp:g} s {name.removesuffix('_s')}"
        )
    c0 = float(t[entry.k0])
    ts = np.arange(n_stand + n_ramp + 1) * dt
    u = np.maximum(ts - n_stand * dt, 0.0) / ramp
    c = c0 + ramp * warp_advance(u)
    c[-1] = t[k_clip]
    rate = smoothstep7(u)
    u_w = _warp_inverse(_BLEND_SHARE * max(entry.blend_clip_s, 0.0) / ramp)
    w = 1.0 - smoothstep7(np.maximum(ts - n_stand * dt, 0.0) / max(u_w * ramp, dt))
    stand = _standing_pose(track, entry, spec)
    blend = w > 0
    root = np.empty((len(ts), 3))
    trans = np.empty((len(ts), 3))
    aa = np.empty((len(ts), 8, 3))
    root[blend], trans[blend], aa[blend] = _blended_poses(
        track, stand, 1 - entry.stance_side, c[blend], w[blend]
    )
    root[~blend], trans[~blend], aa[~blend] = track.poses.at(c[~blend])
    return _Lead(PoseSamples(ts, root, trans, aa), c, w, rate, k_clip)


def build_session_motion(
    clip: PoseSamples,
    skel: LowerBodySkeleton,
    shoe: ShoeGeometry,
    lead_in_s: float,
    lead_out_s: float,
    spec: StandingSpec,
) -> SessionMotion:
    """Standing, lead-in, the clip, lead-out and standing on one clock (module docstring).
    ``lead_in_s`` / ``lead_out_s`` 0: the session starts / ends with the clip's own frame."""
    track = _Track(clip, skel, shoe)
    t = clip.t
    parts: list[tuple[PoseSamples, np.ndarray, np.ndarray, np.ndarray]] = []
    k_start, k_end = 0, len(t) - 1
    if lead_in_s > 0:
        lead = _lead_in(track, lead_in_s, spec, spec.start_s, "lead_in_s")
        parts.append((lead.poses, lead.clip_time_s, lead.blend_weight, lead.time_rate))
        k_start = lead.k_clip
    out = None
    if lead_out_s > 0:
        out = _lead_in(track.reversed(), lead_out_s, spec, spec.end_s, "lead_out_s")
        k_end = len(t) - 1 - out.k_clip
    if k_end <= k_start:
        raise InputError(
            "motion.duration_s: the clip segment is too short for its lead-in and lead-out "
            f"({t[-1] - t[0]:.2f} s; shorten motion.lead_in_s / motion.lead_out_s or play a "
            "longer segment)"
        )
    idx = np.arange(k_start + (1 if parts else 0), k_end + 1)
    parts.append(
        (
            PoseSamples(t[idx], clip.root_orient[idx], clip.trans[idx], clip.joint_aa[idx]),
            t[idx],
            np.zeros(len(idx)),
            np.ones(len(idx)),
        )
    )
    if out is not None:
        r = slice(len(out.poses) - 2, None, -1)  # backwards, without the shared clip sample
        p = out.poses
        parts.append(
            (
                PoseSamples(p.t[r], p.root_orient[r], p.trans[r], p.joint_aa[r]),
                -out.clip_time_s[r],
                out.blend_weight[r],
                out.time_rate[r],
            )
        )
    root = np.concatenate([p.root_orient for p, *_ in parts])
    trans = np.concatenate([p.trans for p, *_ in parts])
    aa = np.concatenate([p.joint_aa for p, *_ in parts])
    dt = float(t[1] - t[0])
    ts = np.arange(len(root)) * dt
    return SessionMotion(
        PoseSamples(ts, root, trans, aa),
        np.concatenate([c for _, c, _, _ in parts]),
        np.concatenate([w for _, _, w, _ in parts]),
        np.concatenate([r for _, _, _, r in parts]),
    )
