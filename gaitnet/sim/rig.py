"""The sensor rig: a D455-like camera on the front of the pelvis and its IMU.

Frames: pelvis P (origin at the SMPL pelvis joint, x forward, y left, z up), camera C (OpenCV:
x right, y down, z forward), IMU I (rigidly attached to the camera, ``T_CfromI``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gaitnet.geometry import make_T, so3_exp
from gaitnet.io.types import CameraIntrinsics

# Camera looking along the pelvis x axis, level: camera x = −pelvis y, y = −pelvis z, z = pelvis x.
R_PfromC_LEVEL = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


@dataclass(frozen=True)
class CameraConfig:
    """Colour camera (depth is aligned to it). Defaults: a D455 at 640×480, 30 Hz."""

    width: int = 640
    height: int = 480
    fx: float = 386.0
    fy: float = 386.0
    cx: float = 319.5
    cy: float = 239.5
    fps: float = 30.0

    def __post_init__(self) -> None:
        if self.width < 16 or self.height < 16 or self.fx <= 0 or self.fy <= 0 or self.fps <= 0:
            raise ValueError("camera size, focal lengths and fps must be positive")

    def intrinsics(self) -> CameraIntrinsics:
        return CameraIntrinsics(self.width, self.height, self.fx, self.fy, self.cx, self.cy)


@dataclass(frozen=True)
class MountConfig:
    """Where the camera sits on the pelvis and how the IMU sits in the camera.

    ``pitch_deg``: downward pitch of the optical axis from horizontal (thesis: about 30–75°).
    ``offset_m``: camera centre in the pelvis frame (forward, left, up) [m] — on the belly.
    ``imu_in_camera_m`` / ``imu_rpy_deg``: the IMU origin in the camera frame and the
    IMU-to-camera rotation (roll, pitch, yaw about the camera x, y, z axes).
    """

    pitch_deg: float = 70.0
    yaw_deg: float = 0.0
    roll_deg: float = 0.0
    offset_m: tuple[float, float, float] = (0.17, 0.0, 0.05)
    imu_in_camera_m: tuple[float, float, float] = (-0.0302, 0.0074, 0.0160)
    imu_rpy_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        if not 10.0 <= self.pitch_deg <= 89.0:
            raise ValueError(f"pitch_deg must be within 10–89°, got {self.pitch_deg}")

    def T_PfromC(self) -> np.ndarray:
        """Camera pose in the pelvis frame: level camera, then yaw, pitch down, roll."""
        yaw = so3_exp(np.deg2rad(self.yaw_deg) * np.array([0.0, 0.0, 1.0]))
        pitch = so3_exp(np.deg2rad(self.pitch_deg) * np.array([0.0, 1.0, 0.0]))
        roll = so3_exp(np.deg2rad(self.roll_deg) * np.array([1.0, 0.0, 0.0]))
        R = yaw @ pitch @ roll @ R_PfromC_LEVEL
        return make_T(R, np.asarray(self.offset_m, dtype=np.float64))

    def T_CfromI(self) -> np.ndarray:
        rx, ry, rz = np.deg2rad(self.imu_rpy_deg)
        R = (
            so3_exp(np.array([0.0, 0.0, rz]))
            @ so3_exp(np.array([0.0, ry, 0.0]))
            @ so3_exp(np.array([rx, 0.0, 0.0]))
        )
        return make_T(R, np.asarray(self.imu_in_camera_m, dtype=np.float64))
