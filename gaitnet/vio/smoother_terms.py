"""The smoother's variables and its whitened residuals with their sparse Jacobians (sec. 3.5).

Variables (thesis ``X_smoother`` of sec. 3.5, as errors about the current estimate, thesis
(3.49)–(3.50)): per frame ``k`` the IMU attitude, position and velocity (9 error dims:
``[dθ, δp, δv]``, ``dθ`` the body-frame rotation vector, :mod:`gaitnet.vio.state`), one gyroscope
and one accelerometer bias for the session (6; the thesis's ``b_g,e``, ``b_a,e``), and each
stance-foot landmark's floor point ``(x, y)`` (2). Column layout: frame ``k`` at ``9k``, the
biases at ``9N``, landmark ``j`` at ``9N + 6 + 2j``.

Terms, each ``½ ‖W e(x)‖²`` with ``WᵀW = Σ⁻¹`` (the thesis's ``quad(a, B)`` corrected to
``½ aᵀ B⁻¹ a`` as in (2.19)):

* prior: ``x_0 ⊟ x_init`` on frame 0's 9 dims and the biases, covariance ``P_init`` (thesis
  ``quad(U_init − U_1, P_U,init)`` and the two bias priors of (2.19); ``U_init`` is the filter's
  initialisation, which takes the conjugate ``q̂₁* ⊗ q̂_tag,1`` of the corrected form);
* dynamics between consecutive frames, thesis ``quad(ζ̄_k,1, Q_ζ̄k,11)`` with
  ``ζ̄_k,1 = U_k+1 − F̄11,k U_k − F̄12,k [b_g,e; b_a,e]`` of (3.8)–(3.9) in its nonlinear form
  (preintegrated, :mod:`gaitnet.vio.records`)::

      e_R = Log(Exp(−J_R δb) ΔRᵀ R_kᵀ R_k+1)
      e_p = R_kᵀ (p_k+1 − p_k − v_k T + ½ g̃ T²) − Δp − J_p δb
      e_v = R_kᵀ (v_k+1 − v_k + g̃ T) − Δv − J_v δb,    δb = b − b̄_k,

  whose Jacobian at the filter's nominal states is ``[−F̄11 | I | −F̄12]`` rotated into the
  body frame; at the filter's estimates ``e`` is the filter's update jump at ``k+1``, so
  linearising around them accounts for the jumps (thesis-notes);
* VO, tag and stance-foot terms (:mod:`gaitnet.vio.smoother_measurements`): the filter's own
  measurement functions
  (``vo_model.vo_measurement``, ``tag_model.tag_measurement``, ``foot_model.foot_measurement``,
  thesis (3.21), (3.33), (3.47)) evaluated on a :class:`~gaitnet.vio.state.FilterState` built from
  the smoother's frames (current IMU pose, the earlier frame as the clone, the observed
  landmark); ``e = z ⊟ h(x)``, Jacobian ``−H``. The tag term is the position block with the end
  sheet's ``ε2`` (thesis-notes: not the attitude block), the foot term acts on ``U_k`` (not
  ``X_k``).

The Jacobian is assembled as COO triplets into a ``scipy.sparse`` CSR matrix; nothing here forms
a dense matrix wider than one term.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from gaitnet.geometry import (
    quat_boxminus,
    quat_boxplus,
    rotmat_from_quat,
    skew,
    so3_exp,
    so3_left_jacobian_inv,
    so3_log,
    so3_right_jacobian,
    so3_right_jacobian_inv,
)
from gaitnet.vio.records import FilterRecord

FRAME_DIM = 9
BIAS_DIM = 6

#: Term kinds, in the order their rows are stacked.
KINDS = ("prior", "imu", "vo", "tag", "foot")


@dataclass
class SmootherVariables:
    """The smoother's nominal values: per frame ``q`` (N, 4), ``p_IinW``, ``v_IinW`` (N, 3); the
    session biases ``b_g``, ``b_a`` (3,); landmarks ``lm_xy`` (M, 2) with ids ``lm_ids``."""

    q: np.ndarray
    p_IinW: np.ndarray
    v_IinW: np.ndarray
    b_g: np.ndarray
    b_a: np.ndarray
    lm_ids: list[int]
    lm_xy: np.ndarray

    @property
    def n_frames(self) -> int:
        return int(self.q.shape[0])

    @property
    def dim(self) -> int:
        """Error-state dimension ``9N + 6 + 2M``."""
        return FRAME_DIM * self.n_frames + BIAS_DIM + 2 * len(self.lm_ids)

    @property
    def bias_col(self) -> int:
        return FRAME_DIM * self.n_frames

    def lm_col(self, j: int) -> int:
        return self.bias_col + BIAS_DIM + 2 * j

    def boxplus(self, dx: np.ndarray) -> SmootherVariables:
        """``x ⊞ δx``: attitudes by :func:`quat_boxplus` (body-frame ``dθ``), the rest added."""
        n = self.n_frames
        d = np.asarray(dx, dtype=np.float64)
        if d.shape != (self.dim,):
            raise ValueError(f"error vector must have shape ({self.dim},), got {d.shape}")
        f = d[: FRAME_DIM * n].reshape(n, FRAME_DIM)
        b = d[self.bias_col : self.bias_col + BIAS_DIM]
        return SmootherVariables(
            q=quat_boxplus(self.q, f[:, 0:3]),
            p_IinW=self.p_IinW + f[:, 3:6],
            v_IinW=self.v_IinW + f[:, 6:9],
            b_g=self.b_g + b[0:3],
            b_a=self.b_a + b[3:6],
            lm_ids=list(self.lm_ids),
            lm_xy=self.lm_xy + d[self.bias_col + BIAS_DIM :].reshape(-1, 2),
        )

    @classmethod
    def from_record(cls, record: FilterRecord) -> SmootherVariables:
        """The filter's estimates: per-frame nominal states, the last frame's biases (the
        thesis's ``b̂`` = the filter's final values) and the observed landmarks."""
        observed = sorted({f.landmark_id for f in record.feet})
        lm = np.array([record.landmarks[i] for i in observed], dtype=np.float64).reshape(-1, 2)
        return cls(
            q=record.q.copy(),
            p_IinW=record.p_IinW.copy(),
            v_IinW=record.v_IinW.copy(),
            b_g=record.b_g[-1].copy(),
            b_a=record.b_a[-1].copy(),
            lm_ids=observed,
            lm_xy=lm,
        )


@dataclass
class TermBlock:
    """Whitened residuals of one kind (``residual`` (m,)) and their Jacobian as COO triplets
    (row indices local to this block)."""

    kind: str
    residual: np.ndarray
    rows: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    cols: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    vals: np.ndarray = field(default_factory=lambda: np.zeros(0))


def whitener(cov: np.ndarray, floor: float = 0.0) -> np.ndarray:
    """``W = L⁻¹`` with ``cov + floor·I = L Lᵀ`` (batched over leading axes): ``‖W e‖² =
    eᵀ cov⁻¹ e``. ``floor`` keeps a noise-free (singular) covariance usable."""
    c = np.asarray(cov, dtype=np.float64)
    c = 0.5 * (c + np.swapaxes(c, -1, -2))
    if floor > 0.0:
        c = c + floor * np.eye(c.shape[-1])
    L = np.linalg.cholesky(c)
    return np.linalg.inv(L)


# --------------------------------------------------------------------------- prior


@dataclass(frozen=True)
class PriorData:
    """``x_init`` (frame 0 and the biases) and the whitener of ``P_init`` (15, 15)."""

    q: np.ndarray
    p_IinW: np.ndarray
    v_IinW: np.ndarray
    b: np.ndarray
    W: np.ndarray


def prior_data(record: FilterRecord, floor: float) -> PriorData:
    x = record.x_prior
    return PriorData(
        q=x.q.copy(),
        p_IinW=x.p_IinW.copy(),
        v_IinW=x.v_IinW.copy(),
        b=np.concatenate([x.b_g, x.b_a]),
        W=whitener(record.P_prior, floor),
    )


def prior_term(x: SmootherVariables, pd: PriorData, jacobian: bool) -> TermBlock:
    """``x_0 ⊟ x_init`` (15,) whitened by ``P_init`` (sec. 3.5 ``quad(U_init − U_1, P_U,init)``
    and (2.19)'s bias priors, with ``quad`` corrected to ``½ aᵀ B⁻¹ a``)."""
    e_th = so3_log(rotmat_from_quat(pd.q).T @ rotmat_from_quat(x.q[0]))
    e = np.concatenate(
        [
            e_th,
            x.p_IinW[0] - pd.p_IinW,
            x.v_IinW[0] - pd.v_IinW,
            np.concatenate([x.b_g, x.b_a]) - pd.b,
        ]
    )
    block = TermBlock("prior", pd.W @ e)
    if jacobian:
        J = np.eye(15)
        J[0:3, 0:3] = so3_right_jacobian_inv(e_th)
        cols = np.concatenate([np.arange(FRAME_DIM), x.bias_col + np.arange(BIAS_DIM)])
        _dense_block(block, pd.W @ J, np.arange(15), cols)
    return block


# --------------------------------------------------------------------------- dynamics


@dataclass(frozen=True)
class DynamicsData:
    """The record's IMU intervals stacked: ``T`` (K,), ``dR`` (K, 3, 3), ``dp``, ``dv`` (K, 3),
    ``J_bias`` (K, 9, 6), ``b_lin`` (K, 6), ``W`` (K, 9, 9) whiteners of ``Q``, ``g`` (3,)."""

    T: np.ndarray
    dR: np.ndarray
    dp: np.ndarray
    dv: np.ndarray
    J_bias: np.ndarray
    b_lin: np.ndarray
    W: np.ndarray
    g: np.ndarray


def dynamics_data(record: FilterRecord, floor: float) -> DynamicsData:
    iv = record.intervals
    K = len(iv)
    g = np.array([0.0, 0.0, iv[0].gravity_mps2 if K else 0.0])
    if K == 0:
        z3 = np.zeros((0, 3))
        return DynamicsData(
            np.zeros(0), np.zeros((0, 3, 3)), z3, z3, np.zeros((0, 9, 6)), np.zeros((0, 6)),
            np.zeros((0, 9, 9)), g,
        )  # fmt: skip
    return DynamicsData(
        T=np.array([i.dt_s for i in iv]),
        dR=np.stack([i.dR for i in iv]),
        dp=np.stack([i.dp for i in iv]),
        dv=np.stack([i.dv for i in iv]),
        J_bias=np.stack([i.J_bias for i in iv]),
        b_lin=np.stack([np.concatenate([i.b_g, i.b_a]) for i in iv]),
        W=whitener(np.stack([i.Q for i in iv]), floor),
        g=g,
    )


def dynamics_term(x: SmootherVariables, dd: DynamicsData, jacobian: bool) -> TermBlock:
    """The IMU terms between all consecutive frames at once (module docstring; thesis
    (3.8)–(3.9) and sec. 3.5's ``quad(ζ̄_k,1, Q_ζ̄k,11)``), with the exact Jacobian of the
    nonlinear residual."""
    K = dd.T.shape[0]
    if K == 0:
        return TermBlock("imu", np.zeros(0))
    R = rotmat_from_quat(x.q)
    Rk, Rk1 = R[:-1], R[1:]
    RkT = np.swapaxes(Rk, -1, -2)
    b = np.concatenate([x.b_g, x.b_a])
    db = b[None, :] - dd.b_lin  # (K, 6)
    JR, Jp, Jv = dd.J_bias[:, 0:3], dd.J_bias[:, 3:6], dd.J_bias[:, 6:9]
    phi = (JR @ db[..., None])[..., 0]
    Ephi_T = so3_exp(-phi)
    dRT = np.swapaxes(dd.dR, -1, -2)
    E = Ephi_T @ dRT @ RkT @ Rk1
    e_R = so3_log(E)
    T = dd.T[:, None]
    w = (RkT @ (x.p_IinW[1:] - x.p_IinW[:-1] - x.v_IinW[:-1] * T + 0.5 * dd.g * T * T)[..., None])[
        ..., 0
    ]
    u = (RkT @ (x.v_IinW[1:] - x.v_IinW[:-1] + dd.g * T)[..., None])[..., 0]
    e_p = w - dd.dp - (Jp @ db[..., None])[..., 0]
    e_v = u - dd.dv - (Jv @ db[..., None])[..., 0]
    e = np.concatenate([e_R, e_p, e_v], axis=1)  # (K, 9)
    block = TermBlock("imu", (dd.W @ e[..., None])[..., 0].reshape(-1))
    if not jacobian:
        return block
    Jli = so3_left_jacobian_inv(e_R)
    J = np.zeros((K, 9, 24))  # columns: frame k (9), frame k+1 (9), biases (6)
    J[:, 0:3, 0:3] = -Jli @ Ephi_T @ dRT
    J[:, 0:3, 9:12] = so3_right_jacobian_inv(e_R)
    J[:, 0:3, 18:24] = -Jli @ so3_right_jacobian(phi) @ JR
    J[:, 3:6, 0:3] = skew(w)
    J[:, 3:6, 3:6] = -RkT
    J[:, 3:6, 6:9] = -T[..., None] * RkT
    J[:, 3:6, 12:15] = RkT
    J[:, 3:6, 18:24] = -Jp
    J[:, 6:9, 0:3] = skew(u)
    J[:, 6:9, 6:9] = -RkT
    J[:, 6:9, 15:18] = RkT
    J[:, 6:9, 18:24] = -Jv
    Jw = dd.W @ J
    k = np.arange(K)
    cols = np.concatenate(
        [
            FRAME_DIM * k[:, None] + np.arange(FRAME_DIM),
            FRAME_DIM * (k[:, None] + 1) + np.arange(FRAME_DIM),
            np.broadcast_to(x.bias_col + np.arange(BIAS_DIM), (K, BIAS_DIM)),
        ],
        axis=1,
    )  # (K, 24)
    rows = FRAME_DIM * k[:, None] + np.arange(FRAME_DIM)  # (K, 9)
    block.rows = np.broadcast_to(rows[:, :, None], (K, 9, 24)).reshape(-1)
    block.cols = np.broadcast_to(cols[:, None, :], (K, 9, 24)).reshape(-1)
    block.vals = Jw.reshape(-1)
    return block


# --------------------------------------------------------------------------- assembly


def _dense_block(block: TermBlock, J: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> None:
    block.rows = np.repeat(rows, cols.size)
    block.cols = np.tile(cols, rows.size)
    block.vals = J.reshape(-1)


def stack_blocks(blocks: list[TermBlock], n_cols: int) -> tuple[np.ndarray, sp.csr_matrix]:
    """The stacked whitened residual and the Jacobian as CSR (COO triplets summed)."""
    offset = 0
    res, r, c, v = [], [], [], []
    for b in blocks:
        res.append(b.residual)
        r.append(b.rows + offset)
        c.append(b.cols)
        v.append(b.vals)
        offset += b.residual.shape[0]
    J = sp.coo_matrix(
        (np.concatenate(v), (np.concatenate(r), np.concatenate(c))), shape=(offset, n_cols)
    ).tocsr()
    return np.concatenate(res), J


def frame_errors(a: SmootherVariables, b: SmootherVariables) -> np.ndarray:
    """``a ⊟ b`` per frame (N, 9) (for diagnostics and tests)."""
    return np.concatenate(
        [quat_boxminus(a.q, b.q), a.p_IinW - b.p_IinW, a.v_IinW - b.v_IinW], axis=1
    )
