"""Write tiny, fully known sessions for tests (not the simulator: pure patterns)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from gaitnet.io import (
    AprilTagBoard,
    CameraIntrinsics,
    ImuNoise,
    ImuSamples,
    SessionCalibration,
    SessionWriter,
)

WIDTH, HEIGHT = 32, 24


def tiny_calibration() -> SessionCalibration:
    cam = CameraIntrinsics(width=WIDTH, height=HEIGHT, fx=30.0, fy=30.0, cx=15.5, cy=11.5)
    T_CfromI = np.eye(4)
    T_CfromI[:3, 3] = [0.01, -0.005, 0.02]
    board = AprilTagBoard(
        name="start",
        family="tag36h11",
        rows=7,
        cols=5,
        tag_size_m=0.04,
        gap_m=0.012,
        first_id=0,
        T_WfromBoard=np.eye(4),
    )
    return SessionCalibration(
        color=cam,
        depth=cam,
        depth_scale_m=0.001,
        depth_aligned_to_color=True,
        T_CfromI=T_CfromI,
        imu_noise=ImuNoise(2.4e-4, 1.5e-3, 1e-5, 1e-4),
        apriltag_boards=(board,),
        device="test pattern",
    )


def tiny_frames(n: int = 4) -> list[tuple[int, np.ndarray, np.ndarray]]:
    rng = np.random.default_rng(1)
    frames = []
    for i in range(n):
        rgb = rng.integers(0, 256, size=(HEIGHT, WIDTH, 3), dtype=np.uint8)
        depth = rng.uniform(0.3, 3.0, size=(HEIGHT, WIDTH)).round(3).astype(np.float32)
        depth[0, :] = 0.0
        frames.append((1_000_000_000 + i * 33_333_333, rgb, depth))
    return frames


def tiny_imu(t0_ns: int = 990_000_000, n: int = 40, period_ns: int = 5_000_000) -> ImuSamples:
    t = t0_ns + period_ns * np.arange(n, dtype=np.int64)
    k = np.arange(n)[:, None]
    accel = np.hstack([0.1 * np.sin(k * 0.1), 0.2 * np.cos(k * 0.1), 9.81 + 0 * k])
    gyro = np.hstack([0.01 * k, -0.02 * k, 0.003 + 0 * k])
    return ImuSamples(t_ns=t, accel=accel.astype(np.float64), gyro=gyro.astype(np.float64))


def make_tiny_session(root: Path, n_frames: int = 4) -> Path:
    with SessionWriter(root, tiny_calibration()) as writer:
        for t_ns, rgb, depth in tiny_frames(n_frames):
            writer.add_frame(t_ns, rgb, depth)
        writer.set_imu(tiny_imu())
    return root
