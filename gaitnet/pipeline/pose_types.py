"""Value types of the pose correction (thesis eq. 4.7, 4.8): pose, measurements, parameters.

A pose is the motion predictor's 21-node vector (docs/predictor.md: node ``3j + c`` is
axis-angle component ``c`` of joint ``j``; ``j = 0`` the root orientation in the world,
``j = 1..6`` the local rotations of L_hip, R_hip, L_knee, R_knee, L_ankle, R_ankle) plus the
SMPL root translation. Measurements are in the world frame (z up): the pelvis pose from the
filter (the camera pose through the camera-to-pelvis extrinsic, :mod:`gaitnet.pipeline.
pelvis_extrinsic`) and one 3-D point per visible foot (the segmenter's keypoint moved to the
world). Every value is checked where it enters; a bad one raises :class:`~gaitnet.errors.
InputError` naming the field.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gaitnet.errors import InputError

FloatArray = NDArray[np.float64]

__all__ = [
    "DEFAULT_ROM_DEG",
    "R_PfromSMPL",
    "FrameMeasurements",
    "PoseCorrectionParams",
    "PoseState",
]

#: SMPL's canonical body axes (x left, y up, z forward) in the pelvis frame (x forward, y left,
#: z up): ``R_WfromP = R_root @ R_PfromSMPL.T`` and ``R_root = R_WfromP @ R_PfromSMPL``.
R_PfromSMPL = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])

#: Range of motion [deg] of the local rotations' axis-angle components (x, y, z) in SMPL's
#: axes (x body-left: +x is hip extension, knee flexion, ankle plantarflexion; y up: internal
#: / external rotation; z forward: ab-/adduction, +z abducts the LEFT leg). Rows: L_hip,
#: R_hip, L_knee, R_knee, L_ankle, R_ankle; textbook ranges (hip flexion 125°, extension 30°,
#: abduction 45°, adduction 30°, rotation 45°; knee 0–150° with 10° of slack at extension;
#: ankle dorsiflexion 30°, plantarflexion 50°, inversion / eversion and ankle rotation 30°).
#: The simulator's stance ankle dorsiflexes up to 40° (docs/pose-correction.md).
DEFAULT_ROM_DEG: tuple[tuple[tuple[float, float], ...], ...] = (
    ((-125.0, 30.0), (-45.0, 45.0), (-30.0, 45.0)),
    ((-125.0, 30.0), (-45.0, 45.0), (-45.0, 30.0)),
    ((-10.0, 150.0), (-30.0, 30.0), (-30.0, 30.0)),
    ((-10.0, 150.0), (-30.0, 30.0), (-30.0, 30.0)),
    ((-30.0, 50.0), (-30.0, 30.0), (-30.0, 30.0)),
    ((-30.0, 50.0), (-30.0, 30.0), (-30.0, 30.0)),
)


def _vector(value: ArrayLike, shape: tuple[int, ...], name: str, *, nan_ok: bool = False):
    try:
        a = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"{name}: expected numbers of shape {shape}") from None
    if a.shape != shape:
        raise InputError(f"{name}: expected shape {shape}, got {a.shape}")
    bad = ~np.isfinite(a) & ~(np.isnan(a) if nan_ok else False)
    if np.any(bad):
        raise InputError(f"{name}: values must be finite")
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class PoseState:
    """One lower-body pose: ``pose`` (21,) in the predictor's node layout, ``trans`` (3,) [m]."""

    pose: FloatArray
    trans: FloatArray

    def __post_init__(self) -> None:
        object.__setattr__(self, "pose", _vector(self.pose, (21,), "pose"))
        object.__setattr__(self, "trans", _vector(self.trans, (3,), "trans"))

    @property
    def root_orient(self) -> FloatArray:
        """Root orientation (3,), axis-angle, world-from-SMPL-body."""
        return self.pose[:3]

    @property
    def joint_aa(self) -> FloatArray:
        """The six local rotations (6, 3) of L_hip, R_hip, L_knee, R_knee, L_ankle, R_ankle."""
        return self.pose[3:].reshape(6, 3)

    def smpl_joint_aa(self) -> FloatArray:
        """The (8, 3) ``joint_aa`` of :func:`gaitnet.motion.forward_kinematics` (feet zero)."""
        return np.concatenate([self.joint_aa, np.zeros((2, 3))])


@dataclass(frozen=True, eq=False)
class FrameMeasurements:
    """What the sensors say about one frame (world frame, z up).

    ``R_WfromP`` (3, 3) and ``p_PinW`` (3,): the pelvis orientation and position (SMPL joint 0;
    pelvis frame x forward, y left, z up), each ``None`` when not measured. ``foot_W`` (2, 3):
    one point on each foot (rows left, right), a row of NaN where that foot is not seen.
    ``contact`` (2,) in [0, 1]: how sure we are that each foot is in stance (1 = flat on the
    floor); it weights the flat-foot term and, when switched on, the contact weighting.
    """

    R_WfromP: FloatArray | None = None
    p_PinW: FloatArray | None = None
    foot_W: FloatArray = field(default_factory=lambda: np.full((2, 3), np.nan))
    contact: FloatArray = field(default_factory=lambda: np.zeros(2))

    def __post_init__(self) -> None:
        if self.R_WfromP is not None:
            R = _vector(self.R_WfromP, (3, 3), "R_WfromP")
            if np.abs(R.T @ R - np.eye(3)).max() > 1e-6 or np.linalg.det(R) < 0:
                raise InputError("R_WfromP: not a rotation matrix")
            object.__setattr__(self, "R_WfromP", R)
        if self.p_PinW is not None:
            object.__setattr__(self, "p_PinW", _vector(self.p_PinW, (3,), "p_PinW"))
        foot = _vector(self.foot_W, (2, 3), "foot_W", nan_ok=True)
        partial = np.isnan(foot).any(axis=1) & ~np.isnan(foot).all(axis=1)
        if np.any(partial):
            raise InputError("foot_W: a foot row must be all numbers or all NaN")
        object.__setattr__(self, "foot_W", foot)
        contact = _vector(self.contact, (2,), "contact")
        if np.any((contact < 0) | (contact > 1)):
            raise InputError("contact: values must lie in [0, 1]")
        object.__setattr__(self, "contact", contact)

    @property
    def visible(self) -> NDArray[np.bool_]:
        """(2,) whether each foot (left, right) has a measured point."""
        return ~np.isnan(self.foot_W[:, 0])


SOLVERS = ("lm", "lbfgs")
"""``solver``: Levenberg–Marquardt (default), or scipy's L-BFGS-B, the thesis's solver."""


@dataclass(frozen=True)
class PoseCorrectionParams:
    """Weights and switches of the correction (docs/pose-correction.md has the objective).

    Each term's weight is ``1 / sigma``: a residual of one sigma costs 1. ``thesis()`` gives
    the thesis's objective (eq. 4.8 with squared terms) with every extension switched off.
    """

    sigma_prior_joint_rad: float = 0.1
    sigma_prior_root_rad: float = 0.1
    sigma_prior_trans_m: float = 0.1
    sigma_root_rot_rad: float = 0.02
    sigma_root_pos_m: float = 0.02
    sigma_foot_m: float = 0.02
    sigma_bone_m: float = 0.01
    fixed_lengths: bool = True
    knee_hinge: bool = True
    sigma_hinge_rad: float = 0.01
    rom_limits: bool = True
    sigma_rom_rad: float = 0.01
    rom_deg: tuple[tuple[tuple[float, float], ...], ...] = DEFAULT_ROM_DEG
    robust_foot: bool = True
    cauchy_scale_m: float = 0.05
    contact_weighting: bool = False
    contact_gain: float = 2.0
    marker_offset: bool = True
    flat_foot_contact: bool = True
    sigma_flat_rad: float = 0.05
    marker_offset_m: tuple[float, float, float] = (0.0, -0.012, 0.078)
    max_iterations: int = 10
    step_tolerance: float = 1e-5
    cost_tolerance: float = 1e-4
    solver: str = "lm"
    lbfgs_max_iterations: int = 25

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name.startswith(("sigma_", "cauchy_")) and not (
                isinstance(value, (int, float)) and np.isfinite(value) and value > 0
            ):
                raise InputError(f"pose correction {f.name}: must be a positive number")
        if not (np.isfinite(self.contact_gain) and self.contact_gain >= 0):
            raise InputError("pose correction contact_gain: must be a number ≥ 0")
        offset = np.asarray(self.marker_offset_m, dtype=np.float64)
        if offset.shape != (3,) or not np.all(np.isfinite(offset)):
            raise InputError("pose correction marker_offset_m: must be three finite numbers")
        rom = np.asarray(self.rom_deg, dtype=np.float64)
        if (
            rom.shape != (6, 3, 2)
            or not np.all(np.isfinite(rom))
            or np.any(rom[..., 0] > rom[..., 1])
        ):
            raise InputError("pose correction rom_deg: must be 6 × 3 (low, high) pairs, low ≤ high")
        if not (isinstance(self.max_iterations, int) and 1 <= self.max_iterations <= 1000):
            raise InputError("pose correction max_iterations: must be an integer in 1..1000")
        if self.solver not in SOLVERS:
            raise InputError(
                f"pose correction solver: must be one of {SOLVERS}, got {self.solver!r}"
            )
        if not (
            isinstance(self.lbfgs_max_iterations, int) and 1 <= self.lbfgs_max_iterations <= 10000
        ):
            raise InputError("pose correction lbfgs_max_iterations: must be an integer in 1..10000")
        for name in ("step_tolerance", "cost_tolerance"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and np.isfinite(value) and value > 0):
                raise InputError(f"pose correction {name}: must be a positive number")

    @classmethod
    def thesis(cls, **overrides: object) -> PoseCorrectionParams:
        """Eq. 4.8 only: prior, root, feet and free bone lengths; every extension off."""
        base: dict[str, object] = dict(
            fixed_lengths=False,
            knee_hinge=False,
            rom_limits=False,
            robust_foot=False,
            contact_weighting=False,
            marker_offset=False,
            flat_foot_contact=False,
        )
        base.update(overrides)
        return cls(**base)  # type: ignore[arg-type]
