"""Residuals of the pose correction and their analytic Jacobians, batched over frames.

The objective (thesis eq. 4.7, 4.8 and the extensions; docs/pose-correction.md) is a sum of
squared, weighted residuals, so it is solved by Levenberg-Marquardt (:mod:`gaitnet.pipeline.
pose_correction`). Parameters of one frame, in this column order:

- ``δ`` (3): a right increment of the root rotation, ``R_root ← R_root Exp(δ)``, re-linearised
  at every step (so the root never meets the axis-angle singularity at π);
- ``t`` (3): the SMPL root translation;
- ``a`` (18): the axis-angle local rotations of L_hip, R_hip, L_knee, R_knee, L_ankle,
  R_ankle (nodes 1..6 of the predictor);
- ``l`` (4, only with free bone lengths): thigh left, thigh right, shank left, shank right [m].

Kinematics per side (SMPL convention, :mod:`gaitnet.motion.skeleton`): ``p_0 = J_0 + t``;
``hip = p_0 + R_root o_hip``, ``G_hip = R_root R(a_hip)``; ``knee = hip + l_thigh G_hip u_thigh``,
``G_knee = G_hip R(a_knee)``; ``ankle = knee + l_shank G_knee u_shank``, ``G_ank = G_knee
R(a_ank)``; foot point ``f = ankle + G_ank m`` (``m`` the ankle-to-marker offset, zero when off).

Derivatives: a right perturbation ``Exp(ω)`` of joint k's local rotation turns every point below
it about the joint by ``G_k ω`` (world), so ``∂p/∂ω = −[p − p_k]× G_k``; with axis-angle
parameters ``ω = Jr(a) da`` (``so3_exp(a + da) ≈ so3_exp(a) Exp(Jr(a) da)``). A bone length
moves the points below it along the posed bone: ``∂p/∂l = G_parent u``. The rotation residual
``Log(R̃ᵀ R_root Exp(δ))`` has ``∂/∂δ = Jr⁻¹(r)`` at ``δ = 0``. The flat-foot residuals are
world-up components ``e_zᵀ G_ank e_k`` of the ankle frame's left (k = x) and forward (k = z)
axes; a world rotation ``φ`` upstream changes them by ``(G_ank e_k × e_z)ᵀ φ``.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from gaitnet.geometry import so3_exp, so3_log
from gaitnet.motion.skeleton import LowerBodySkeleton
from gaitnet.pipeline.pose_types import PoseCorrectionParams

FloatArray = NDArray[np.float64]

__all__ = [
    "N_BASE_PARAMS",
    "ChainGeometry",
    "ChainState",
    "Problem",
    "chain_points",
    "evaluate",
    "exp_and_right_jacobian",
    "foot_points",
    "log_and_right_jacobian_inv",
    "retract",
]

N_BASE_PARAMS = 24
_A0 = 6  # first column of the joint axis-angles
_L0 = 24  # first column of the bone lengths (free lengths only)
# Generators: skew(v) = (v @ _GEN).reshape(3, 3).
_GEN = np.zeros((3, 9))
_GEN[2, 1], _GEN[1, 2], _GEN[2, 3], _GEN[0, 5], _GEN[1, 6], _GEN[0, 7] = -1, 1, 1, -1, -1, 1
_EYE3 = np.eye(3)
_KNEE_YZ = [7, 8, 10, 11]  # y, z of L_knee and R_knee among the 18 joint values
_ROWS18 = np.arange(18)
_VEE_PLUS, _VEE_MINUS, _DIAG = [7, 2, 3], [5, 6, 1], [0, 4, 8]  # R − Rᵀ → vector


def _skew(v: FloatArray) -> FloatArray:
    return (v @ _GEN).reshape(*v.shape[:-1], 3, 3)


def exp_and_right_jacobian(phi: FloatArray) -> tuple[FloatArray, FloatArray]:
    """``so3_exp(φ)`` and ``so3_right_jacobian(φ)`` of (..., 3) in one pass (shared ``[φ×]``).

    ``R = I + A K + B K²``, ``Jr = I − B K + C K²`` with ``A = sin θ/θ``, ``B = (1 − cos θ)/θ²``
    (as ``2 sin²(θ/2)/θ²``, free of cancellation) and ``C = (θ − sin θ)/θ³``, whose rounding
    error is multiplied by ``K² = O(θ²)``; θ is floored at 1e-12 (both then equal the limits
    to within 1e-16 in the products).
    """
    t = np.maximum(np.sqrt(np.einsum("...i,...i->...", phi, phi)), 1e-12)
    s = np.sin(t)
    h = np.sin(0.5 * t) / t
    A = (s / t)[..., None, None]
    B = (2.0 * h * h)[..., None, None]
    C = ((t - s) / (t * t * t))[..., None, None]
    K = _skew(phi)
    K2 = K @ K
    return _EYE3 + A * K + B * K2, _EYE3 - B * K + C * K2


def log_and_right_jacobian_inv(R: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Rotation vector ``φ`` of (..., 3, 3) rotations and ``Jr(φ)⁻¹``.

    ``φ`` by the ``atan2`` form (accurate near 0) below 90°, else :func:`gaitnet.geometry.
    so3_log`; ``Jr⁻¹ = I + ½K + (1/θ² − (1 + cos θ)/(2θ sin θ)) K²`` (series below 1e-2 rad).
    """
    Rf = R.reshape(*R.shape[:-2], 9)
    v = 0.5 * (Rf[..., _VEE_PLUS] - Rf[..., _VEE_MINUS])
    s = np.sqrt(np.einsum("...i,...i->...", v, v))
    c = 0.5 * (Rf[..., _DIAG].sum(axis=-1) - 1.0)
    theta = np.arctan2(s, c)
    phi = v * (theta / np.maximum(s, 1e-300))[..., None]
    tiny = s < 1e-300
    if np.any(tiny):
        phi[tiny] = v[tiny]
    far = c < 0.0
    if np.any(far):
        phi[far] = so3_log(R[far])
        theta = np.where(far, np.linalg.norm(phi, axis=-1), theta)
    small = theta < 1e-2
    tt = np.where(small, 1.0, theta)
    t2 = theta * theta
    D = np.where(
        small,
        1.0 / 12.0 + t2 / 720.0,
        1.0 / (tt * tt) - (1.0 + np.cos(tt)) / (2.0 * tt * np.sin(tt)),
    )
    K = _skew(phi)
    return phi, _EYE3 + 0.5 * K + D[..., None, None] * (K @ K)


@dataclass(frozen=True, eq=False)
class ChainGeometry:
    """Constants of the chain from a skeleton and the parameters (per side: rows left, right)."""

    J0: FloatArray  # (3,) rest pelvis
    o_hip: FloatArray  # (2, 3) pelvis → hip
    u_thigh: FloatArray  # (2, 3) unit rest thigh direction
    u_shank: FloatArray  # (2, 3) unit rest shank direction
    lengths: FloatArray  # (4,) thigh L, thigh R, shank L, shank R
    marker: FloatArray  # (2, 3) ankle → foot point, ankle frame

    @classmethod
    def build(cls, skel: LowerBodySkeleton, params: PoseCorrectionParams) -> ChainGeometry:
        off = skel.offsets
        thigh, shank = off[3:5], off[5:7]
        lt, ls = np.linalg.norm(thigh, axis=1), np.linalg.norm(shank, axis=1)
        m = np.zeros((2, 3))
        if params.marker_offset:
            m[:] = params.marker_offset_m
            m[1, 0] = -m[1, 0]  # the right foot mirrors the left across the sagittal plane
        return cls(
            J0=skel.rest_joints[0].copy(),
            o_hip=off[1:3].copy(),
            u_thigh=thigh / lt[:, None],
            u_shank=shank / ls[:, None],
            lengths=np.concatenate([lt, ls]),
            marker=m,
        )


@dataclass(eq=False)
class ChainState:
    """A batch of B poses: ``R0`` (B, 3, 3), ``t`` (B, 3), ``a`` (B, 6, 3), ``l`` (B, 4)."""

    R0: FloatArray
    t: FloatArray
    a: FloatArray
    l: FloatArray  # noqa: E741


@dataclass(frozen=True, eq=False)
class Problem:
    """Fixed data of a batch: prior, measurements with masks, and the per-term weights."""

    geo: ChainGeometry
    params: PoseCorrectionParams
    R_prior: FloatArray  # (B, 3, 3)
    t_prior: FloatArray  # (B, 3)
    a_prior: FloatArray  # (B, 6, 3)
    R_meas: FloatArray  # (B, 3, 3) (identity where not measured)
    w_root_rot: FloatArray  # (B,) 0 where not measured
    p_meas: FloatArray  # (B, 3)
    w_root_pos: FloatArray  # (B,)
    foot: FloatArray  # (B, 2, 3) (0 where not seen)
    w_foot: FloatArray  # (B, 2) 0 where not seen, else (1 + gain c) / sigma
    rom_lo: FloatArray  # (18,) rad
    rom_hi: FloatArray  # (18,)
    w_flat: FloatArray  # (B, 2) contact / sigma_flat_rad
    R_prior_meas_T: FloatArray  # (B, 2, 3, 3): [R̄ᵀ, R̃ᵀ]

    @property
    def n_params(self) -> int:
        return N_BASE_PARAMS + (0 if self.params.fixed_lengths else 4)

    @cached_property
    def n_residuals(self) -> int:
        par = self.params
        return (
            36
            + 4 * (not par.fixed_lengths)
            + 4 * par.knee_hinge
            + 18 * par.rom_limits
            + 4 * par.flat_foot_contact
        )

    @cached_property
    def w_rot(self) -> FloatArray:
        """(B, 2) weights of the root rotation against its prior and its measurement."""
        w_prior = np.full(len(self.w_root_rot), 1 / self.params.sigma_prior_root_rad)
        return np.stack([w_prior, self.w_root_rot], axis=1)

    @cached_property
    def J_const(self) -> FloatArray:
        """The Jacobian's rows that do not depend on the state (B, m, n), zeros elsewhere."""
        par, B = self.params, len(self.w_root_rot)
        J = np.zeros((B, self.n_residuals, self.n_params))
        J[:, np.arange(18), _A0 + np.arange(18)] = 1 / par.sigma_prior_joint_rad
        J[:, np.arange(24, 27), np.arange(3, 6)] = 1 / par.sigma_prior_trans_m
        J[:, np.arange(27, 30), np.arange(3, 6)] = self.w_root_pos[:, None]
        row = 36
        if not par.fixed_lengths:
            J[:, np.arange(row, row + 4), _L0 + np.arange(4)] = 1 / par.sigma_bone_m
            row += 4
        if par.knee_hinge:
            J[:, np.arange(row, row + 4), _A0 + np.array(_KNEE_YZ)] = 1 / par.sigma_hinge_rad
        return J


def chain_points(geo: ChainGeometry, s: ChainState, jac: bool = False) -> dict[str, FloatArray]:
    """Joint and foot-point positions of a batch; with ``jac`` also the rotations it needs."""
    E, Jr = exp_and_right_jacobian(s.a)  # (B, 6, 3, 3)
    p0 = geo.J0 + s.t
    R0 = s.R0[:, None]
    hip = p0[:, None] + (R0 @ geo.o_hip[..., None])[..., 0]
    G_hip = R0 @ E[:, 0:2]
    d_thigh = (G_hip @ geo.u_thigh[..., None])[..., 0]
    knee = hip + s.l[:, 0:2, None] * d_thigh
    G_knee = G_hip @ E[:, 2:4]
    d_shank = (G_knee @ geo.u_shank[..., None])[..., 0]
    ankle = knee + s.l[:, 2:4, None] * d_shank
    G_ank = G_knee @ E[:, 4:6]
    foot = ankle + (G_ank @ geo.marker[..., None])[..., 0]
    out = {"p0": p0, "hip": hip, "knee": knee, "ankle": ankle, "foot": foot, "G_ank": G_ank}
    if jac:
        out |= {"G_hip": G_hip, "G_knee": G_knee, "Jr": Jr}
        out |= {"d_thigh": d_thigh, "d_shank": d_shank}
    return out


def foot_points(geometry: ChainGeometry, poses: FloatArray, trans: FloatArray) -> FloatArray:
    """World foot points (n, 2, 3) of ``geometry`` (its foot offset, the skeleton's lengths)
    for poses (n, 21: root and the six leg joints' axis-angles, SMPL convention) and root
    translations (n, 3)."""
    n = len(poses)
    lengths = np.broadcast_to(geometry.lengths, (n, 4)).copy()
    state = ChainState(
        R0=so3_exp(poses[:, :3]), t=trans, a=poses[:, 3:].reshape(n, 6, 3), l=lengths
    )
    return chain_points(geometry, state)["foot"]


def _root_terms(pb: Problem, s: ChainState) -> tuple[FloatArray, FloatArray]:
    """Log residuals of the root against its prior and its measurement: (B, 2, 3) each way."""
    return log_and_right_jacobian_inv(pb.R_prior_meas_T @ s.R0[:, None])


def _foot_weights(pb: Problem, e: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Per-foot residual scale (B, 2) and robust cost (B,) of foot errors ``e`` (B, 2, 3)."""
    d2 = np.einsum("bsi,bsi->bs", e, e)
    w2 = pb.w_foot**2
    if not pb.params.robust_foot:
        return pb.w_foot, np.sum(w2 * d2, axis=1)
    c2 = pb.params.cauchy_scale_m**2
    cost = np.sum(w2 * c2 * np.log1p(d2 / c2), axis=1)
    return pb.w_foot / np.sqrt(1.0 + d2 / c2), cost


def evaluate(
    pb: Problem, s: ChainState, jac: bool = True
) -> tuple[FloatArray, FloatArray | None, FloatArray]:
    """Stacked residuals (B, m), their Jacobian (B, m, n) or None, and the cost (B,).

    The cost is the sum of squares, except that the robust foot terms (Cauchy, seed 004:
    ``c² log(1 + d²/c²)`` weighted) enter through their true loss; the returned residuals and
    Jacobian are the iteratively re-weighted ones (scaled by ``sqrt(ρ')``), whose Gauss-Newton
    step has the exact gradient.
    """
    par, geo = pb.params, pb.geo
    B = s.t.shape[0]
    pts = chain_points(geo, s, jac)
    a = s.a.reshape(B, 18)
    r_root, Jinv = _root_terms(pb, s)
    e_foot = pts["foot"] - pb.foot
    scale_foot, foot_cost = _foot_weights(pb, e_foot)
    blocks = [
        (a - pb.a_prior.reshape(B, 18)) / par.sigma_prior_joint_rad,
        (pb.w_rot[..., None] * r_root).reshape(B, 6),
        (s.t - pb.t_prior) / par.sigma_prior_trans_m,
        pb.w_root_pos[:, None] * (pts["p0"] - pb.p_meas),
        (scale_foot[..., None] * e_foot).reshape(B, 6),
    ]
    if not par.fixed_lengths:
        blocks.append((s.l - geo.lengths) / par.sigma_bone_m)
    if par.knee_hinge:
        blocks.append(a[:, _KNEE_YZ] / par.sigma_hinge_rad)
    if par.rom_limits:
        below, above = np.minimum(a - pb.rom_lo, 0.0), np.maximum(a - pb.rom_hi, 0.0)
        blocks.append((below + above) / par.sigma_rom_rad)
    if par.flat_foot_contact:
        blocks.append((pb.w_flat[..., None] * _flat_residuals(pts)).reshape(B, 4))
    r = np.concatenate(blocks, axis=1)
    cost = np.einsum("bi,bi->b", r, r)
    if par.robust_foot:
        cost = cost - np.einsum("bi,bi->b", r[:, 30:36], r[:, 30:36]) + foot_cost
    if not jac:
        return r, None, cost
    J = pb.J_const.copy()
    J[:, 18:24, 0:3] = (pb.w_rot[..., None, None] * Jinv).reshape(B, 6, 3)
    Jf = _feet_jacobian(pts, s, pb.n_params, par.flat_foot_contact)
    J[:, 30:36] = (Jf[:, :, 0:3] * scale_foot[..., None, None]).reshape(B, 6, -1)
    row = 36 + 4 * (not par.fixed_lengths) + 4 * par.knee_hinge
    if par.rom_limits:
        outside = ((a < pb.rom_lo) | (a > pb.rom_hi)) / par.sigma_rom_rad
        J[:, row + _ROWS18, _A0 + _ROWS18] = outside
        row += 18
    if par.flat_foot_contact:
        J[:, row : row + 4] = (Jf[:, :, 3:5] * pb.w_flat[..., None, None]).reshape(B, 4, -1)
    return r, J, cost


def _chain_jacobian(
    pts: dict[str, FloatArray], s: ChainState, n: int, A_root: FloatArray, A: FloatArray
) -> FloatArray:
    """Jacobian (B, 2, m, n) of per-side quantities whose derivative with respect to a world
    rotation ``φ`` at the root is ``A_root φ`` (A_root (B, 2, m, 3)) and at hip, knee, ankle is
    ``A[:, :, level] φ`` (A (B, 2, 3, m, 3)); translation and lengths are left at zero."""
    B, m = s.t.shape[0], A_root.shape[2]
    Jq = np.zeros((B, 2, m, n))
    Jq[..., 0:3] = A_root @ s.R0[:, None]
    # Levels hip, knee, ankle: (B, side, level, 3, 3); Jr rows are ordered (level, side).
    G = np.stack([pts["G_hip"], pts["G_knee"], pts["G_ank"]], axis=2)
    Jr = pts["Jr"].reshape(B, 3, 2, 3, 3).swapaxes(1, 2)
    block = A @ G @ Jr  # (B, side, level, m rows, 3 components)
    Ja = Jq[..., _A0:_L0].view()
    Ja.shape = (B, 2, m, 3, 2, 3)  # a view of Jq (raises otherwise): side, row, level, side', comp
    for side in (0, 1):
        Ja[:, side, :, :, side, :] = block[:, side].swapaxes(1, 2)
    return Jq


def _feet_jacobian(pts: dict[str, FloatArray], s: ChainState, n: int, flat: bool) -> FloatArray:
    """∂(foot point)/∂(parameters) (B, 2, 3, n), then with ``flat`` ∂(flat residuals) (B, 2, 2,
    n) stacked below, in one pass: ``∂p/∂φ = −[p − p_k]×`` at each joint; the flat residuals
    ``e_zᵀ G_ank e_k`` have rows ``(G_ank e_k × e_z)ᵀ`` at every level."""
    f = pts["foot"]
    lever = f[:, :, None] - np.stack([pts["hip"], pts["knee"], pts["ankle"]], axis=2)
    A_root, A = -_skew(f - pts["p0"][:, None]), -_skew(lever)
    if flat:
        axes = pts["G_ank"][..., :, 0::2].swapaxes(-1, -2)  # (B, 2, 2, 3): G e_x, G e_z
        rows = np.zeros_like(axes)  # v × e_z = (v_y, −v_x, 0)
        rows[..., 0], rows[..., 1] = axes[..., 1], -axes[..., 0]
        A_root = np.concatenate([A_root, rows], axis=2)
        A = np.concatenate([A, np.broadcast_to(rows[:, :, None], (*rows.shape[:2], 3, 2, 3))], 3)
    Jf = _chain_jacobian(pts, s, n, A_root, A)
    Jf[:, :, 0:3, 3:6] = _EYE3
    if n > N_BASE_PARAMS:
        for side in (0, 1):
            Jf[:, side, 0:3, _L0 + side] = pts["d_thigh"][:, side]
            Jf[:, side, 0:3, _L0 + 2 + side] = pts["d_shank"][:, side]
    return Jf


def _flat_residuals(pts: dict[str, FloatArray]) -> FloatArray:
    """World-up components of the ankle frames' left and forward axes (B, 2, 2): 0 when flat."""
    return pts["G_ank"][:, :, 2, 0::2]


def retract(s: ChainState, step: FloatArray) -> ChainState:
    """The state moved by a parameter step (B, n): right increment on the root, sums elsewhere."""
    B = s.t.shape[0]
    E, _ = exp_and_right_jacobian(step[:, 0:3])
    l_new = s.l + step[:, _L0:] if step.shape[1] > N_BASE_PARAMS else s.l
    return ChainState(
        R0=s.R0 @ E,
        t=s.t + step[:, 3:6],
        a=s.a + step[:, _A0:_L0].reshape(B, 6, 3),
        l=l_new,
    )
