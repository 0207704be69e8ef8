"""The simulator's config: one YAML file (``configs/sim/*.yaml``) → :class:`SimConfig`.

Sections: ``subject``, ``gait`` (:class:`gaitnet.sim.gait.GaitConfig`), ``motion``
(:class:`MotionConfig`: a motion-capture clip instead of the gait generator), ``camera`` and
``mount`` (:mod:`gaitnet.sim.rig`), ``imu`` (:class:`gaitnet.sim.imu.ImuConfig`), ``scene``,
``sensor`` (:class:`gaitnet.sim.sensor_model.SensorNoiseConfig`), ``floor_relief``
(:class:`gaitnet.sim.floor_relief.FloorReliefConfig`), ``timing``
(:class:`gaitnet.sim.frame_timing.FrameTimingConfig`) and ``output``. Every key
has a default, so an empty file is the default session. Each section checks its values' ranges
in its ``__post_init__``; :class:`SimConfig` checks the few that depend on two sections. See
docs/simulator.md for the table of keys and ranges.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from gaitnet.checks import check_each, check_int_range, check_range
from gaitnet.sim.floor import FLOOR_FAMILIES, MAX_TEXTURE_SIDE
from gaitnet.sim.floor_relief import FloorReliefConfig
from gaitnet.sim.frame_timing import FrameTimingConfig
from gaitnet.sim.gait import GaitConfig
from gaitnet.sim.imu import ImuConfig
from gaitnet.sim.mipmap import COARSEST_TEXEL_M
from gaitnet.sim.rig import CameraConfig, MountConfig
from gaitnet.sim.sensor_model import SensorNoiseConfig

HEIGHT_LIMITS_M = (1.2, 2.2)
#: The floor reaches this much further than the walk itself (see ``scene_setup.floor_extent``).
FLOOR_MARGIN_M = 6.0


@dataclass(frozen=True)
class SubjectConfig:
    """``height_m`` fixes the body height; None samples it uniformly in ``height_range_m``.

    Heights within 1.2–2.2 m.
    """

    height_m: float | None = None
    height_range_m: tuple[float, float] = (1.55, 1.90)

    def __post_init__(self) -> None:
        lo, hi = HEIGHT_LIMITS_M
        check_each("height_range_m", self.height_range_m, lo, hi, " m")
        if self.height_range_m[0] > self.height_range_m[1]:
            raise ValueError(f"height_range_m must be [low, high], got {self.height_range_m}")
        if self.height_m is not None:
            check_range("height_m", self.height_m, lo, hi, " m")


@dataclass(frozen=True)
class MotionConfig:
    """Where the subject's motion comes from (docs/simulator.md, *Motion sources*).

    ``clip``: an AMASS-format ``*_poses.npz`` (or SMPL-X ``*_stageii.npz``) file played as the
    subject's motion (:mod:`gaitnet.sim.clip_walk`); None: the gait generator (every other key
    of this section is then unused). ``start_s`` / ``duration_s``: the segment of the clip
    played (None: to its end). ``lead_in_s`` / ``lead_out_s``: the time over which the
    subject accelerates from standing into the clip / slows from it to standing
    (:mod:`gaitnet.sim.clip_lead`); 0: the session starts / ends with the clip's own frame
    (no standing). ``lowpass_hz``: cut-off of the zero-phase Butterworth filter applied to
    the clip's root and joint rotations and its translation (0: played as recorded).
    """

    clip: str | None = None
    start_s: float = 0.0
    duration_s: float | None = None
    lead_in_s: float = 1.0
    lead_out_s: float = 1.0
    lowpass_hz: float = 8.0

    def __post_init__(self) -> None:
        if self.clip is not None and (not isinstance(self.clip, str) or not self.clip.strip()):
            raise ValueError(f"clip must be a path to an .npz file, got {self.clip!r}")
        check_range("start_s", self.start_s, 0.0, 36000.0, " s")
        if self.duration_s is not None:
            check_range("duration_s", self.duration_s, 0.5, 3600.0, " s")
        for name in ("lead_in_s", "lead_out_s"):
            value = check_range(name, getattr(self, name), 0.0, 5.0, " s")
            if 0.0 < value < 0.5:
                raise ValueError(f"{name} must be 0 (none) or within [0.5, 5] s, got {value!r}")
        lowpass = check_range("lowpass_hz", self.lowpass_hz, 0.0, 60.0, " Hz")
        if 0.0 < lowpass < 2.0:
            raise ValueError(f"lowpass_hz must be 0 (off) or within [2, 60] Hz, got {lowpass!r}")


@dataclass(frozen=True)
class SceneConfig:
    """The room the subject walks in.

    ``floor_family``: one of tiles, wood, carpet, concrete, textureless, or ``random``.
    ``clutter_count``: boxes/cylinders placed away from the walking path (0–50).
    ``shoe_like_floor_prob``: chance that the shoes take a colour close to the floor's.
    ``lighting_variation``: sample key/ambient light, direction and tint per session (else the
    defaults); ``exposure_range``: the session's exposure factor is drawn from this range
    (within 0.25–4) and drifts slowly (auto-exposure) by ``exposure_drift`` (relative std over
    the session, 0–0.5).
    ``apriltag_boards``: put the A3 sheets of 5×7 tag36h11 tags in front of the feet at the
    start and at the end; ``tag_size_m`` (0.01–0.05 m) / ``tag_gap_m`` (0–0.03 m) define the
    printed grid, which must fit on the sheet.
    ``room``: walls and a ceiling around the floor (else an unbounded floor).
    ``texel_m``: floor texture resolution, 0.002–0.02 m.
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
        check_int_range("clutter_count", self.clutter_count, 0, 50)
        check_range("shoe_like_floor_prob", self.shoe_like_floor_prob, 0.0, 1.0)
        check_each("exposure_range", self.exposure_range, 0.25, 4.0)
        if self.exposure_range[0] > self.exposure_range[1]:
            raise ValueError(f"exposure_range must be [low, high], got {self.exposure_range}")
        check_range("exposure_drift", self.exposure_drift, 0.0, 0.5)
        check_range("tag_size_m", self.tag_size_m, 0.01, 0.05, " m")
        check_range("tag_gap_m", self.tag_gap_m, 0.0, 0.03, " m")
        if (
            5 * self.tag_size_m + 4 * self.tag_gap_m > 0.28
            or 7 * self.tag_size_m + 6 * self.tag_gap_m > 0.40
        ):
            raise ValueError("5×7 tags of tag_size_m with tag_gap_m do not fit on an A3 sheet")
        check_range("texel_m", self.texel_m, 0.002, COARSEST_TEXEL_M, " m")


@dataclass(frozen=True)
class OutputConfig:
    """``labels``: write per-frame label and instance maps; ``preview_frames``: frames in the
    contact sheet ``preview.png`` (0 = none, at most 24); ``compress_frames``: deflate the
    colour and depth PNGs (about 2.3× smaller, about ten times slower to write and six times
    slower to read) rather than store them uncompressed as a RealSense recording does; in
    ``gaitnet simulate`` and ``gaitnet simulate-dataset`` alike."""

    labels: bool = True
    preview_frames: int = 6
    compress_frames: bool = False

    def __post_init__(self) -> None:
        check_int_range("preview_frames", self.preview_frames, 0, 24)


@dataclass(frozen=True)
class SimConfig:
    subject: SubjectConfig = field(default_factory=SubjectConfig)
    gait: GaitConfig = field(default_factory=GaitConfig)
    motion: MotionConfig = field(default_factory=MotionConfig)
    camera: CameraConfig = field(default_factory=CameraConfig)
    mount: MountConfig = field(default_factory=MountConfig)
    imu: ImuConfig = field(default_factory=ImuConfig)
    scene: SceneConfig = field(default_factory=SceneConfig)
    sensor: SensorNoiseConfig = field(default_factory=SensorNoiseConfig)
    floor_relief: FloorReliefConfig = field(default_factory=FloorReliefConfig)
    timing: FrameTimingConfig = field(default_factory=FrameTimingConfig)
    output: OutputConfig = field(default_factory=OutputConfig)

    def __post_init__(self) -> None:
        # The floor texture spans the walk plus margins; its side is limited (floor.py).
        longest_m = self.gait.walk_length_m + FLOOR_MARGIN_M
        if longest_m / self.scene.texel_m > MAX_TEXTURE_SIDE:
            raise ValueError(
                f"scene.texel_m {self.scene.texel_m:g} is too fine for gait.walk_length_m "
                f"{self.gait.walk_length_m:g} (the floor would exceed {MAX_TEXTURE_SIDE} texels; "
                f"use scene.texel_m ≥ {longest_m / MAX_TEXTURE_SIDE:.4f})"
            )
