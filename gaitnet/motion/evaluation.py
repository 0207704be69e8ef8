"""Per-horizon evaluation of motion predictors and the two classic baselines (thesis sec. 4.2).

Protocol. Each test window holds ``n_past`` observed and ``n_future`` true future poses in the
21-node layout of :mod:`gaitnet.motion.gcn` (heading-normalised as in training, see
:class:`gaitnet.motion.windows.WalkingWindows`). A predictor maps the observed poses
(B, n_past, 21) to future poses (B, n_future, 21). For every horizon ``k = 1 .. n_future``
(``k / fps`` s: 33 … 333 ms at 30 fps) we report

* MPJPE (eq. 4.5, :func:`gaitnet.evaluation.metrics.mpjpe_per_horizon`) [m]: mean over
  windows and the 7 lower-body joints (pelvis, hips, knees, ankles) of ``‖p̂ − p‖₂`` with joint
  positions from forward kinematics (:func:`gaitnet.motion.gcn.joint_positions`) on ONE
  evaluation skeleton for all clips. The root TRANSLATION is not predicted, so predicted and
  true poses are both placed with the true translation; as it is the same for both, this
  equals zeroing it, and it is the same for every method. Consequently the pelvis joint's
  error is always zero (it is still counted among the 7 joints, as in the thesis's loss;
  multiply by 7/6 for the mean over the six moving joints); the root ORIENTATION error moves
  the hips and everything below.
* angle MAE (eq. 4.6, :func:`gaitnet.evaluation.metrics.angle_errors`) [rad]: mean over
  windows and the 7 rotation nodes (root orientation + 6 joints) of the L1 norm of the
  axis-angle difference, as the training loss.

Baselines (no learning):

* zero-velocity: every future pose is the last observed pose;
* constant-velocity: per rotation node, the last step's rotation increment is repeated ON SO(3):
  ``R_{T+k} = R_T (R_{T−1}ᵀ R_T)^k = R_T exp(k log(R_{T−1}ᵀ R_T))`` (body-frame constant angular
  velocity), never a linear extrapolation of axis-angle vectors (which is not a rotation at a
  constant rate and breaks near the ±π wrap).

A predictor is any callable ``(B, n_past, 21) → (B, n_future, 21)``; :func:`torch_predictor`
wraps a :class:`gaitnet.motion.gcn.DCTGCN`, :func:`onnx_predictor` an
:class:`gaitnet.motion.onnx_runtime.OnnxPredictor`, so the same numbers come out of a torch
checkpoint and its exported ONNX file.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from gaitnet.errors import InputError
from gaitnet.evaluation.metrics import angle_errors, mpjpe_per_horizon, per_horizon
from gaitnet.geometry import so3_exp, so3_log
from gaitnet.motion.gcn import joint_positions
from gaitnet.motion.skeleton import LowerBodySkeleton

if TYPE_CHECKING:
    import torch

    from gaitnet.motion.onnx_runtime import OnnxPredictor

__all__ = [
    "HorizonMetrics",
    "Predictor",
    "PredictorComparison",
    "constant_velocity",
    "evaluate_predictors",
    "horizon_errors",
    "onnx_predictor",
    "torch_predictor",
    "zero_velocity",
]

Predictor = Callable[[np.ndarray], np.ndarray]


# --------------------------------------------------------------------------- baselines


def zero_velocity(past: np.ndarray, n_future: int) -> np.ndarray:
    """Repeat the last observed pose: (B, n_past, N) → (B, n_future, N)."""
    past = np.asarray(past)
    return np.repeat(past[:, -1:], int(n_future), axis=1)


def constant_velocity(past: np.ndarray, n_future: int) -> np.ndarray:
    """Constant angular velocity per node on SO(3): ``R_{T+k} = R_T (R_{T−1}ᵀ R_T)^k``.

    ``past`` (B, n_past ≥ 2, 3·J) axis-angle vectors (any number of 3-component nodes);
    returns (B, n_future, 3·J) axis-angle vectors (angles in [0, π]).
    """
    past = np.asarray(past, dtype=np.float64)
    if past.ndim != 3 or past.shape[1] < 2 or past.shape[2] % 3 != 0:
        raise ValueError(f"constant_velocity needs (B, n_past >= 2, 3·J) poses, got {past.shape}")
    B, _, N = past.shape
    R_last = so3_exp(past[:, -1].reshape(B, N // 3, 3))  # (B, J, 3, 3)
    R_prev = so3_exp(past[:, -2].reshape(B, N // 3, 3))
    delta = so3_log(np.swapaxes(R_prev, -1, -2) @ R_last)  # (B, J, 3): log(R_prevᵀ R_last)
    k = np.arange(1, int(n_future) + 1, dtype=np.float64)[None, :, None, None]
    R_future = R_last[:, None] @ so3_exp(k * delta[:, None])  # (B, K, J, 3, 3)
    return so3_log(R_future).reshape(B, int(n_future), N)


# --------------------------------------------------------------------------- learnt predictors


def torch_predictor(
    model: torch.nn.Module, *, device: str | torch.device = "cpu", batch_size: int = 1024
) -> Predictor:
    """Wrap a :class:`~gaitnet.motion.gcn.DCTGCN` (or DDP-free module with ``predict_future``).

    The model is put in eval mode; inputs run in float32 batches of ``batch_size`` without
    gradients; outputs come back as float64 numpy arrays.
    """
    import torch

    def predict(past: np.ndarray) -> np.ndarray:
        model.eval()
        out = []
        with torch.no_grad():
            for i in range(0, past.shape[0], batch_size):
                x = torch.as_tensor(past[i : i + batch_size], dtype=torch.float32, device=device)
                out.append(model.predict_future(x).cpu().numpy().astype(np.float64))
        return np.concatenate(out, axis=0)

    return predict


def onnx_predictor(model: OnnxPredictor, *, batch_size: int = 1024) -> Predictor:
    """Wrap an :class:`~gaitnet.motion.onnx_runtime.OnnxPredictor` (onnxruntime, CPU)."""

    def predict(past: np.ndarray) -> np.ndarray:
        out = [
            model.predict_future(past[i : i + batch_size]).astype(np.float64)
            for i in range(0, past.shape[0], batch_size)
        ]
        return np.concatenate(out, axis=0)

    return predict


# --------------------------------------------------------------------------- metrics


def horizon_errors(
    pred: np.ndarray, truth: np.ndarray, skeleton: LowerBodySkeleton
) -> tuple[np.ndarray, np.ndarray]:
    """Sums over windows of MPJPE [m] and angle MAE [rad] per horizon: two (K,) arrays.

    ``pred`` and ``truth`` are (B, K, 21). Sums (not means) so batches can be accumulated;
    divide by the number of windows.
    """
    pred = np.asarray(pred, dtype=np.float64)
    truth = np.asarray(truth, dtype=np.float64)
    if pred.shape != truth.shape or pred.ndim != 3:
        raise ValueError(f"need equal (B, K, 21) arrays, got {pred.shape} and {truth.shape}")
    p_pred, p_true = joint_positions(pred, skeleton), joint_positions(truth, skeleton)
    mpjpe = mpjpe_per_horizon(p_pred, p_true, reduction="sum")
    mae = per_horizon(angle_errors(pred, truth), reduction="sum")
    return mpjpe, mae


@dataclass(frozen=True)
class HorizonMetrics:
    """One method's errors per horizon ``k = 1 .. K`` (index ``k − 1``)."""

    name: str
    mpjpe_m: np.ndarray  # (K,)
    mae_rad: np.ndarray  # (K,)
    n_windows: int

    @property
    def mean_mpjpe_m(self) -> float:
        """Mean over horizons (the model-selection number)."""
        return float(np.mean(self.mpjpe_m))

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-able data."""
        return {
            "mpjpe_m": [float(v) for v in self.mpjpe_m],
            "mae_rad": [float(v) for v in self.mae_rad],
            "mean_mpjpe_m": self.mean_mpjpe_m,
            "mean_mae_rad": float(np.mean(self.mae_rad)),
            "n_windows": int(self.n_windows),
        }


@dataclass(frozen=True)
class PredictorComparison:
    """Per-horizon errors of every method (learnt predictors and baselines) on one split.

    ``horizons_ms[k − 1] = 1000 k / fps``; :meth:`to_dict` is what ``eval.json`` holds.
    """

    split: str
    fps: float
    n_past: int
    n_future: int
    n_windows: int
    methods: dict[str, HorizonMetrics]
    notes: dict[str, str]

    @property
    def horizons_ms(self) -> list[float]:
        return [1000.0 * k / self.fps for k in range(1, self.n_future + 1)]

    def improvement_over(self, method: str, baseline: str) -> np.ndarray:
        """Relative MPJPE reduction of ``method`` vs ``baseline`` per horizon (0.3 = 30 %)."""
        a, b = self.methods[method].mpjpe_m, self.methods[baseline].mpjpe_m
        return 1.0 - a / b

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-able data (what ``eval.json`` holds)."""
        out: dict[str, Any] = {
            "split": self.split,
            "fps": self.fps,
            "n_past": self.n_past,
            "n_future": self.n_future,
            "n_windows": self.n_windows,
            "horizons_ms": [round(h, 3) for h in self.horizons_ms],
            "methods": {k: v.to_dict() for k, v in self.methods.items()},
            "notes": dict(self.notes),
        }
        learnt = [m for m in self.methods if m not in ("zero_velocity", "constant_velocity")]
        improvements: dict[str, dict[str, list[float]]] = {}
        for m in learnt:
            improvements[m] = {
                b: [float(v) for v in self.improvement_over(m, b)]
                for b in ("zero_velocity", "constant_velocity")
                if b in self.methods
            }
        out["mpjpe_reduction_vs_baselines"] = improvements
        return out


def evaluate_predictors(
    windows: np.ndarray,
    predictors: Mapping[str, Predictor],
    skeleton: LowerBodySkeleton,
    *,
    n_past: int,
    fps: float,
    split: str = "test",
    batch_size: int = 2048,
    baselines: bool = True,
) -> PredictorComparison:
    """Errors per horizon of each predictor (and both baselines) on ``windows`` (N, W, 21).

    ``W = n_past + n_future``. With ``baselines`` the report also holds ``zero_velocity`` and
    ``constant_velocity``. Windows must be finite; a prediction of the wrong shape or with a
    NaN/inf raises :class:`~gaitnet.errors.InputError` naming the predictor (a NaN must never
    reach a report).
    """
    windows = np.asarray(windows, dtype=np.float64)
    if windows.ndim != 3 or windows.shape[1] <= n_past or windows.shape[0] == 0:
        raise InputError(f"need (N > 0, n_past + n_future, 21) windows, got {windows.shape}")
    if not np.all(np.isfinite(windows)):
        raise InputError("evaluation windows contain NaN or inf")
    n_future = windows.shape[1] - n_past
    methods: dict[str, Predictor] = dict(predictors)
    if baselines:
        methods["zero_velocity"] = lambda p: zero_velocity(p, n_future)
        methods["constant_velocity"] = lambda p: constant_velocity(p, n_future)
    results: dict[str, HorizonMetrics] = {}
    N = windows.shape[0]
    for name, predict in methods.items():
        mpjpe = np.zeros(n_future)
        mae = np.zeros(n_future)
        for i in range(0, N, batch_size):
            batch = windows[i : i + batch_size]
            pred = np.asarray(predict(batch[:, :n_past]), dtype=np.float64)
            if pred.shape != batch[:, n_past:].shape:
                raise InputError(
                    f"predictor {name!r} returned {pred.shape}, expected {batch[:, n_past:].shape}"
                )
            if not np.all(np.isfinite(pred)):
                raise InputError(f"predictor {name!r} returned NaN or inf")
            s_pos, s_ang = horizon_errors(pred, batch[:, n_past:], skeleton)
            mpjpe += s_pos
            mae += s_ang
        results[name] = HorizonMetrics(name, mpjpe / N, mae / N, N)
    notes = {
        "mpjpe": "mean over the 7 joints SMPL 0,1,2,4,5,7,8 (pelvis error is 0: translation "
        "is not predicted; predicted and true poses share the true translation)",
        "mae": "eq. 4.6: L1 norm of the axis-angle difference, mean over 7 rotation nodes",
        "skeleton": "one evaluation skeleton for every clip, rest joints below",
        "skeleton_rest_joints": repr(np.round(skeleton.rest_joints, 4).tolist()),
        "constant_velocity": "R_{T+k} = R_T (R_{T-1}^T R_T)^k per rotation node",
    }
    return PredictorComparison(
        split=split,
        fps=float(fps),
        n_past=int(n_past),
        n_future=int(n_future),
        n_windows=int(N),
        methods=results,
        notes=notes,
    )
