"""The filter's state: nominal values and the error-state covariance layout (a plain container).

Nominal state (thesis sec. 3.2, eq. (3.3)): the IMU attitude ``q`` (thesis convention,
``R(q) = R_WfromI``, ``C(q) = R_IfromW``), position ``p_IinW``, velocity ``v_IinW``, gyroscope
and accelerometer biases ``b_g``, ``b_a``; the stochastic clone (the IMU pose at the previous
frame, thesis ``U_{k-1}`` of (3.10) without its velocity) and the stance-foot landmarks
(floor points ``(x, y)`` on ``z = 0``, thesis ``r̄_foot`` of (3.35)).

Error state and covariance layout (``P`` is n×n)::

    [dθ 0:3, δp 3:6, δv 6:9, δb_g 9:12, δb_a 12:15 | dθ_clone 15:18, δp_clone 18:21 | lm ...]

The clone block exists once :func:`gaitnet.vio.covariance.clone` has run; landmarks follow in
augmentation order, 2 dims each. Attitude errors are body-frame rotation vectors
``dθ = 2 q̄_e`` (thesis (3.1): ``q = q̂ ⊗ f_quat(q̄_e)``, applied with
:func:`~gaitnet.geometry.quat_boxplus`), so ``R_WfromI ≈ R̂ (I + [dθ×])``; every other error is
additive. A thesis Jacobian column for ``q̄_e`` is therefore twice ours.

Only :mod:`gaitnet.vio.covariance` changes ``P`` and the layout (clone, landmarks); this module
reads them and applies an error vector to the nominal values (:meth:`FilterState.boxplus`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from gaitnet.geometry import quat_boxplus, rotmat_from_quat

#: A state variable: ``"imu"`` (15), ``"att"``, ``"pos"``, ``"vel"``, ``"bg"``, ``"ba"`` (3 each),
#: ``"clone_att"``, ``"clone_pos"`` (3 each), ``"clone"`` (6) or ``("lm", id)`` (2).
Var = str | tuple[str, int]

IMU_DIM = 15
CLONE_DIM = 6
LM_DIM = 2

_IMU_SLICES: dict[str, slice] = {
    "imu": slice(0, 15),
    "att": slice(0, 3),
    "pos": slice(3, 6),
    "vel": slice(6, 9),
    "bg": slice(9, 12),
    "ba": slice(12, 15),
}
_CLONE_SLICES: dict[str, slice] = {
    "clone": slice(15, 21),
    "clone_att": slice(15, 18),
    "clone_pos": slice(18, 21),
}


@dataclass
class ImuState:
    """Nominal IMU state at time ``t_s`` (filter clock, seconds).

    ``q`` (4,) thesis attitude ``[w, x, y, z]`` with ``rotmat_from_quat(q) = R_WfromI``;
    ``p_IinW``, ``v_IinW`` (3,) world position and velocity; ``b_g`` [rad/s], ``b_a`` [m/s²]
    (3,) biases in the IMU frame (thesis (3.2): ``y = truth + b + η``).
    """

    q: np.ndarray
    p_IinW: np.ndarray
    v_IinW: np.ndarray
    b_g: np.ndarray
    b_a: np.ndarray
    t_s: float

    @property
    def R_WfromI(self) -> np.ndarray:
        """``R(q)``, body (IMU) to world."""
        return rotmat_from_quat(self.q)

    def copy(self) -> ImuState:
        return ImuState(
            self.q.copy(),
            self.p_IinW.copy(),
            self.v_IinW.copy(),
            self.b_g.copy(),
            self.b_a.copy(),
            float(self.t_s),
        )


@dataclass
class PoseClone:
    """The IMU pose at the previous frame (stochastic cloning): ``q`` (thesis attitude) and
    ``p_IinW`` at time ``t_s``."""

    q: np.ndarray
    p_IinW: np.ndarray
    t_s: float

    @property
    def R_WfromI(self) -> np.ndarray:
        return rotmat_from_quat(self.q)

    def copy(self) -> PoseClone:
        return PoseClone(self.q.copy(), self.p_IinW.copy(), float(self.t_s))


@dataclass
class FilterState:
    """Nominal state plus the error-state covariance ``P`` (module docstring for the layout).

    ``landmarks`` maps a landmark id to its floor point ``(x, y)`` (world, ``z = 0``); its order
    (insertion order) is the order of the landmark blocks in ``P``.
    """

    imu: ImuState
    P: np.ndarray
    clone: PoseClone | None = None
    landmarks: dict[int, np.ndarray] = field(default_factory=dict)

    @classmethod
    def new(cls, imu: ImuState, P_imu: np.ndarray) -> FilterState:
        """A state with no clone and no landmarks; ``P_imu`` (15, 15) is copied."""
        P = np.array(P_imu, dtype=np.float64)
        if P.shape != (IMU_DIM, IMU_DIM):
            raise ValueError(f"P_imu must be 15x15, got {P.shape}")
        return cls(imu=imu, P=0.5 * (P + P.T))

    @property
    def dim(self) -> int:
        """Error-state dimension ``n``."""
        return IMU_DIM + (CLONE_DIM if self.clone is not None else 0) + LM_DIM * len(self.landmarks)

    @property
    def landmark_offset(self) -> int:
        """Index in ``P`` of the first landmark block."""
        return IMU_DIM + (CLONE_DIM if self.clone is not None else 0)

    def index(self, var: Var) -> slice:
        """The slice of ``var``'s error block in the error state (see :data:`Var`)."""
        if isinstance(var, tuple):
            kind, lm_id = var
            if kind != "lm":
                raise KeyError(f"unknown state variable {var!r}")
            if lm_id not in self.landmarks:
                raise KeyError(f"no landmark with id {lm_id}")
            k = list(self.landmarks).index(lm_id)
            start = self.landmark_offset + LM_DIM * k
            return slice(start, start + LM_DIM)
        if var in _IMU_SLICES:
            return _IMU_SLICES[var]
        if var in _CLONE_SLICES:
            if self.clone is None:
                raise KeyError(f"state variable {var!r} needs a clone; the state has none")
            return _CLONE_SLICES[var]
        raise KeyError(f"unknown state variable {var!r}")

    def copy(self) -> FilterState:
        return FilterState(
            imu=self.imu.copy(),
            P=self.P.copy(),
            clone=None if self.clone is None else self.clone.copy(),
            landmarks={k: v.copy() for k, v in self.landmarks.items()},
        )

    def boxplus(self, dx: np.ndarray) -> FilterState:
        """``x̂ ⊞ δx``: a new state with the error vector ``dx`` (n,) applied to the nominal
        values (attitudes by :func:`quat_boxplus`, the rest additively); ``P`` is copied
        unchanged. This is the injection step of the error-state filter and the chart the
        Jacobian tests differentiate through."""
        dx = np.asarray(dx, dtype=np.float64)
        if dx.shape != (self.dim,):
            raise ValueError(f"error vector must have shape ({self.dim},), got {dx.shape}")
        out = self.copy()
        imu = out.imu
        imu.q = quat_boxplus(imu.q, dx[0:3])
        imu.p_IinW = imu.p_IinW + dx[3:6]
        imu.v_IinW = imu.v_IinW + dx[6:9]
        imu.b_g = imu.b_g + dx[9:12]
        imu.b_a = imu.b_a + dx[12:15]
        if out.clone is not None:
            out.clone.q = quat_boxplus(out.clone.q, dx[15:18])
            out.clone.p_IinW = out.clone.p_IinW + dx[18:21]
        off = self.landmark_offset
        for k, lm_id in enumerate(out.landmarks):
            out.landmarks[lm_id] = out.landmarks[lm_id] + dx[off + 2 * k : off + 2 * k + 2]
        return out
