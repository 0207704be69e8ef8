"""One simulated world from a config and a seed: subject, walk, room, lighting, camera mount.

Used by both products of the simulator — whole sessions (:mod:`gaitnet.sim.session`) and
single labelled frames (:mod:`gaitnet.sim.dataset`) — so every config key means the same in
both. Order of work: sample the subject → generate the walk (or play ``motion.clip``,
:mod:`gaitnet.sim.clip_walk`) → build the room (floor family,
tag sheets in front of the feet at the start and at the end, floor texture, walls, clutter,
shoe colours) → sample the lighting and the exposure factor → fix the camera pitch → the
rig's motion on its strap (:mod:`gaitnet.sim.mount_dynamics`).

Randomness: one ``numpy.random.SeedSequence(seed)`` spawns independent streams
(:data:`STREAMS`) for the subject, gait, room, lighting, IMU, sensor noise, camera mount, rig
motion, IMU calibration errors and frame timing, so
the same seed and config give the same world, and changing e.g. the IMU noise does not change
the subject. A stream a config does not use is never drawn from (a fixed ``mount.pitch_deg``
leaves the ``mount`` stream untouched).
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass, field, replace

import numpy as np

from gaitnet.errors import InputError
from gaitnet.geometry import make_T, so3_exp
from gaitnet.io.types import AprilTagBoard
from gaitnet.sim.clip_walk import build_clip_walk
from gaitnet.sim.clutter import Clutter, make_clutter
from gaitnet.sim.config import SimConfig
from gaitnet.sim.floor import FLOOR_FAMILIES, FloorTexture, make_floor
from gaitnet.sim.floor_relief import FloorRelief, flat_relief, sample_floor_relief
from gaitnet.sim.gait import Walk, generate_walk
from gaitnet.sim.mount_dynamics import MountMotion, build_mount_motion, compose_kinematics
from gaitnet.sim.render import render_frame
from gaitnet.sim.render_color import srgb_to_linear
from gaitnet.sim.render_motion import Motion
from gaitnet.sim.render_types import Lighting, RenderResult
from gaitnet.sim.rig import PITCH_RANGE_DEG, CameraConfig, MountConfig
from gaitnet.sim.scene import SIDES, Appearance
from gaitnet.sim.sensor_depth import DepthUnit, sample_depth_unit
from gaitnet.sim.subject import Subject, sample_subject

__all__ = [
    "ROOM_HEIGHT_M",
    "SEED_LIMIT",
    "STREAMS",
    "SimScene",
    "board_in_front",
    "build_scene",
    "check_seed",
    "floor_extent",
    "rng_streams",
    "sample_appearance",
    "sample_lighting",
]

STREAMS = (
    "subject",
    "gait",
    "room",
    "lighting",
    "imu",
    "sensor",
    "mount",
    "rig_motion",  # heel-strike shock amplitudes (mount_dynamics)
    "imu_calibration",  # IMU scale / misalignment errors and time offset
    "frame_timing",  # frame timestamp jitter and dropped frames
    "floor_relief",  # the floor's millimetre relief (floor_relief)
    "depth",  # the depth camera unit's fixed errors and per-frame depth noise (sensor_depth)
    "sway",  # postural sway of the pelvis while standing (gait_style)
)
SEED_LIMIT = 2**32  # seeds are 0 ≤ seed < 2**32 (the command line promises 32 bits)
ROOM_HEIGHT_M = 2.8


def check_seed(seed: object, name: str = "seed") -> int:
    """``seed`` as an int, or :class:`InputError` when it is not an integer in [0, 2**32)."""
    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral):
        raise InputError(f"{name} must be an integer, got {seed!r}")
    if not 0 <= int(seed) < SEED_LIMIT:
        raise InputError(f"{name} must be within 0–{SEED_LIMIT - 1}, got {seed}")
    return int(seed)


def rng_streams(seed: int) -> dict[str, np.random.Generator]:
    """Independent generators per part of the simulation (see module docstring).

    Spawned children are numbered, so adding a stream at the end of :data:`STREAMS` leaves the
    earlier ones unchanged.
    """
    children = np.random.SeedSequence(check_seed(seed)).spawn(len(STREAMS))
    return {name: np.random.default_rng(c) for name, c in zip(STREAMS, children, strict=True)}


def _yaw_matrix(yaw: float) -> np.ndarray:
    return so3_exp(np.array([0.0, 0.0, yaw]))


def board_in_front(
    name: str, first_id: int, walk: Walk, t: float, tag_size_m: float, tag_gap_m: float
) -> AprilTagBoard:
    """An A3 sheet lying in front of the toes at time ``t``, tags reading upright in the camera."""
    soles = walk.sole_centres(np.array([t]))[0]
    yaws = [
        float(
            np.interp(
                t,
                walk.events[s].flat_start_s,
                walk.events[s].yaw_rad,
                left=walk.events[s].yaw_rad[0],
                right=walk.events[s].yaw_rad[-1],
            )
        )
        for s in SIDES
    ]
    heading = float(np.arctan2(np.mean(np.sin(yaws)), np.mean(np.cos(yaws))))
    R_head = _yaw_matrix(heading)
    forward, left = R_head[:, 0], R_head[:, 1]
    toe = float(np.max(soles @ forward)) + 0.5 * walk.subject.shoe_length_m
    grid_w = 5 * tag_size_m + 4 * tag_gap_m
    centre_lat = float(np.mean(soles @ left))
    origin = (toe + 0.06) * forward + (centre_lat + grid_w / 2) * left
    # Board x = world right (−left), board y = forward: tags read upright in the waist camera.
    R = np.stack([-left, forward, np.array([0.0, 0.0, 1.0])], axis=1)
    origin[2] = 0.0
    return AprilTagBoard(name, "tag36h11", 7, 5, tag_size_m, tag_gap_m, first_id, make_T(R, origin))


def floor_extent(walk: Walk) -> tuple[tuple[float, float], tuple[float, float]]:
    """The floor under the whole walk: 2 m behind and beside it, 3.5 m beyond its end."""
    t = np.linspace(0.0, walk.duration_s, 200)
    soles = walk.sole_centres(t).reshape(-1, 3)
    (x0, y0), (x1, y1) = soles[:, :2].min(0), soles[:, :2].max(0)
    return (float(x0 - 2.0), float(x1 + 3.5)), (float(y0 - 2.0), float(y1 + 2.0))


def sample_lighting(rng: np.random.Generator, vary: bool) -> Lighting:
    """Random key/ambient light, direction and tint; the defaults (no draw) when not ``vary``."""
    if not vary:
        return Lighting()
    azimuth = rng.uniform(0, 2 * np.pi)
    horizontal = rng.uniform(0.05, 0.6)
    tint = np.array([1.0, rng.uniform(0.93, 1.0), rng.uniform(0.82, 1.0)])
    return replace(
        Lighting(),
        direction_W=(float(horizontal * np.cos(azimuth)), float(horizontal * np.sin(azimuth)), 1.0),
        key=float(rng.uniform(0.3, 0.8)),
        ambient=float(rng.uniform(0.25, 0.6)),
        rgb=tuple(float(v) for v in tint / tint.max()),
    )


def sample_appearance(
    subject: Subject, floor: FloorTexture, rng: np.random.Generator, p: float
) -> Appearance:
    """The subject's clothes; with probability ``p`` shoes coloured close to the floor."""
    appearance = subject.appearance()
    if rng.random() < p:
        mean_srgb = floor.levels[-1][..., :3].reshape(-1, 3).mean(0) / 255.0
        floor_lin = srgb_to_linear(mean_srgb)
        shoe = np.clip(floor_lin * rng.uniform(0.85, 1.15, 3), 0.0, 1.0)
        appearance = Appearance(
            appearance.trouser_rgb, tuple(float(c) for c in shoe), appearance.sole_rgb
        )
    return appearance


@dataclass(frozen=True, eq=False)
class SimScene:
    """Everything of one simulated world that does not depend on the frame time.

    ``mount`` has a fixed ``pitch_deg`` (drawn when the config gives a range);
    ``exposure_gain`` is the session's exposure factor from ``scene.exposure_range``.
    """

    subject: Subject
    walk: Walk
    floor_family: str
    boards: tuple[AprilTagBoard, ...]
    floor: FloorTexture
    clutter: tuple[Clutter, ...]
    appearance: Appearance
    light: Lighting
    exposure_gain: float
    mount: MountConfig
    mount_motion: MountMotion
    relief: FloorRelief = field(default_factory=flat_relief)
    depth_unit: DepthUnit = field(default_factory=DepthUnit)
    pelvis_tilt_deg: float = 0.0

    @property
    def pitch_deg(self) -> float:
        """The camera's downward pitch from horizontal while the subject stands: the mount's
        pitch in the pelvis frame plus the standing pelvis's anterior tilt (0 for generated
        walks; a clip's median tilt, ``pelvis_tilt_deg``)."""
        return float(self.mount.pitch_deg) + self.pelvis_tilt_deg  # type: ignore[arg-type]

    def T_WfromC(self, t_s: np.ndarray) -> np.ndarray:
        """Camera poses (n, 4, 4) at times ``t_s`` (n,): the pelvis pose times the mount's
        moving camera-in-pelvis pose (heel-strike shocks and strap wobble, ``mount_motion``)."""
        t = np.asarray(t_s, dtype=np.float64)
        R_WP, p_P = self.walk.pelvis_pose(t)
        return make_T(R_WP, p_P) @ self.mount_motion.T_PfromC(t)

    def camera_kinematics(self, t_s: np.ndarray) -> tuple[np.ndarray, ...]:
        """``(R_WfromC, p_CinW, v, a, ω_C)`` at times ``t_s``: what the IMU on the camera
        feels (:func:`gaitnet.sim.mount_dynamics.compose_kinematics`)."""
        kin = compose_kinematics(self.walk.pelvis_kinematics, self.mount_motion.kinematics)
        return kin(t_s)

    def render(
        self, camera: CameraConfig, t_s: float, T_WfromC: np.ndarray, exposure_s: float = 0.0
    ) -> RenderResult:
        """The noise-free view of ``camera`` at pose ``T_WfromC`` and time ``t_s`` (the middle
        of the exposure); with ``exposure_s`` > 0 the colour is integrated over
        ``t_s ± exposure_s / 2`` (motion blur, :mod:`gaitnet.sim.render_motion`), while depth,
        labels and instances stay the instant ``t_s``."""
        body = self.walk.body_state(t_s)
        motion = None
        if exposure_s > 0:
            t_end = t_s + exposure_s / 2
            T_end = self.T_WfromC(np.array([t_end]))[0]
            motion = Motion(T_WfromC, body, T_end, self.walk.body_state(t_end))
        return render_frame(
            camera.intrinsics().K,
            camera.width,
            camera.height,
            T_WfromC,
            self.floor,
            body,
            self.appearance,
            self.clutter,
            self.light,
            relief=self.relief,
            motion=motion,
        )


def build_scene(cfg: SimConfig, rngs: dict[str, np.random.Generator], threads: int = 1) -> SimScene:
    """The world of one session or one data-set frame (module docstring), drawn from ``rngs``
    (:func:`rng_streams`). Every ``subject``, ``gait``, ``scene`` and ``mount.pitch_deg`` key
    acts here. ``threads``: threads generating the floor texture (the same world for any
    number)."""
    sc = cfg.subject
    if cfg.motion.clip is None:
        subject = sample_subject(rngs["subject"], sc.height_range_m, sc.height_m)
        walk = generate_walk(subject, cfg.gait, rngs["gait"], sway_rng=rngs["sway"])
    else:  # a motion-capture clip drives the subject (docs/simulator.md, *Motion sources*)
        walk = build_clip_walk(cfg, rngs["subject"])
        subject = walk.subject

    room_rng = rngs["room"]
    family = cfg.scene.floor_family
    if family == "random":
        family = FLOOR_FAMILIES[int(room_rng.integers(len(FLOOR_FAMILIES)))]
    boards: tuple[AprilTagBoard, ...] = ()
    if cfg.scene.apriltag_boards:
        size, gap = cfg.scene.tag_size_m, cfg.scene.tag_gap_m
        boards = (
            board_in_front("start", 0, walk, 0.0, size, gap),
            board_in_front("end", 35, walk, walk.duration_s, size, gap),
        )
    extent = floor_extent(walk)
    floor = make_floor(
        family,
        room_rng,
        extent,
        cfg.scene.texel_m,
        boards,
        room_height_m=ROOM_HEIGHT_M if cfg.scene.room else None,
        threads=threads,
    )
    path_y = float(np.mean(walk.sole_centres(np.array([0.0]))[0, :, 1]))
    path_t = np.linspace(0.0, walk.duration_s, max(2, int(np.ceil(walk.duration_s / 0.05)) + 1))
    path_xy = walk.sole_centres(path_t)[:, :, :2].mean(axis=1)  # midway between the feet
    clutter = make_clutter(
        room_rng, extent, cfg.scene.clutter_count, path_y_m=path_y, path_xy=path_xy
    )
    appearance = sample_appearance(subject, floor, room_rng, cfg.scene.shoe_like_floor_prob)

    light_rng = rngs["lighting"]
    light = sample_lighting(light_rng, cfg.scene.lighting_variation)
    exposure_gain = float(light_rng.uniform(*cfg.scene.exposure_range))
    drawn = cfg.mount.with_pitch(rngs["mount"])
    mount, tilt = drawn, 0.0
    if walk.source is not None:  # mount.pitch_deg is from horizontal with the subject standing
        pitch = float(drawn.pitch_deg) - walk.source.pelvis_tilt_deg  # type: ignore[arg-type]
        mount = replace(drawn, pitch_deg=float(np.clip(pitch, *PITCH_RANGE_DEG)))
        tilt = float(drawn.pitch_deg) - float(mount.pitch_deg)  # type: ignore[arg-type]
    mount_motion = build_mount_motion(walk, mount, mount.T_PfromC(), rngs["rig_motion"])
    return SimScene(
        subject=subject,
        walk=walk,
        floor_family=family,
        boards=boards,
        floor=floor,
        clutter=clutter,
        appearance=appearance,
        light=light,
        exposure_gain=exposure_gain,
        mount=mount,
        mount_motion=mount_motion,
        relief=sample_floor_relief(rngs["floor_relief"], cfg.floor_relief, family, extent),
        depth_unit=sample_depth_unit(rngs["depth"]),
        pelvis_tilt_deg=tilt,
    )
