"""The smoother's VO, tag and stance-foot terms: the filter's own measurement functions
evaluated on the smoother's variables (sec. 3.5; :mod:`gaitnet.vio.smoother_terms` has the
variables, the prior and dynamics terms and the assembly).

A measurement function (``vo_model.vo_measurement``, ``tag_model.tag_measurement``,
``foot_model.foot_measurement``, thesis (3.21), (3.33), (3.47)) sees a
:class:`~gaitnet.vio.state.FilterState` built from the smoother's frames (current IMU pose, the
earlier frame as the clone, the observed landmark); the term is ``e = z ⊟ h(x)`` with Jacobian
``−H``, whitened by the measurement's constant covariance. Terms of one kind share their
structure and are evaluated as one :class:`MeasurementGroup`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from gaitnet.geometry import so3_right_jacobian_inv
from gaitnet.vio.measurement import Measurement
from gaitnet.vio.smoother_terms import (
    FRAME_DIM,
    KINDS,
    SmootherVariables,
    TermBlock,
    whitener,
)
from gaitnet.vio.state import FilterState, ImuState, PoseClone, Var

__all__ = [
    "MeasurementFn",
    "MeasurementGroup",
    "MeasurementTerm",
    "filter_state_at",
    "group_terms",
]

#: A measurement function of the filter: ``FilterState -> Measurement``.
MeasurementFn = Callable[[FilterState], Measurement]


@dataclass(frozen=True)
class MeasurementTerm:
    """One measurement of the record: its kind, the frame of the current IMU pose, the frame
    used as the clone (VO) or ``None``, the observed landmark id or ``None``, the filter's
    measurement function closed over its data (``fn(state) -> Measurement``), and
    ``so3_rows``: the residual rows (start, stop) that are a rotation vector
    ``log(R_meas R_predᵀ)`` (VO (3.15) in the rotation-vector form), whose exact derivative is
    ``J_r⁻¹(e)`` times the model's tangent Jacobian ``H`` (equal at ``e = 0``)."""

    kind: str
    frame: int
    clone_frame: int | None
    landmark_id: int | None
    fn: MeasurementFn
    so3_rows: tuple[int, int] | None = None


def filter_state_at(
    x: SmootherVariables, term: MeasurementTerm, lm_index: dict[int, int]
) -> FilterState:
    """The :class:`FilterState` a measurement function sees for ``term``: the smoother's frame
    ``term.frame`` as the IMU state, ``term.clone_frame`` as the clone, the observed landmark.
    ``P`` is a zero matrix of the right size (measurement functions do not read it)."""
    k = term.frame
    imu = ImuState(x.q[k], x.p_IinW[k], x.v_IinW[k], x.b_g, x.b_a, 0.0)
    clone = None
    if term.clone_frame is not None:
        c = term.clone_frame
        clone = PoseClone(x.q[c], x.p_IinW[c], 0.0)
    landmarks = {}
    if term.landmark_id is not None:
        landmarks[term.landmark_id] = x.lm_xy[lm_index[term.landmark_id]]
    dim = 15 + (6 if clone is not None else 0) + 2 * len(landmarks)
    return FilterState(imu=imu, P=np.zeros((dim, dim)), clone=clone, landmarks=landmarks)


def _var_columns(
    var: Var, term: MeasurementTerm, x: SmootherVariables, lm_index: dict[int, int]
) -> np.ndarray:
    """The smoother columns of the filter's state variable ``var`` for ``term``."""
    f = FRAME_DIM * term.frame
    b = x.bias_col
    if isinstance(var, tuple):
        return x.lm_col(lm_index[var[1]]) + np.arange(2)
    if var.startswith("clone"):
        if term.clone_frame is None:
            raise ValueError(f"{term.kind} measurement has a clone block but no clone frame")
        c = FRAME_DIM * term.clone_frame
        return {"clone": c + np.arange(6), "clone_att": c + np.arange(3),
                "clone_pos": c + 3 + np.arange(3)}[var]  # fmt: skip
    table = {
        "imu": np.concatenate([f + np.arange(9), b + np.arange(6)]),
        "att": f + np.arange(3),
        "pos": f + 3 + np.arange(3),
        "vel": f + 6 + np.arange(3),
        "bg": b + np.arange(3),
        "ba": b + 3 + np.arange(3),
    }
    return table[var]


def _signature(m: Measurement) -> tuple:
    """What must agree for measurements to be stacked: size and the kinds of blocks (a
    landmark block counts as one kind whatever its id)."""
    return (m.dim, tuple(v[0] if isinstance(v, tuple) else v for v in m.H))


class MeasurementGroup:
    """Measurement terms of one kind, evaluated with the filter's functions one by one and
    whitened and scattered all at once (``W = L⁻¹`` of each term's constant ``R``).

    The structure (residual size, blocks, columns, whiteners) is taken from the first
    evaluation and reused; every term of a group must give the same block kinds."""

    def __init__(self, kind: str, terms: list[MeasurementTerm]) -> None:
        self.kind = kind
        self.terms = terms
        self._W: np.ndarray | None = None
        self._cols: np.ndarray | None = None
        self._sig: tuple | None = None

    def _structure(
        self, ms: list[Measurement], x: SmootherVariables, lm_index: dict[int, int]
    ) -> None:
        sig = _signature(ms[0])
        if any(_signature(m) != sig for m in ms):
            raise ValueError(f"{self.kind}: measurements of one kind differ in structure")
        self._sig = sig
        self._W = whitener(np.stack([m.R for m in ms]))
        self._cols = np.stack(
            [
                np.concatenate([_var_columns(v, t, x, lm_index) for v in m.H])
                for t, m in zip(self.terms, ms, strict=True)
            ]
        )

    def evaluate(self, x: SmootherVariables, jacobian: bool) -> TermBlock:
        """``W (z ⊟ h(x))`` for every term and, with ``jacobian``, ``−W H`` (``H`` with the
        ``so3_rows`` correction) as COO triplets."""
        if not self.terms:
            return TermBlock(self.kind, np.zeros(0))
        lm_index = {lm_id: j for j, lm_id in enumerate(x.lm_ids)}
        ms = [t.fn(filter_state_at(x, t, lm_index)) for t in self.terms]
        if self._W is None:
            self._structure(ms, x, lm_index)
        W, cols = self._W, self._cols
        assert W is not None and cols is not None
        n, d = len(ms), ms[0].dim
        r = np.stack([m.residual for m in ms])  # (n, d)
        block = TermBlock(self.kind, (W @ r[..., None])[..., 0].reshape(-1))
        if not jacobian:
            return block
        H = np.stack([np.concatenate(list(m.H.values()), axis=1) for m in ms])  # (n, d, w)
        so3 = self.terms[0].so3_rows
        if so3 is not None:
            a, b = so3
            H[:, a:b, :] = so3_right_jacobian_inv(r[:, a:b]) @ H[:, a:b, :]
        Jw = -(W @ H)
        w = cols.shape[1]
        rows = d * np.arange(n)[:, None] + np.arange(d)  # (n, d)
        block.rows = np.broadcast_to(rows[:, :, None], (n, d, w)).reshape(-1)
        block.cols = np.broadcast_to(cols[:, None, :], (n, d, w)).reshape(-1)
        block.vals = Jw.reshape(-1)
        return block


def group_terms(terms: list[MeasurementTerm]) -> list[MeasurementGroup]:
    """One :class:`MeasurementGroup` per kind (in :data:`KINDS` order, then any other kind;
    VO, tag and foot terms of one kind share their structure)."""
    kinds = list(KINDS[2:]) + sorted({t.kind for t in terms} - set(KINDS))
    return [MeasurementGroup(k, [t for t in terms if t.kind == k]) for k in kinds]
