"""Simulate one recorded walking session with full ground truth (``gaitnet simulate``).

Order of work: build the world (:func:`gaitnet.sim.scene_setup.build_scene`: subject, walk,
room with tag sheets, lighting, camera pitch) → render every frame at the camera rate through
the D455 sensor model → synthesise the IMU → write the session folder (docs/session-format.md)
and ``groundtruth/`` (docs/groundtruth.md) through :class:`gaitnet.io.session_folder.
SessionWriter`, which stages everything in a hidden folder and publishes it only when complete
(an exception removes it; a killed run's leftovers are removed by the next write).

Randomness: independent streams per part of the simulation
(:func:`gaitnet.sim.scene_setup.rng_streams`), so the same seed and config give the same bytes,
and changing e.g. the IMU noise does not change the subject.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterable
from contextlib import closing
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gaitnet.config import dump_config
from gaitnet.geometry import project
from gaitnet.io.atomic import atomic_write_text, check_output_folder
from gaitnet.io.contact_sheet import colourise_depth, colourise_labels, contact_sheet, write_png
from gaitnet.io.session_folder import SessionWriter
from gaitnet.io.types import SessionCalibration
from gaitnet.sim.config import SimConfig
from gaitnet.sim.frame_timing import make_frame_times
from gaitnet.sim.gait import Walk
from gaitnet.sim.groundtruth import GroundTruthWriter
from gaitnet.sim.imu import draw_imu_calibration, simulate_imu
from gaitnet.sim.scene import SIDES
from gaitnet.sim.scene_setup import build_scene, check_seed, rng_streams
from gaitnet.sim.session_frames import FrameOut, make_job, render_frames
from gaitnet.sim.subject import Subject
from gaitnet.sim.worker_pool import default_workers, start_workers

log = logging.getLogger(__name__)

Progress = Callable[[Iterable, int], Iterable]


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
    workers: int | None = None,
) -> SimulationResult:
    """Simulate and write one session; returns where and what (module docstring).

    ``workers``: processes rendering frames (at most 2 at once; None: 2 where 2 or more CPUs
    are usable, else 1; :mod:`gaitnet.sim.session_frames`); the same bytes for any value.

    ``seed``: 0 ≤ seed < 2**32 (else :class:`~gaitnet.errors.InputError`); ``out_dir`` must not
    be a file, nor a non-empty folder unless ``overwrite``; both are checked before any work.
    """
    seed = check_seed(seed)
    out_dir = check_output_folder(out_dir, overwrite)
    workers = default_workers() if workers is None else int(workers)
    start_workers(workers)  # they get ready on another CPU while the world is built
    rngs = rng_streams(seed)
    scene = build_scene(cfg, rngs, threads=workers)  # the CPUs the frames will use
    walk, subject, family = scene.walk, scene.subject, scene.floor_family

    cam = cfg.camera
    T_CfromI = cfg.mount.T_CfromI()
    extra: dict[str, object] = {"simulator_seed": seed, "floor_family": family}
    if cfg.mount.pitch_is_drawn:
        extra["mount_pitch_deg"] = round(scene.pitch_deg, 6)
    calibration = SessionCalibration(
        color=cam.intrinsics(),
        depth=cam.intrinsics(),
        depth_scale_m=0.001,
        depth_aligned_to_color=True,
        T_CfromI=T_CfromI,
        imu_noise=None if cfg.imu.noise_free else cfg.imu.noise(),
        apriltag_boards=scene.boards,
        device="gaitnet simulator (Intel RealSense D455-like)",
        extra=extra,
    )

    # Frame times: true exposure mid-times (render, ground truth) and timestamps (file names).
    frames = make_frame_times(walk.duration_s, cam.fps, cfg.timing, rngs["frame_timing"])
    times, t_ns = frames.true_s, frames.stamp_ns
    calib_rng = rngs["imu_calibration"]
    imu_calibration = draw_imu_calibration(
        cfg.imu, calib_rng, cfg.timing.draw_imu_time_offset(calib_rng)
    )
    imu, imu_truth = simulate_imu(
        scene.camera_kinematics, T_CfromI, 0.0, walk.duration_s, cfg.imu, rngs["imu"],
        imu_calibration,
    )  # fmt: skip
    T_WfromC_all = scene.T_WfromC(times)

    job = make_job(cfg, scene, times, T_WfromC_all, rngs, marker_pixel_checks)
    preview_idx = preview_frames(times, cfg)
    preview_rows, captions, checks = [], [], []
    exposures = np.zeros((len(times), 2))
    writer = SessionWriter(
        out_dir, calibration, overwrite=overwrite, compress_frames=cfg.output.compress_frames
    )
    try:
        gt = GroundTruthWriter(writer.staging / "groundtruth", cfg.output.labels, writer.write_png)
        # closing(): on an interrupt the worker pool stops here, before the error propagates
        # (a generator left to the garbage collector stops it after the CLI's last line)
        with closing(render_frames(job, workers)) as rendered:
            outs: Iterable[FrameOut] = rendered
            if progress is not None:  # only now: a progress bar must not precede an early error
                outs = progress(outs, len(times))
            for out in outs:
                k = out.index
                writer.add_frame(int(t_ns[k]), out.rgb, out.depth_m)
                gt.add_frame(int(t_ns[k]), out.label, out.instance)
                checks.extend((int(t_ns[k]), *row) for row in out.marker_rows)
                exposures[k] = out.exposure, out.exposure_s
                if k in preview_idx:
                    preview_rows.append(
                        [out.rgb, colourise_depth(out.depth_m), colourise_labels(out.label)]
                    )
                    captions.append(f"t = {times[k]:.2f} s")
        writer.set_imu(imu)
        atomic_write_text(
            writer.staging / "groundtruth" / "exposure.csv",
            "t_ns,exposure_factor,exposure_time_s\n"
            + "".join(f"{int(t_ns[k])},{e:.6g},{d:.6g}\n" for k, (e, d) in enumerate(exposures)),
        )
        gt.write_all(walk, times, T_WfromC_all, T_CfromI, imu_truth, checks, t_ns)
        gt.write_motion(walk, times, t_ns)
        gt.write_rig(scene.mount_motion, frames, imu_truth, imu_calibration)
        gt.write_floor_and_depth(scene.relief.to_dict(), scene.depth_unit.to_dict(cfg.sensor))
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
    feet_seen = sum(1 for c in checks if c[4]) / max(1, len(checks))
    if feet_seen < 0.5:
        log.warning(
            "%s: the foot markers are in the image in only %.0f %% of frame-sides; check "
            "mount.pitch_deg / yaw_deg / roll_deg and the camera intrinsics",
            out_dir,
            100 * feet_seen,
        )
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
