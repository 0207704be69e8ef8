"""The simulator's config: one YAML file (``configs/sim/*.yaml``) → :class:`SimConfig`.

Sections: ``subject``, ``gait`` (:class:`gaitnet.sim.gait.GaitConfig`), ``camera`` and
``mount`` (:mod:`gaitnet.sim.rig`), ``imu`` (:class:`gaitnet.sim.imu.ImuConfig`), ``scene``,
``sensor`` (:class:`gaitnet.sim.sensor_model.SensorNoiseConfig`) and ``output``. Every key
has a default, so an empty file is the default session. See docs/simulator.md for the table.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from gaitnet.sim.floor import FLOOR_FAMILIES
from gaitnet.sim.gait import GaitConfig
from gaitnet.sim.imu import ImuConfig
from gaitnet.sim.rig import CameraConfig, MountConfig
from gaitnet.sim.sensor_model import SensorNoiseConfig


@dataclass(frozen=True)
class SubjectConfig:
    """``height_m`` fixes the body height; None samples it uniformly in ``height_range_m``."""

    height_m: float | None = None
    height_range_m: tuple[float, float] = (1.55, 1.90)

    def __post_init__(self) -> None:
        lo, hi = self.height_range_m
        if not 1.2 <= lo <= hi <= 2.2:
            raise ValueError(f"height_range_m must be within 1.2–2.2 m, got {self.height_range_m}")
        if self.height_m is not None and not 1.2 <= self.height_m <= 2.2:
            raise ValueError(f"height_m must be within 1.2–2.2 m, got {self.height_m}")


@dataclass(frozen=True)
class SceneConfig:
    """The room the subject walks in.

    ``floor_family``: one of tiles, wood, carpet, concrete, textureless, or ``random``.
    ``clutter_count``: boxes/cylinders placed away from the walking path.
    ``shoe_like_floor_prob``: chance that the shoes take a colour close to the floor's.
    ``lighting_variation``: sample key/ambient light, direction and tint per session (else the
    defaults); ``exposure_range``: the session's exposure is drawn from this range and drifts
    slowly (auto-exposure) by ``exposure_drift`` (relative std over the session).
    ``apriltag_boards``: put the A3 sheets of 5×7 tag36h11 tags in front of the feet at the
    start and at the end; ``tag_size_m``/``tag_gap_m`` define the printed grid.
    ``room``: walls and a ceiling around the floor (else an unbounded floor).
    """

    floor_family: str = "random"
    clutter_count: int = 4
    shoe_like_floor_prob: float = 0.15
    lighting_variation: bool = True
    exposure_range: tuple[float, float] = (0.8, 1.25)
    exposure_drift: float = 0.03
    apriltag_boards: bool = True
    tag_size_m: float = 0.04
    tag_gap_m: float = 0.012
    room: bool = True
    texel_m: float = 0.0025

    def __post_init__(self) -> None:
        if self.floor_family not in (*FLOOR_FAMILIES, "random"):
            raise ValueError(
                f"floor_family must be one of {', '.join(FLOOR_FAMILIES)} or random, "
                f"got {self.floor_family!r}"
            )
        if not 0 <= self.clutter_count <= 50:
            raise ValueError("clutter_count must be within 0–50")
        if not 0.0 <= self.shoe_like_floor_prob <= 1.0:
            raise ValueError("shoe_like_floor_prob must be a probability")
        if (
            5 * self.tag_size_m + 4 * self.tag_gap_m > 0.28
            or 7 * self.tag_size_m + 6 * self.tag_gap_m > 0.40
        ):
            raise ValueError("5×7 tags of tag_size_m with tag_gap_m do not fit on an A3 sheet")


@dataclass(frozen=True)
class OutputConfig:
    """``labels``: write per-frame label and instance maps; ``preview_frames``: frames in the
    contact sheet ``preview.png`` (0 = none)."""

    labels: bool = True
    preview_frames: int = 6


@dataclass(frozen=True)
class SimConfig:
    subject: SubjectConfig = field(default_factory=SubjectConfig)
    gait: GaitConfig = field(default_factory=GaitConfig)
    camera: CameraConfig = field(default_factory=CameraConfig)
    mount: MountConfig = field(default_factory=MountConfig)
    imu: ImuConfig = field(default_factory=ImuConfig)
    scene: SceneConfig = field(default_factory=SceneConfig)
    sensor: SensorNoiseConfig = field(default_factory=SensorNoiseConfig)
    output: OutputConfig = field(default_factory=OutputConfig)
