"""Plain data types shared by every session source (folder, RealSense bag, simulator).

A *session* is what one recording holds: calibration, a list of RGB-D frames and the IMU
stream. Frames load lazily: a source lists its frame timestamps up front and decodes a frame
only when asked (:meth:`SessionSource.frame`).

Frames of reference are named in variable names: ``T_CfromI`` maps points in the IMU frame to
the camera frame (``p_C = R_CfromI @ p_I + t_CfromI``). The camera frame is OpenCV's (x right,
y down, z forward).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

SESSION_FORMAT_VERSION = 1


@dataclass(frozen=True)
class CameraIntrinsics:
    """Pinhole intrinsics of one image stream (pixels).

    ``distortion`` holds OpenCV-ordered coefficients ``(k1, k2, p1, p2, k3)``; the D455's
    colour stream reports an (inverse) Brown-Conrady model whose coefficients are near zero and
    the pipeline treats images as undistorted pinhole images.
    """

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    distortion: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0)

    @property
    def K(self) -> np.ndarray:
        """3×3 camera matrix (float64)."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    def scaled(self, factor: float) -> CameraIntrinsics:
        """Intrinsics of the same camera with images resized by ``factor`` (pixel-centre model)."""
        return CameraIntrinsics(
            width=round(self.width * factor),
            height=round(self.height * factor),
            fx=self.fx * factor,
            fy=self.fy * factor,
            cx=(self.cx + 0.5) * factor - 0.5,
            cy=(self.cy + 0.5) * factor - 0.5,
            distortion=self.distortion,
        )


@dataclass(frozen=True)
class ImuNoise:
    """Continuous-time IMU noise densities, as on a datasheet (SI units).

    ``gyro_noise_density`` [rad/s/√Hz], ``accel_noise_density`` [m/s²/√Hz],
    ``gyro_bias_random_walk`` [rad/s²/√Hz], ``accel_bias_random_walk`` [m/s³/√Hz].
    A discrete per-sample variance at rate f is ``density² · f``.
    """

    gyro_noise_density: float
    accel_noise_density: float
    gyro_bias_random_walk: float
    accel_bias_random_walk: float


@dataclass(frozen=True)
class AprilTagBoard:
    """A printed sheet of AprilTags lying on the floor at a known pose.

    ``T_WfromBoard`` (4×4) places the board frame in the world; tag ``first_id + r * cols + c``
    has its centre at ``(origin + c * spacing, origin + r * spacing, 0)`` in the board frame,
    where ``spacing = tag_size_m + gap_m``. Corners follow OpenCV's aruco order.
    """

    name: str
    family: str
    rows: int
    cols: int
    tag_size_m: float
    gap_m: float
    first_id: int
    T_WfromBoard: np.ndarray

    def tag_centre_in_board(self, tag_id: int) -> np.ndarray:
        """Centre of tag ``tag_id`` in the board frame (z = 0)."""
        k = tag_id - self.first_id
        if not 0 <= k < self.rows * self.cols:
            raise KeyError(f"tag id {tag_id} is not on board {self.name!r}")
        r, c = divmod(k, self.cols)
        spacing = self.tag_size_m + self.gap_m
        half = self.tag_size_m / 2.0
        return np.array([half + c * spacing, half + r * spacing, 0.0])


@dataclass(frozen=True)
class SessionCalibration:
    """Everything ``session.yaml`` states about the sensors of one recording."""

    color: CameraIntrinsics
    depth: CameraIntrinsics
    depth_scale_m: float
    depth_aligned_to_color: bool
    T_CfromI: np.ndarray
    imu_noise: ImuNoise | None = None
    apriltag_boards: tuple[AprilTagBoard, ...] = ()
    device: str = "unknown"
    extra: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Frame:
    """One RGB-D frame. ``depth_m`` is float32 metres aligned to colour, 0 where invalid."""

    index: int
    t_ns: int
    rgb: np.ndarray
    depth_m: np.ndarray


@dataclass(frozen=True)
class ImuSamples:
    """IMU stream on common timestamps: ``accel`` specific force [m/s²], ``gyro`` [rad/s]."""

    t_ns: np.ndarray
    accel: np.ndarray
    gyro: np.ndarray

    def __len__(self) -> int:
        return int(self.t_ns.shape[0])

    @property
    def t_s(self) -> np.ndarray:
        return self.t_ns.astype(np.float64) * 1e-9


class SessionSource(Protocol):
    """What every session reader offers (folder, RealSense bag)."""

    @property
    def calibration(self) -> SessionCalibration: ...

    @property
    def frame_times_ns(self) -> np.ndarray: ...

    @property
    def imu(self) -> ImuSamples: ...

    def __len__(self) -> int: ...

    def frame(self, index: int) -> Frame: ...

    def frames(self) -> Iterator[Frame]: ...
