"""Simulate one recorded walking session with full ground truth (``gaitnet simulate``).

Order of work: sample the subject → generate the walk → build the room (floor texture, tag
sheets in front of the feet at the start and at the end, clutter) → sample lighting → render
every frame at the camera rate through the D455 sensor model → synthesise the IMU → write the
session folder (docs/session-format.md) and ``groundtruth/`` (docs/groundtruth.md).

Randomness: one ``numpy.random.SeedSequence(seed)`` spawns independent streams for the
subject, gait, room, lighting, IMU and sensor noise, so the same seed and config give the same
bytes, and changing e.g. the IMU noise does not change the subject.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from gaitnet.config import dump_config
from gaitnet.geometry import make_T, project, so3_exp
from gaitnet.io.atomic import atomic_write_text
from gaitnet.io.contact_sheet import colourise_depth, colourise_labels, contact_sheet, write_png
from gaitnet.io.session_folder import SessionWriter
from gaitnet.io.types import AprilTagBoard, SessionCalibration
from gaitnet.sim.config import SimConfig
from gaitnet.sim.floor import FLOOR_FAMILIES, FloorTexture, make_clutter, make_floor
from gaitnet.sim.gait import Walk, generate_walk
from gaitnet.sim.groundtruth import GroundTruthWriter
from gaitnet.sim.imu import simulate_imu
from gaitnet.sim.render import render_frame
from gaitnet.sim.render_color import srgb_to_linear
from gaitnet.sim.render_types import Lighting
from gaitnet.sim.scene import SIDES, Appearance
from gaitnet.sim.sensor_model import apply_sensor, auto_exposure
from gaitnet.sim.subject import Subject, sample_subject

log = logging.getLogger(__name__)

Progress = Callable[[Iterable, int], Iterable]
STREAMS = ("subject", "gait", "room", "lighting", "imu", "sensor")


@dataclass(frozen=True)
class SimulationResult:
    """What a simulation wrote and a few figures about it."""

    path: Path
    n_frames: int
    n_imu: int
    duration_s: float
    subject: Subject
    floor_family: str
    marker_checks: dict[str, float]


def rng_streams(seed: int) -> dict[str, np.random.Generator]:
    """Independent generators per part of the simulation (see module docstring)."""
    children = np.random.SeedSequence(seed).spawn(len(STREAMS))
    return {name: np.random.default_rng(c) for name, c in zip(STREAMS, children, strict=True)}


def _yaw_matrix(yaw: float) -> np.ndarray:
    return so3_exp(np.array([0.0, 0.0, yaw]))


def _board_in_front(
    name: str, first_id: int, walk: Walk, t: float, cfg: SimConfig
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
    s, g = cfg.scene.tag_size_m, cfg.scene.tag_gap_m
    grid_w = 5 * s + 4 * g
    centre_lat = float(np.mean(soles @ left))
    origin = (toe + 0.06) * forward + (centre_lat + grid_w / 2) * left
    # Board x = world right (−left), board y = forward: tags read upright in the waist camera.
    R = np.stack([-left, forward, np.array([0.0, 0.0, 1.0])], axis=1)
    origin[2] = 0.0
    return AprilTagBoard(name, "tag36h11", 7, 5, s, g, first_id, make_T(R, origin))


def floor_extent(walk: Walk) -> tuple[tuple[float, float], tuple[float, float]]:
    t = np.linspace(0.0, walk.duration_s, 200)
    soles = walk.sole_centres(t).reshape(-1, 3)
    (x0, y0), (x1, y1) = soles[:, :2].min(0), soles[:, :2].max(0)
    return (float(x0 - 2.0), float(x1 + 3.5)), (float(y0 - 2.0), float(y1 + 2.0))


def sample_lighting(rng: np.random.Generator, vary: bool) -> Lighting:
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
    appearance = subject.appearance()
    if rng.random() < p:
        mean_srgb = floor.levels[-1][..., :3].reshape(-1, 3).mean(0) / 255.0
        floor_lin = srgb_to_linear(mean_srgb)
        shoe = np.clip(floor_lin * rng.uniform(0.85, 1.15, 3), 0.0, 1.0)
        appearance = Appearance(
            appearance.trouser_rgb, tuple(float(c) for c in shoe), appearance.sole_rgb
        )
    return appearance


FRAME_MARGIN_S = 0.05  # frames start/end this far inside the IMU stream, as on a real device


def frame_times(duration_s: float, fps: float) -> np.ndarray:
    """Camera timestamps [s] on the nominal grid, inside the IMU's span by a small margin."""
    n = int(np.floor((duration_s - 2 * FRAME_MARGIN_S) * fps)) + 1
    return FRAME_MARGIN_S + np.arange(n) / fps


def preview_frames(times: np.ndarray, cfg: SimConfig) -> set[int]:
    """Frames for the contact sheet: the first one (standing on the tags), the rest walking."""
    n = cfg.output.preview_frames
    if n <= 0:
        return set()
    walking = (times > cfg.gait.stand_start_s + 0.5) & (times < times[-1] - cfg.gait.stand_end_s)
    candidates = np.flatnonzero(walking) if walking.sum() >= n else np.arange(len(times))
    picks = candidates[np.linspace(0, len(candidates) - 1, max(n - 1, 1)).round().astype(int)]
    return {0, *picks.tolist()} if n > 1 else {0}


def marker_pixel_checks(
    walk: Walk,
    t: float,
    T_WfromC: np.ndarray,
    K: np.ndarray,
    depth_true: np.ndarray,
    label: np.ndarray,
    instance: np.ndarray,
):
    """Per side: marker pixel (u, v), whether it is visible and whether its label is right.

    Visible: projects inside the image and the rendered surface there is the marker's
    (true depth within 1 cm of the marker's depth; otherwise something occludes it).
    """
    height, width = label.shape
    markers_W = walk.marker_points(np.array([t]))[0]
    T_CfromW = np.linalg.inv(T_WfromC)
    p_C = markers_W @ T_CfromW[:3, :3].T + T_CfromW[:3, 3]
    uv, valid = project(K, p_C)
    rows = []
    for k, side in enumerate(SIDES):
        u, v = uv[k]
        inside = bool(valid[k]) and 0 <= u < width - 0.5 and 0 <= v < height - 0.5
        visible, correct = False, False
        if inside:
            ui, vi = int(round(u)), int(round(v))
            visible = abs(float(depth_true[vi, ui]) - float(p_C[k, 2])) < 0.01
            correct = bool(label[vi, ui] == 1 and instance[vi, ui] == k + 1)
        rows.append((side, float(u), float(v), inside, visible, correct))
    return rows


def simulate_session(
    cfg: SimConfig,
    seed: int,
    out_dir: str | Path,
    overwrite: bool = False,
    progress: Progress | None = None,
    config_text: str | None = None,
) -> SimulationResult:
    """Simulate and write one session; returns where and what (module docstring)."""
    rngs = rng_streams(seed)
    sc = cfg.subject
    subject = sample_subject(rngs["subject"], sc.height_range_m, sc.height_m)
    walk = generate_walk(subject, cfg.gait, rngs["gait"])

    room_rng = rngs["room"]
    family = cfg.scene.floor_family
    if family == "random":
        family = FLOOR_FAMILIES[int(room_rng.integers(len(FLOOR_FAMILIES)))]
    boards: tuple[AprilTagBoard, ...] = ()
    if cfg.scene.apriltag_boards:
        boards = (
            _board_in_front("start", 0, walk, 0.0, cfg),
            _board_in_front("end", 35, walk, walk.duration_s, cfg),
        )
    extent = floor_extent(walk)
    floor = make_floor(
        family,
        room_rng,
        extent,
        cfg.scene.texel_m,
        boards,
        room_height_m=2.8 if cfg.scene.room else None,
    )
    path_y = float(np.mean(walk.sole_centres(np.array([0.0]))[0, :, 1]))
    clutter = make_clutter(room_rng, extent, cfg.scene.clutter_count, path_y_m=path_y)
    appearance = sample_appearance(subject, floor, room_rng, cfg.scene.shoe_like_floor_prob)

    light_rng = rngs["lighting"]
    light = sample_lighting(light_rng, cfg.scene.lighting_variation)
    exposure_gain = float(light_rng.uniform(*cfg.scene.exposure_range))

    cam = cfg.camera
    K = cam.intrinsics().K
    T_PfromC = cfg.mount.T_PfromC()
    T_CfromI = cfg.mount.T_CfromI()
    T_PfromI = T_PfromC @ T_CfromI
    calibration = SessionCalibration(
        color=cam.intrinsics(),
        depth=cam.intrinsics(),
        depth_scale_m=0.001,
        depth_aligned_to_color=True,
        T_CfromI=T_CfromI,
        imu_noise=None if cfg.imu.noise_free else cfg.imu.noise(),
        apriltag_boards=boards,
        device="gaitnet simulator (Intel RealSense D455-like)",
        extra={"simulator_seed": int(seed), "floor_family": family},
    )

    times = frame_times(walk.duration_s, cam.fps)
    t_ns = np.round(times * 1e9).astype(np.int64)
    imu, imu_truth = simulate_imu(
        walk.pelvis_kinematics, T_PfromI, 0.0, walk.duration_s, cfg.imu, rngs["imu"]
    )
    R_WP, p_P = walk.pelvis_pose(times)
    T_WfromC_all = np.einsum("nij,jk->nik", make_T(R_WP, p_P), T_PfromC)

    out_dir = Path(out_dir)
    writer = SessionWriter(out_dir, calibration, overwrite=overwrite)
    gt = GroundTruthWriter(writer.staging / "groundtruth", cfg.output.labels, writer.write_png)
    sensor_rng = rngs["sensor"]
    drift = np.cumsum(
        sensor_rng.normal(0.0, cfg.scene.exposure_drift / np.sqrt(len(times)), len(times))
    )
    preview_idx = preview_frames(times, cfg)
    preview_rows, captions, checks = [], [], []
    auto = None
    indices: Iterable[int] = range(len(times))
    if progress is not None:
        indices = progress(indices, len(times))
    try:
        for k in indices:
            T_WfromC = T_WfromC_all[k]
            result = render_frame(
                K,
                cam.width,
                cam.height,
                T_WfromC,
                floor,
                walk.body_state(float(times[k])),
                appearance,
                clutter,
                light,
            )
            target = auto_exposure(result.rgb_linear)
            auto = target if auto is None else auto + 0.25 * (target - auto)
            exposure = auto * exposure_gain * float(np.exp(drift[k]))
            rgb, depth = apply_sensor(result, K, sensor_rng, cfg.sensor, exposure)
            writer.add_frame(int(t_ns[k]), rgb, depth)
            gt.add_frame(int(t_ns[k]), result.label, result.instance)
            checks.extend(
                (int(t_ns[k]), *row)
                for row in marker_pixel_checks(
                    walk,
                    float(times[k]),
                    T_WfromC,
                    K,
                    result.depth_m,
                    result.label,
                    result.instance,
                )
            )
            if k in preview_idx:
                preview_rows.append([rgb, colourise_depth(depth), colourise_labels(result.label)])
                captions.append(f"t = {times[k]:.2f} s")
        writer.set_imu(imu)
        gt.write_all(walk, times, T_WfromC_all, T_PfromC, T_PfromI, imu_truth, checks)
        resolved = config_text if config_text is not None else dump_config(cfg)
        atomic_write_text(
            writer.staging / "sim_config.yaml",
            f"# gaitnet simulate --seed {seed} --config <this file> reproduces this session\n"
            + resolved,
        )
        if preview_rows:
            write_png(writer.staging / "preview.png", contact_sheet(preview_rows, captions))
        writer.close()
    except BaseException:
        writer.abort()
        raise
    visible = [c for c in checks if c[5]]
    marker_checks = {
        "visible_marker_fraction": len(visible) / max(1, len(checks)),
        "visible_marker_on_foot_label": (sum(c[6] for c in visible) / len(visible))
        if visible
        else float("nan"),
    }
    return SimulationResult(
        out_dir, len(times), len(imu), walk.duration_s, subject, family, marker_checks
    )
