"""What the renderer draws: the contract between the gait generator and the renderer.

Frames: world z up, floor z = 0. A *shoe frame* has its origin at the centre of the sole (on
the sole's plane), x along the foot towards the toe, y to the foot's left, z up out of the
sole; when the foot is flat on the floor ``R_WfromShoe`` is a rotation about z and the origin
has z = 0.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

Side = Literal["left", "right"]
SIDES: tuple[Side, Side] = ("left", "right")

# Label values (docs/design.md, *Conventions*): 0 background, 1 foot, 2 leg, 255 ignore.
LABEL_BACKGROUND, LABEL_FOOT, LABEL_LEG, LABEL_IGNORE = 0, 1, 2, 255
# Instance values: 0 none, 1 left, 2 right.
INSTANCE_NONE, INSTANCE_LEFT, INSTANCE_RIGHT = 0, 1, 2


@dataclass(frozen=True)
class LegSegment:
    """A thigh or shank drawn as a tapered cylinder with rounded ends (a trouser leg)."""

    side: Side
    name: Literal["thigh", "shank"]
    p_top_W: np.ndarray
    p_bottom_W: np.ndarray
    radius_top_m: float
    radius_bottom_m: float


@dataclass(frozen=True)
class ShoeState:
    """Pose and size of one shoe (a rounded 3-D shape sitting on its sole)."""

    side: Side
    R_WfromShoe: np.ndarray
    p_SoleCentre_W: np.ndarray
    length_m: float
    width_m: float
    height_m: float


@dataclass(frozen=True)
class BodyState:
    """Everything of the subject that the waist camera can see at one instant."""

    legs: tuple[LegSegment, ...]
    shoes: tuple[ShoeState, ShoeState]


@dataclass(frozen=True)
class Appearance:
    """Colours (linear RGB in [0, 1]) of the subject's clothes."""

    trouser_rgb: tuple[float, float, float]
    shoe_rgb: tuple[float, float, float]
    sole_rgb: tuple[float, float, float]
