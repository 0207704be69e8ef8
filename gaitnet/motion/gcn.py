"""DCT-GCN lower-body motion predictor (thesis sec. 4.2, Fig. 4.8).

Paper: W. Mao, M. Liu, M. Salzmann, H. Li, "Learning Trajectory Dependencies for Human Motion
Prediction", ICCV 2019 (LTD), https://github.com/wei-mao-2019/LearnTrajDep. Layer names follow
the reference code (``gc1``, ``bn1``, ``gcbs``, ``gc7``, ``do``, ``act_f``; ``att`` is the
learnable adjacency).

Nodes. The thesis predicts a 7-joint lower body from joint angles: ``n_nodes = 21 = 7 × 3``
axis-angle components (thesis sec. 4.2.4: ``x̄_i ∈ R^21``). Node ``3j + c`` holds component
``c`` of the rotation of :data:`NODE_JOINTS` ``[j]``:

* nodes 0–2: the ROOT ORIENTATION (SMPL joint 0, pelvis, world-from-pelvis, in the
  heading-normalised world of :mod:`gaitnet.motion.heading`), so the root node carries the
  orientation of the body, not a local joint rotation;
* nodes 3–20: the local rotations (relative to the parent, SMPL convention) of L_hip 1,
  R_hip 2, L_knee 4, R_knee 5, L_ankle 7, R_ankle 8.

The root TRANSLATION is not predicted: the net sees and returns rotations only. Joint positions
for the MPJPE loss (4.5) come from forward kinematics with the translation held fixed (see
:mod:`gaitnet.motion.losses`); in the pipeline the translation comes from the VIO body track.
The foot joints' own rotations (SMPL 10, 11) move no modelled joint and are not nodes.

Temporal encoding (thesis eq. 4.2, 4.3; LTD sec. 3.1). The ``n_past`` observed poses are padded
to ``n_past + n_future`` frames by repeating the last observed pose, each node's padded
trajectory is encoded by its first ``dct_n`` DCT coefficients, the GCN maps these to the DCT
coefficients of the whole sequence through a global residual (output = input coefficients +
net(input coefficients)), and the inverse DCT gives back ``n_past + n_future`` poses. With
``dct_n = n_past + n_future`` (the thesis: depth 20 for 10 + 10) the basis is complete and no
temporal smoothing happens; LTD used 15 for this setting. Both are supported.

Padding with damped velocity (``pad_velocity_decay = γ > 0``). Instead of repeating the last
observed pose ``c``, future frame ``k`` of the padded input is ``c + v Σ_{i=1..k} γ^i`` with
``v`` the last observed step (``x_T − x_{T−1}`` per node): the network then corrects a damped
constant-velocity guess rather than a standing one, so on motion unlike its training data it
still continues what it sees for the first frames (``γ = 0.8``: the guess moves on by about
3.6 steps in all and comes to rest within about 300 ms; constant velocity itself overshoots).
A still input has ``v = 0``, so the guarantee below is kept.

Still-input guarantee (``residual = "last_pose"``, the committed model's setting). LTD's
global residual alone does not keep a still input still: the network adds
``gc7(blocks(gc1(x)))``, which is not zero for the coefficients of a constant sequence, so a
standing subject gets invented motion. With ``residual = "last_pose"`` the model works on the
displacement from the LAST OBSERVED pose ``c``: ``x' = past − c`` (padded with zeros, its last
observed row is zero), and the graph network sees ``[DCT(x'), c]`` per node (``dct_n + 1``
features, so the absolute pose still informs the prediction) and returns DCT coefficients of
the displacement:

    out = c + IDCT( DCT(x') + h(DCT(x'), c) − h(0, c) ).

For a constant input ``x' = 0`` and both ``h`` terms are the same computation, so the output
is ``c`` in every frame (exactly, up to float32 rounding in the batched matrix products); for
a nearly still input the prediction moves no more than the net's Lipschitz constant times
the input's motion. Both ``h`` terms run in one batch of ``2B`` rows (batch norm in training
sees both). ``residual = "ltd"`` is LTD's original structure (older checkpoints).

Graph convolution (thesis eq. 4.4): ``H⁽ᵖ⁺¹⁾ = σ(A⁽ᵖ⁾ H⁽ᵖ⁾ W⁽ᵖ⁾)`` on a fully connected graph
whose dense adjacency ``A⁽ᵖ⁾`` (``att``) is learnt per layer.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch
from torch import nn

from gaitnet.checks import check_int_range, check_range
from gaitnet.motion.dct import dct_matrix_torch, idct_matrix_torch
from gaitnet.motion.skeleton import (
    JOINT_NAMES,
    N_ROTATED,
    LowerBodySkeleton,
    forward_kinematics,
    forward_kinematics_torch,
)

__all__ = [
    "DCTGCN",
    "GCBlock",
    "GraphConvolution",
    "NODE_JOINTS",
    "NODE_JOINT_NAMES",
    "N_EVAL_JOINTS",
    "PredictorConfig",
    "RESIDUALS",
    "joint_positions",
    "pose_features",
    "split_pose_features",
]

#: Joints of the MPJPE (loss and evaluation): SMPL 0, 1, 2, 4, 5, 7, 8, the first 7 of the
#: skeleton (pelvis, hips, knees, ankles), as the thesis.
N_EVAL_JOINTS = 7
#: SMPL joint whose rotation nodes ``3j .. 3j+2`` hold (joint 0: the root orientation).
NODE_JOINTS: tuple[int, ...] = (0, 1, 2, 4, 5, 7, 8)
NODE_JOINT_NAMES: tuple[str, ...] = JOINT_NAMES[: len(NODE_JOINTS)]
#: Residual structures of :class:`DCTGCN` (:attr:`PredictorConfig.residual`).
RESIDUALS: tuple[str, ...] = ("ltd", "last_pose")


@dataclass(frozen=True)
class PredictorConfig:
    """Architecture of :class:`DCTGCN`; the defaults are the thesis's (sec. 4.2, 5.x).

    ``n_past`` observed frames → ``n_future`` predicted frames (10 → 10 at 30 fps), ``dct_n``
    DCT coefficients kept per node (20: full basis; LTD: 15), ``n_nodes`` = 7 joints × 3
    axis-angle components (root orientation first, see the module docstring), ``hidden``
    features per node, ``n_blocks`` residual blocks, dropout probability ``dropout``.
    """

    n_past: int = 10
    n_future: int = 10
    dct_n: int = 20
    n_nodes: int = 21
    hidden: int = 256
    n_blocks: int = 12
    dropout: float = 0.5
    #: ``"ltd"`` (LTD's global residual) or ``"last_pose"`` (a still input stays still exactly;
    #: module docstring)
    residual: str = "ltd"
    #: Padding of the future frames: 0 repeats the last observed pose (LTD); ``γ`` in (0, 1]
    #: continues the last step's motion, damped by ``γ`` per frame (module docstring)
    pad_velocity_decay: float = 0.0

    #: Largest accepted value of each integer key (far above any useful size; guards against
    #: typos that would ask for terabytes).
    LIMITS = {"n_past": 1000, "n_future": 1000, "dct_n": 2000, "n_nodes": 1000, "hidden": 8192}

    def __post_init__(self) -> None:
        for name, limit in self.LIMITS.items():
            check_int_range(f"PredictorConfig.{name}", getattr(self, name), 1, limit)
        check_int_range("PredictorConfig.n_blocks", self.n_blocks, 0, 256)
        if self.dct_n > self.seq_len:
            raise ValueError(
                f"PredictorConfig.dct_n = {self.dct_n} exceeds n_past + n_future = {self.seq_len}"
            )
        dropout = check_range("PredictorConfig.dropout", self.dropout, 0.0, 1.0)
        if dropout == 1.0:
            raise ValueError("PredictorConfig.dropout must be below 1 (1 drops every feature)")
        check_range("PredictorConfig.pad_velocity_decay", self.pad_velocity_decay, 0.0, 1.0)
        if self.residual not in RESIDUALS:
            raise ValueError(
                f"PredictorConfig.residual must be one of {list(RESIDUALS)}, got {self.residual!r}"
            )

    @property
    def seq_len(self) -> int:
        """``n_past + n_future``: frames of the padded input and of the output sequence."""
        return self.n_past + self.n_future


class GraphConvolution(nn.Module):
    """One graph convolution ``A H W + b`` (thesis eq. 4.4 before σ; LTD ``GraphConvolution``).

    ``H`` (B, nodes, in) → (B, nodes, out). ``att`` (nodes, nodes) is the learnable dense
    adjacency ``A``, ``weight`` (in, out) is ``W``. Initialised uniform(±1/sqrt(out)) as LTD.
    """

    def __init__(self, in_features: int, out_features: int, n_nodes: int, bias: bool = True):
        super().__init__()
        self.in_features = in_features
        self.out_features = out_features
        self.weight = nn.Parameter(torch.empty(in_features, out_features))
        self.att = nn.Parameter(torch.empty(n_nodes, n_nodes))
        self.bias = nn.Parameter(torch.empty(out_features)) if bias else None
        self.reset_parameters()

    def reset_parameters(self) -> None:
        """LTD's initialisation: every parameter uniform in ``±1/sqrt(out_features)``."""
        stdv = 1.0 / math.sqrt(self.out_features)
        nn.init.uniform_(self.weight, -stdv, stdv)
        nn.init.uniform_(self.att, -stdv, stdv)
        if self.bias is not None:
            nn.init.uniform_(self.bias, -stdv, stdv)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        support = torch.matmul(x, self.weight)
        out = torch.matmul(self.att, support)
        if self.bias is not None:
            out = out + self.bias
        return out


class GCBlock(nn.Module):
    """Residual block (LTD ``GC_Block``): 2 × [graph conv → BatchNorm → tanh → dropout] + x.

    Batch norm runs over the flattened ``nodes × features`` vector, as in LTD.
    """

    def __init__(self, features: int, dropout: float, n_nodes: int, bias: bool = True):
        super().__init__()
        self.gc1 = GraphConvolution(features, features, n_nodes, bias=bias)
        self.bn1 = nn.BatchNorm1d(n_nodes * features)
        self.gc2 = GraphConvolution(features, features, n_nodes, bias=bias)
        self.bn2 = nn.BatchNorm1d(n_nodes * features)
        self.do = nn.Dropout(dropout)
        self.act_f = nn.Tanh()

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        b, n, f = x.shape
        y = self.gc1(x)
        y = self.bn1(y.reshape(b, n * f)).reshape(b, n, f)
        y = self.do(self.act_f(y))
        y = self.gc2(y)
        y = self.bn2(y.reshape(b, n * f)).reshape(b, n, f)
        y = self.do(self.act_f(y))
        return y + x


class DCTGCN(nn.Module):
    """LTD's GCN on DCT coefficients of the padded pose sequence (thesis Fig. 4.8).

    ``forward(past)``: ``past`` (B, n_past, n_nodes) → the whole sequence (B, n_past + n_future,
    n_nodes), i.e. the reconstructed past followed by the prediction; :meth:`predict_future`
    returns only the last ``n_future`` frames. The padding indices and the (truncated) DCT and
    inverse-DCT matrices are non-persistent buffers derived from the config, so they follow
    ``.to()`` and are exported to ONNX as constants.
    """

    def __init__(self, config: PredictorConfig | None = None):
        super().__init__()
        config = PredictorConfig() if config is None else config
        self.config = config
        n, L = config.seq_len, config.dct_n
        pad_idx = list(range(config.n_past)) + [config.n_past - 1] * config.n_future
        self.register_buffer("pad_idx", torch.tensor(pad_idx, dtype=torch.long), persistent=False)
        g = float(config.pad_velocity_decay)
        steps = [0.0] * config.n_past + [sum(g**i for i in range(1, k + 1)) for k in
                                         range(1, config.n_future + 1)]  # fmt: skip
        self.register_buffer(
            "pad_steps", torch.tensor(steps, dtype=torch.float32)[:, None], persistent=False
        )
        # (4.2) keeps the first L coefficients: C = D[:L] x; (4.3) x = Dᵀ[:, :L] C.
        self.register_buffer("dct_m", dct_matrix_torch(n)[:L].contiguous(), persistent=False)
        self.register_buffer("idct_m", idct_matrix_torch(n)[:, :L].contiguous(), persistent=False)

        self.last_pose = config.residual == "last_pose"
        # last_pose: each node also sees its value in the last observed pose (one feature more)
        self.gc1 = GraphConvolution(L + int(self.last_pose), config.hidden, config.n_nodes)
        self.bn1 = nn.BatchNorm1d(config.n_nodes * config.hidden)
        self.gcbs = nn.ModuleList(
            GCBlock(config.hidden, config.dropout, config.n_nodes) for _ in range(config.n_blocks)
        )
        self.gc7 = GraphConvolution(config.hidden, L, config.n_nodes)
        self.do = nn.Dropout(config.dropout)
        self.act_f = nn.Tanh()

    def pad(self, past: torch.Tensor) -> torch.Tensor:
        """The padded sequence (B, n_past + n_future, N): the observed poses, then the last
        observed pose plus the damped last step with ``pad_velocity_decay`` (the guess the
        network corrects; zero velocity with γ = 0)."""
        padded = past[:, self.pad_idx]  # (B, T, N)
        if self.config.pad_velocity_decay > 0 and past.shape[1] >= 2:
            padded = padded + self.pad_steps * (past[:, -1:] - past[:, -2:-1])
        return padded

    def encode(self, past: torch.Tensor) -> torch.Tensor:
        """Pad (:meth:`pad`), then DCT: (B, n_past, N) → (B, N, dct_n)."""
        return torch.matmul(self.dct_m, self.pad(past)).transpose(1, 2)

    def decode(self, coeffs: torch.Tensor) -> torch.Tensor:
        """Inverse DCT (4.3) of (B, N, dct_n) coefficients → (B, n_past + n_future, N)."""
        return torch.matmul(self.idct_m, coeffs.transpose(1, 2))

    def net(self, x: torch.Tensor) -> torch.Tensor:
        """The graph network without residual: ``gc7(blocks(gc1(x)))``."""
        b, n, _ = x.shape
        y = self.gc1(x)
        y = self.bn1(y.reshape(b, n * self.config.hidden)).reshape(b, n, self.config.hidden)
        y = self.do(self.act_f(y))
        for block in self.gcbs:
            y = block(y)
        return self.gc7(y)

    def gcn(self, x: torch.Tensor) -> torch.Tensor:
        """LTD's graph network with its global residual: ``x + gc7(blocks(gc1(x)))``."""
        return x + self.net(x)

    def forward(self, past: torch.Tensor) -> torch.Tensor:
        cfg = self.config
        if past.dim() != 3 or past.shape[1] != cfg.n_past or past.shape[2] != cfg.n_nodes:
            raise ValueError(
                f"DCTGCN expects past poses of shape (batch, {cfg.n_past}, {cfg.n_nodes}), "
                f"got {tuple(past.shape)}"
            )
        if not self.last_pose:
            return self.decode(self.gcn(self.encode(past)))
        last = past[:, -1:]  # (B, 1, N): the last observed pose c
        coeffs = self.encode(past - last)  # DCT of the displacement x' (B, N, L)
        c = last.transpose(1, 2)  # (B, N, 1)
        feats = torch.cat(
            [torch.cat([coeffs, c], dim=2), torch.cat([torch.zeros_like(coeffs), c], dim=2)]
        )
        h = self.net(feats)
        b = past.shape[0]
        return self.decode(coeffs + h[:b] - h[b:]) + last

    def predict_future(self, past: torch.Tensor) -> torch.Tensor:
        """Only the predicted frames: (B, n_past, N) → (B, n_future, N)."""
        return self.forward(past)[:, self.config.n_past :]


def pose_features(root_orient: np.ndarray, joint_aa: np.ndarray) -> np.ndarray:
    """Node vector (..., 21) from ``root_orient`` (..., 3) and lower-body ``joint_aa``.

    ``joint_aa`` holds local axis-angle rotations of SMPL joints ``[1, 2, 4, 5, 7, 8]`` (..., 6,
    3) or ``[1, 2, 4, 5, 7, 8, 10, 11]`` (..., 8, 3); the foot rotations are dropped.
    """
    root_orient = np.asarray(root_orient)
    joint_aa = np.asarray(joint_aa)
    if root_orient.shape[-1:] != (3,) or joint_aa.shape[-2:] not in ((6, 3), (8, 3)):
        raise ValueError(
            "pose_features needs root_orient (..., 3) and joint_aa (..., 6 or 8, 3), got "
            f"{root_orient.shape} and {joint_aa.shape}"
        )
    body = joint_aa[..., :6, :].reshape(*joint_aa.shape[:-2], 18)
    return np.concatenate([root_orient, body], axis=-1)


def split_pose_features(
    features: np.ndarray | torch.Tensor,
) -> tuple[np.ndarray | torch.Tensor, np.ndarray | torch.Tensor]:
    """Inverse of :func:`pose_features`: (..., 21) → root orientation (..., 3), joints (..., 6, 3).

    Works on numpy arrays and torch tensors alike (slicing and reshaping only).
    """
    if features.shape[-1] != 3 * len(NODE_JOINTS):
        raise ValueError(f"pose features need a last axis of 21, got shape {tuple(features.shape)}")
    root = features[..., :3]
    joints = features[..., 3:].reshape(*features.shape[:-1], len(NODE_JOINTS) - 1, 3)
    return root, joints


def joint_positions(
    features: np.ndarray | torch.Tensor,
    skeleton: LowerBodySkeleton | torch.Tensor,
    trans: np.ndarray | torch.Tensor | None = None,
    *,
    n_joints: int = N_EVAL_JOINTS,
) -> np.ndarray | torch.Tensor:
    """Forward kinematics of 21-node pose vectors (..., 21) → joints (..., n_joints, 3) [m].

    numpy in, float64 numpy out (:func:`~gaitnet.motion.skeleton.forward_kinematics`); torch
    in, differentiable torch out (:func:`~gaitnet.motion.skeleton.forward_kinematics_torch`).
    The foot joints' own rotations are set to zero (they move none of the 9 skeleton joints).
    ``trans`` (..., 3) defaults to zero (the predictor does not predict the translation).
    """
    root, body = split_pose_features(features)
    if isinstance(features, torch.Tensor):
        feet = body.new_zeros(*body.shape[:-2], N_ROTATED - body.shape[-2], 3)
        joint_aa = torch.cat([body, feet], dim=-2)
        if trans is None:
            trans = features.new_zeros(*features.shape[:-1], 3)
        return forward_kinematics_torch(skeleton, root, trans, joint_aa)[..., :n_joints, :]
    root, body = np.asarray(root, np.float64), np.asarray(body, np.float64)
    feet = np.zeros((*body.shape[:-2], N_ROTATED - body.shape[-2], 3))
    joint_aa = np.concatenate([body, feet], axis=-2)
    if trans is None:
        trans = np.zeros((*root.shape[:-1], 3))
    return forward_kinematics(skeleton, root, trans, joint_aa)[..., :n_joints, :]
