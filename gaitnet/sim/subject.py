"""The simulated subject: body proportions, shoes, trouser-leg shapes and clothes colours.

Segment lengths follow Winter's anthropometric ratios (docs/references.md, *Sensors*:
thigh ≈ 0.245 H, shank ≈ 0.246 H, foot ≈ 0.152 H; ankle height ≈ 0.039 H from the same tables)
with a small per-subject random variation. The subject's :meth:`Subject.skeleton` is built
from exactly these lengths, so the simulator's legs and the forward kinematics agree to
rounding.

Shoe frame (as in :mod:`gaitnet.sim.scene`): origin at the centre of the sole on the sole's
plane, x towards the toe, y to the foot's left, z up. Points of the foot in that frame are
given by :meth:`Subject.ankle_in_shoe` (the ankle joint, above the sole near the heel) and
:meth:`Subject.marker_in_shoe` (a reflective marker on top of the shoe, on the instep).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from gaitnet.motion.skeleton import LowerBodySkeleton, builtin_skeleton
from gaitnet.sim.gait_style import GaitStyle, sample_gait_style
from gaitnet.sim.scene import Appearance

__all__ = ["HEIGHT_RANGE_M", "Subject", "sample_subject"]

HEIGHT_RANGE_M: tuple[float, float] = (1.55, 1.90)
RGB = tuple[float, float, float]

# Winter's ratios (segment length / body height) and our shape defaults.
_THIGH, _SHANK, _FOOT, _ANKLE = 0.245, 0.246, 0.152, 0.039
_HIP_WIDTH, _PELVIS_UP, _PELVIS_BACK = 0.10, 0.05, 0.006
_FOOT_WIDTH = 0.055
_HEEL_TO_ANKLE, _HEEL_TO_BALL = 0.21, 0.72  # fractions of the (barefoot) foot length
_SHOE_HEEL_COUNTER_M = 0.015  # back of the shoe to the back of the heel

# Clothes palettes in sRGB (converted to linear RGB when sampled).
_TROUSERS_SRGB: tuple[RGB, ...] = (
    (0.22, 0.30, 0.48),  # denim
    (0.12, 0.16, 0.30),  # dark denim / navy
    (0.08, 0.08, 0.09),  # black
    (0.25, 0.25, 0.27),  # charcoal
    (0.50, 0.50, 0.52),  # grey
    (0.64, 0.57, 0.42),  # khaki
    (0.36, 0.38, 0.22),  # olive
    (0.40, 0.27, 0.18),  # brown
    (0.78, 0.74, 0.66),  # beige
)
_SHOES_SRGB: tuple[RGB, ...] = (
    (0.92, 0.92, 0.90),  # white
    (0.07, 0.07, 0.08),  # black
    (0.45, 0.45, 0.47),  # grey
    (0.14, 0.17, 0.35),  # navy
    (0.70, 0.12, 0.12),  # red
    (0.45, 0.30, 0.18),  # brown leather
    (0.80, 0.72, 0.58),  # tan
    (0.25, 0.55, 0.75),  # light blue
)
_SOLES_SRGB: tuple[RGB, ...] = (
    (0.93, 0.93, 0.91),  # white
    (0.10, 0.10, 0.10),  # black
    (0.55, 0.55, 0.55),  # grey
    (0.62, 0.45, 0.28),  # gum
)


@dataclass(frozen=True)
class Subject:
    """One simulated person (lengths in metres, colours linear RGB in [0, 1])."""

    height_m: float
    thigh_m: float
    shank_m: float
    hip_width_m: float  # distance between the hip joint centres
    pelvis_above_hip_m: float  # SMPL pelvis joint above the hip joints
    pelvis_behind_hip_m: float  # ... and behind them
    ankle_height_m: float  # barefoot ankle joint above the floor
    foot_length_m: float
    foot_joint_height_m: float  # SMPL foot joint (ball of the foot) above the barefoot sole
    shoe_length_m: float
    shoe_width_m: float
    shoe_height_m: float  # top of the shoe above the floor (instep)
    sole_thickness_m: float
    thigh_radius_top_m: float
    thigh_radius_bottom_m: float
    shank_radius_top_m: float
    shank_radius_bottom_m: float
    trouser_rgb: RGB
    shoe_rgb: RGB
    sole_rgb: RGB
    gait_style: GaitStyle = field(default_factory=GaitStyle)  # how this person walks

    def __post_init__(self) -> None:
        lengths = (self.thigh_m, self.shank_m, self.hip_width_m, self.ankle_height_m)
        if min(lengths) <= 0 or not 1.0 <= self.height_m <= 2.3:
            raise ValueError("Subject needs a plausible height and positive segment lengths")
        if self.shoe_length_m <= self.foot_length_m:
            raise ValueError("the shoe must be longer than the foot")
        if self.shoe_height_m <= self.sole_thickness_m:
            raise ValueError("shoe_height_m must exceed sole_thickness_m")

    @property
    def leg_length_m(self) -> float:
        """Thigh + shank (hip joint to ankle joint, straight leg)."""
        return self.thigh_m + self.shank_m

    @property
    def heel_to_ankle_m(self) -> float:
        """Horizontal distance from the back of the shoe to the ankle joint."""
        return _SHOE_HEEL_COUNTER_M + _HEEL_TO_ANKLE * self.foot_length_m

    @property
    def ankle_to_ball_m(self) -> float:
        """Horizontal distance from the ankle joint forward to the SMPL foot joint."""
        return (_HEEL_TO_BALL - _HEEL_TO_ANKLE) * self.foot_length_m

    def skeleton(self) -> LowerBodySkeleton:
        """The subject's lower-body skeleton (SMPL convention), built from the same lengths."""
        return builtin_skeleton(
            self.height_m,
            thigh_m=self.thigh_m,
            shank_m=self.shank_m,
            hip_width_m=self.hip_width_m,
            ankle_height_m=self.ankle_height_m,
            pelvis_above_hip_m=self.pelvis_above_hip_m,
            pelvis_behind_hip_m=self.pelvis_behind_hip_m,
            foot_joint_forward_m=self.ankle_to_ball_m,
            foot_joint_height_m=self.foot_joint_height_m,
        )

    def ankle_in_shoe(self) -> np.ndarray:
        """Ankle joint in the shoe frame (3,): above the sole, near the heel."""
        x = -0.5 * self.shoe_length_m + self.heel_to_ankle_m
        return np.array([x, 0.0, self.sole_thickness_m + self.ankle_height_m])

    def marker_in_shoe(self) -> np.ndarray:
        """A marker on top of the shoe over the instep, in the shoe frame (3,)."""
        x_ankle = self.ankle_in_shoe()[0]
        x = x_ankle + 0.35 * (0.5 * self.shoe_length_m - x_ankle)
        return np.array([x, 0.0, self.shoe_height_m])

    def appearance(self) -> Appearance:
        """Clothes colours for the renderer."""
        return Appearance(self.trouser_rgb, self.shoe_rgb, self.sole_rgb)


def _linear_from_srgb(c: np.ndarray) -> np.ndarray:
    c = np.clip(c, 0.0, 1.0)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def _pick_colour(rng: np.random.Generator, palette: tuple[RGB, ...], jitter: float) -> RGB:
    base = np.asarray(palette[int(rng.integers(len(palette)))])
    lin = _linear_from_srgb(base + rng.uniform(-jitter, jitter, size=3))
    return (float(lin[0]), float(lin[1]), float(lin[2]))


def _vary(rng: np.random.Generator, cv: float) -> float:
    """A multiplicative factor ``1 + cv·N(0, 1)`` clipped to two standard deviations."""
    return float(1.0 + cv * np.clip(rng.normal(), -2.0, 2.0))


def sample_subject(
    rng: np.random.Generator,
    height_range: tuple[float, float] = HEIGHT_RANGE_M,
    height_m: float | None = None,
) -> Subject:
    """A random subject: height uniform in ``height_range`` (or ``height_m``), ratios ±3 %, and
    a gait style (:class:`gaitnet.sim.gait_style.GaitStyle`)."""
    lo, hi = height_range
    if not 1.0 <= lo <= hi <= 2.3:
        raise ValueError(f"height_range must be within 1.0–2.3 m and ordered, got {height_range}")
    H = float(rng.uniform(lo, hi)) if height_m is None else float(height_m)
    foot = _FOOT * H * _vary(rng, 0.03)
    sole = float(rng.uniform(0.018, 0.030))
    ankle = _ANKLE * H * _vary(rng, 0.04)
    thigh_r = 0.052 * H * _vary(rng, 0.08)
    return Subject(
        height_m=H,
        thigh_m=_THIGH * H * _vary(rng, 0.03),
        shank_m=_SHANK * H * _vary(rng, 0.03),
        hip_width_m=_HIP_WIDTH * H * _vary(rng, 0.04),
        pelvis_above_hip_m=_PELVIS_UP * H * _vary(rng, 0.05),
        pelvis_behind_hip_m=_PELVIS_BACK * H * _vary(rng, 0.2),
        ankle_height_m=ankle,
        foot_length_m=foot,
        foot_joint_height_m=0.3 * ankle,
        shoe_length_m=foot + float(rng.uniform(0.02, 0.03)),
        shoe_width_m=_FOOT_WIDTH * H * _vary(rng, 0.05) + float(rng.uniform(0.008, 0.015)),
        shoe_height_m=sole + 0.9 * ankle * float(rng.uniform(0.9, 1.05)),
        sole_thickness_m=sole,
        thigh_radius_top_m=thigh_r,
        thigh_radius_bottom_m=float(rng.uniform(0.058, 0.068)),
        shank_radius_top_m=float(rng.uniform(0.052, 0.062)),
        shank_radius_bottom_m=float(rng.uniform(0.042, 0.050)),
        trouser_rgb=_pick_colour(rng, _TROUSERS_SRGB, 0.04),
        shoe_rgb=_pick_colour(rng, _SHOES_SRGB, 0.04),
        sole_rgb=_pick_colour(rng, _SOLES_SRGB, 0.03),
        gait_style=sample_gait_style(rng),  # drawn last: the draws above are unchanged
    )
