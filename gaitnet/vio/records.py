"""The record of a filter run that the smoother consumes (thesis sec. 3.5).

The smoother of sec. 3.5 re-estimates every frame's IMU state from the same information the
filter used: the IMU between frames, the visual-odometry, AprilTag and stance-foot measurements,
and the initialisation. :class:`FilterRecorder` collects them while the filter runs (one call per
event, in the order the filter meets them) and :meth:`FilterRecorder.finish` freezes them into a
:class:`FilterRecord` of plain arrays.

Frame indices in a record are positions in the record (0 … N−1, the frames the filter
processed), not session frame numbers; :attr:`FilterRecord.session_index` maps back.

The IMU between frames ``k`` and ``k+1`` is kept as a preintegrated increment
(:class:`ImuInterval`): with the core's mechanisation (:mod:`gaitnet.vio.imu_propagation`) the
state at ``k+1`` is an exact function of the state at ``k``,

    ``R_{k+1} = R_k ΔR``, ``v_{k+1} = v_k + R_k Δv − g̃ T``,
    ``p_{k+1} = p_k + v_k T + R_k Δp − ½ g̃ T²``  (``g̃ = [0, 0, g]``, ``T`` the interval),

where ``(ΔR, Δp, Δv)`` depend on the readings and the biases only (the rotation chain starts
from the identity). So one propagation per interval, done by the filter anyway, serves every
smoother iteration; a bias change ``δb`` is applied to first order with the bias columns of the
lifted transition ``Φ`` (thesis (3.8)), and the noise is ``Q̄``'s 9×9 block (thesis (3.9))
expressed in the body frame at ``k``. Error-state conventions: :mod:`gaitnet.vio.state`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from gaitnet.geometry import rotmat_from_quat
from gaitnet.io.types import ImuNoise, ImuSamples
from gaitnet.vio.imu_propagation import GRAVITY_MPS2, ImuNoiseLike, propagate_to
from gaitnet.vio.state import FilterState, ImuState

#: Scale of the bias block of the probe covariance in :func:`preintegrate` (a power of two, so
#: dividing it out is exact).
_PROBE = 2.0**-20


@dataclass(frozen=True)
class ImuInterval:
    """The IMU between two consecutive recorded frames, preintegrated (module docstring).

    ``dt_s`` the interval ``T``; ``dR`` (3, 3) ``R_{I_k from I_k+1}``; ``dp``, ``dv`` (3,) in
    the IMU frame at ``k``; all at the linearisation biases ``b_g``, ``b_a`` (3,) (the filter's
    at frame ``k``). ``J_bias`` (9, 6): rows ``[dθ_end, δΔp, δΔv]`` (``dθ_end`` in the body frame
    at ``k+1``, ``Δp``/``Δv`` in the body frame at ``k``), columns ``[δb_g, δb_a]``, so
    ``ΔR(b + δb) ≈ ΔR Exp(J_bias[0:3] δb)``, ``Δp(b + δb) ≈ Δp + J_bias[3:6] δb`` and likewise
    ``Δv``. ``Q`` (9, 9) the covariance of the reading noise in the same coordinates (thesis
    ``Q_ζ̄,11`` of (3.9), rotated into the body frame at ``k``). ``gravity_mps2`` ``g``.
    """

    dt_s: float
    dR: np.ndarray
    dp: np.ndarray
    dv: np.ndarray
    J_bias: np.ndarray
    Q: np.ndarray
    b_g: np.ndarray
    b_a: np.ndarray
    gravity_mps2: float = GRAVITY_MPS2

    @classmethod
    def from_propagation(
        cls,
        before: ImuState,
        after: ImuState,
        Phi15: np.ndarray,
        Q15: np.ndarray,
        gravity_mps2: float = GRAVITY_MPS2,
    ) -> ImuInterval:
        """The interval from one filter time update (thesis (3.8)): the nominal IMU state
        ``before`` the propagation (the filter's state after its updates at frame ``k``), the
        nominal ``after`` it (at frame ``k+1``, before updates), and the lifted ``Φ`` and ``Q̄``
        (15×15) of :func:`gaitnet.vio.imu_propagation.lift`. Only ``Φ[0:9, 9:15]`` and
        ``Q̄[0:9, 0:9]`` are read (the other blocks follow from the increments)."""
        R_k = rotmat_from_quat(before.q)
        T = float(after.t_s - before.t_s)
        g = np.array([0.0, 0.0, gravity_mps2])
        dR = R_k.T @ rotmat_from_quat(after.q)
        dv = R_k.T @ (after.v_IinW - before.v_IinW + g * T)
        dp = R_k.T @ (after.p_IinW - before.p_IinW - before.v_IinW * T + 0.5 * g * T * T)
        A_inv = np.eye(9)
        A_inv[3:6, 3:6] = R_k.T
        A_inv[6:9, 6:9] = R_k.T
        J_bias = A_inv @ np.asarray(Phi15, dtype=np.float64)[0:9, 9:15]
        Q = A_inv @ np.asarray(Q15, dtype=np.float64)[0:9, 0:9] @ A_inv.T
        return cls(
            dt_s=T,
            dR=dR,
            dp=dp,
            dv=dv,
            J_bias=J_bias,
            Q=0.5 * (Q + Q.T),
            b_g=before.b_g.copy(),
            b_a=before.b_a.copy(),
            gravity_mps2=float(gravity_mps2),
        )


def preintegrate(
    before: ImuState,
    imu: ImuSamples,
    t_end_s: float,
    noise: ImuNoiseLike,
    *,
    gravity_mps2: float = GRAVITY_MPS2,
    t_ref_ns: int = 0,
) -> tuple[ImuInterval, ImuState]:
    """Propagate ``before`` to ``t_end_s`` with the core's :func:`propagate_to` and return the
    :class:`ImuInterval` and the propagated nominal state (the nominal equals the filter's).

    For a caller that does not have the lifted ``Φ``, ``Q̄`` at hand: a probe covariance
    ``P₀ = diag(0₉, s² I₆)`` propagated with reading noise only (bias random walks zero) gives
    ``P = Φ P₀ Φᵀ + Q̄`` with ``P[0:9, 9:15] = s² Φ[0:9, 9:15]`` (the bias rows of ``Φ`` are the
    identity, thesis (3.5)) and ``Q̄[0:9, 0:9] = P[0:9, 0:9] − s² Φ_b Φ_bᵀ``. The smoother holds
    the biases constant over the session (sec. 3.5), so the random walk is not part of ``Q``.
    """
    P0 = np.zeros((15, 15))
    P0[9:15, 9:15] = _PROBE * np.eye(6)
    state = FilterState(imu=before.copy(), P=P0)
    reading_noise = ImuNoise(
        gyro_noise_density=float(noise.gyro_noise_density),
        accel_noise_density=float(noise.accel_noise_density),
        gyro_bias_random_walk=0.0,
        accel_bias_random_walk=0.0,
    )
    propagate_to(state, imu, t_end_s, reading_noise, gravity_mps2=gravity_mps2, t_ref_ns=t_ref_ns)
    P = state.P
    Phi_b = P[0:9, 9:15] / _PROBE
    Phi15 = np.eye(15)
    Phi15[0:9, 9:15] = Phi_b
    Q15 = np.zeros((15, 15))
    Q15[0:9, 0:9] = P[0:9, 0:9] - _PROBE * (Phi_b @ Phi_b.T)
    interval = ImuInterval.from_propagation(before, state.imu, Phi15, Q15, gravity_mps2)
    return interval, state.imu


@dataclass(frozen=True)
class VoRecord:
    """A visual-odometry measurement between frames ``frame_prev`` and ``frame`` (thesis
    (3.11)–(3.21)): ``R`` (3, 3), ``t`` (3,) with ``p_Ck = R p_Ck−1 + t``, ``cov6`` (6, 6)
    (rotation then translation), exactly as given to ``vo_model.vo_measurement``."""

    frame_prev: int
    frame: int
    R: np.ndarray
    t: np.ndarray
    cov6: np.ndarray


@dataclass(frozen=True)
class TagRecord:
    """An AprilTag board observation at ``frame`` (thesis (3.27)–(3.34)), with the arguments
    given to ``tag_model.tag_measurement``: the camera pose ``T_WfromC`` (4, 4), ``cov6``
    (``R_tag`` of (3.30), rotation then position), ``end_sheet_eps2`` (``ε2`` [m²] of the end
    sheet, 0 elsewhere) and ``use_attitude``. ``is_first``: the detection that initialised the
    filter; its information is in the prior (:attr:`FilterRecord.P_prior`), so the smoother
    does not use it a second time."""

    frame: int
    T_WfromC: np.ndarray
    cov6: np.ndarray
    end_sheet_eps2: float = 0.0
    use_attitude: bool = False
    is_first: bool = False

    @property
    def end_sheet(self) -> bool:
        return self.end_sheet_eps2 > 0.0


@dataclass(frozen=True)
class FootRecord:
    """A stance-foot observation at ``frame`` of landmark ``landmark_id`` (thesis
    (3.35)–(3.48)): the foot point on the floor in the camera frame ``p_FinC`` (3,) and its
    noise ``R3`` (3, 3), as given to ``foot_model.foot_measurement`` (or, for the observation
    that created the landmark, to ``landmark_from_observation``: ``is_first``)."""

    frame: int
    landmark_id: int
    p_FinC: np.ndarray
    R3: np.ndarray
    is_first: bool = False


@dataclass(frozen=True)
class FilterRecord:
    """Everything the smoother needs from one filter run (N frames, M landmarks).

    Per frame (arrays with N rows): ``t_s`` filter time, ``session_index`` the session frame
    number, and the filter's nominal IMU state after its updates at that frame: ``q`` (N, 4)
    (thesis attitude, ``R(q) = R_WfromI``), ``p_IinW``, ``v_IinW``, ``b_g``, ``b_a`` (N, 3).
    ``intervals`` (N−1): the IMU between frames ``k`` and ``k+1``. ``x_prior`` /
    ``P_prior`` (15, 15): the initialisation at frame 0 (tag pose or gravity/floor, the
    thesis's ``U_init``, velocity and bias priors of (2.19)), ``P_prior`` in the error state
    ``[dθ, δp, δv, δb_g, δb_a]``. ``landmarks``: the filter's last estimate of every landmark
    ``(x, y)`` (the smoother's starting point). ``T_CfromI`` (4, 4) the camera extrinsic.
    """

    t_s: np.ndarray
    session_index: np.ndarray
    q: np.ndarray
    p_IinW: np.ndarray
    v_IinW: np.ndarray
    b_g: np.ndarray
    b_a: np.ndarray
    intervals: list[ImuInterval]
    x_prior: ImuState
    P_prior: np.ndarray
    T_CfromI: np.ndarray
    vo: list[VoRecord] = field(default_factory=list)
    tags: list[TagRecord] = field(default_factory=list)
    feet: list[FootRecord] = field(default_factory=list)
    landmarks: dict[int, np.ndarray] = field(default_factory=dict)

    @property
    def n_frames(self) -> int:
        return int(self.t_s.shape[0])

    def imu_state(self, k: int) -> ImuState:
        """The filter's nominal state at frame ``k``."""
        return ImuState(
            self.q[k].copy(),
            self.p_IinW[k].copy(),
            self.v_IinW[k].copy(),
            self.b_g[k].copy(),
            self.b_a[k].copy(),
            float(self.t_s[k]),
        )

    def validate(self) -> None:
        """Raise ``ValueError`` naming the first inconsistency (shapes, indices, landmarks)."""
        n = self.n_frames
        if n < 1:
            raise ValueError("a filter record needs at least one frame")
        for name in ("q", "p_IinW", "v_IinW", "b_g", "b_a"):
            arr = getattr(self, name)
            width = 4 if name == "q" else 3
            if arr.shape != (n, width):
                raise ValueError(f"record.{name} has shape {arr.shape}, expected {(n, width)}")
            if not np.all(np.isfinite(arr)):
                raise ValueError(f"record.{name} is not finite")
        if len(self.intervals) != n - 1:
            raise ValueError(f"record has {n} frames but {len(self.intervals)} IMU intervals")
        if np.any(np.diff(self.t_s) <= 0.0):
            raise ValueError("record frame times are not increasing")
        if self.P_prior.shape != (15, 15):
            raise ValueError(f"record.P_prior has shape {self.P_prior.shape}, expected (15, 15)")
        for m in self.vo:
            if not (0 <= m.frame_prev < m.frame < n):
                raise ValueError(f"VO record between frames {m.frame_prev} and {m.frame} (of {n})")
        for m in self.tags:
            if not 0 <= m.frame < n:
                raise ValueError(f"tag record at frame {m.frame} (of {n})")
        for m in self.feet:
            if not 0 <= m.frame < n:
                raise ValueError(f"foot record at frame {m.frame} (of {n})")
            if m.landmark_id not in self.landmarks:
                raise ValueError(f"foot record of landmark {m.landmark_id} with no estimate")


class FilterRecorder:
    """Collects a :class:`FilterRecord` while the filter runs.

    Per frame, in the filter's order (Algorithm 1 of sec. 3.5)::

        rec = FilterRecorder(T_CfromI, gravity_mps2)
        # frame 0: initialise the state (tag or gravity/floor), then
        rec.set_prior(state)                        # x_init, P_init (15×15 IMU block)
        rec.add_frame(state, session_index=0)
        for each later frame i:
            before = state.imu.copy()
            clone(state); propagate_to(state, imu, t_i, noise)   (Φ, Q̄ of this step)
            rec.add_propagation(before, state.imu, Phi, Q)     # or rec.add_interval(...)
            rec.add_vo(R, t, cov6)                  # each ACCEPTED update, as given to it
            rec.add_tag(T_WfromC, cov6, end_sheet_eps2=...)
            rec.add_foot(lm_id, p_FinC, R3, is_first=...)      # augmentation or update
            rec.add_frame(state, session_index=i)   # nominal after the updates
        record = rec.finish()

    The measurements added between two :meth:`add_frame` calls belong to the frame added next
    (VO pairs it with the previous frame); :meth:`add_frame` also stores the current landmark
    estimates (a marginalised landmark keeps its last one).
    """

    def __init__(self, T_CfromI: np.ndarray, gravity_mps2: float = GRAVITY_MPS2) -> None:
        self.T_CfromI = np.asarray(T_CfromI, dtype=np.float64).copy()
        self.gravity_mps2 = float(gravity_mps2)
        self._frames: list[ImuState] = []
        self._session_index: list[int] = []
        self._intervals: list[ImuInterval] = []
        self._vo: list[VoRecord] = []
        self._tags: list[TagRecord] = []
        self._feet: list[FootRecord] = []
        self._landmarks: dict[int, np.ndarray] = {}
        self._prior: tuple[ImuState, np.ndarray] | None = None

    @property
    def current_frame(self) -> int:
        """The record index the next measurements belong to (the frame not yet added)."""
        return len(self._frames)

    def set_prior(self, state: FilterState) -> None:
        """The initialisation: ``state``'s nominal IMU state and the 15×15 IMU block of P."""
        self._prior = (state.imu.copy(), np.array(state.P[0:15, 0:15], dtype=np.float64))

    def add_interval(self, interval: ImuInterval) -> None:
        """The IMU between the last added frame and the next one."""
        if len(self._intervals) != len(self._frames) - 1:
            raise ValueError("add_interval: one interval per pair of frames (add_frame first)")
        self._intervals.append(interval)

    def add_propagation(
        self, before: ImuState, after: ImuState, Phi15: np.ndarray, Q15: np.ndarray
    ) -> None:
        """:meth:`add_interval` from one time update (:meth:`ImuInterval.from_propagation`)."""
        self.add_interval(
            ImuInterval.from_propagation(before, after, Phi15, Q15, self.gravity_mps2)
        )

    def add_vo(self, R: np.ndarray, t: np.ndarray, cov6: np.ndarray) -> None:
        """An accepted VO update between the previous frame and the current one."""
        k = self.current_frame
        if k < 1:
            raise ValueError("add_vo: VO needs a previous frame")
        self._vo.append(VoRecord(k - 1, k, _arr(R), _arr(t), _arr(cov6)))

    def add_tag(
        self,
        T_WfromC: np.ndarray,
        cov6: np.ndarray,
        *,
        end_sheet_eps2: float = 0.0,
        use_attitude: bool = False,
        is_first: bool = False,
    ) -> None:
        """An accepted tag update (or, ``is_first``, the initialising detection), with the
        arguments given to ``tag_measurement``."""
        self._tags.append(
            TagRecord(
                self.current_frame,
                _arr(T_WfromC),
                _arr(cov6),
                float(end_sheet_eps2),
                bool(use_attitude),
                bool(is_first),
            )
        )

    def add_foot(
        self, landmark_id: int, p_FinC: np.ndarray, R3: np.ndarray, *, is_first: bool = False
    ) -> None:
        """A stance-foot observation: an accepted update, or (``is_first``) the augmentation."""
        self._feet.append(
            FootRecord(self.current_frame, int(landmark_id), _arr(p_FinC), _arr(R3), is_first)
        )

    def add_frame(self, state: FilterState, session_index: int | None = None) -> None:
        """The filter's state after its updates at this frame."""
        self._frames.append(state.imu.copy())
        self._session_index.append(
            len(self._frames) - 1 if session_index is None else int(session_index)
        )
        for lm_id, xy in state.landmarks.items():
            self._landmarks[int(lm_id)] = np.array(xy, dtype=np.float64)

    def set_landmark(self, landmark_id: int, xy: np.ndarray) -> None:
        """The filter's current estimate of a landmark (call before marginalising it, if the
        updates of this frame are not yet stored by :meth:`add_frame`)."""
        self._landmarks[int(landmark_id)] = np.array(xy, dtype=np.float64)

    def finish(self) -> FilterRecord:
        """The :class:`FilterRecord` (validated)."""
        if self._prior is None:
            raise ValueError("FilterRecorder.finish: set_prior was never called")
        fr = self._frames
        record = FilterRecord(
            t_s=np.array([s.t_s for s in fr], dtype=np.float64),
            session_index=np.array(self._session_index, dtype=np.int64),
            q=np.array([s.q for s in fr], dtype=np.float64).reshape(-1, 4),
            p_IinW=np.array([s.p_IinW for s in fr], dtype=np.float64).reshape(-1, 3),
            v_IinW=np.array([s.v_IinW for s in fr], dtype=np.float64).reshape(-1, 3),
            b_g=np.array([s.b_g for s in fr], dtype=np.float64).reshape(-1, 3),
            b_a=np.array([s.b_a for s in fr], dtype=np.float64).reshape(-1, 3),
            intervals=list(self._intervals),
            x_prior=self._prior[0],
            P_prior=self._prior[1],
            T_CfromI=self.T_CfromI,
            vo=list(self._vo),
            tags=list(self._tags),
            feet=list(self._feet),
            landmarks=dict(self._landmarks),
        )
        record.validate()
        return record


def _arr(a: np.ndarray) -> np.ndarray:
    return np.array(a, dtype=np.float64)
