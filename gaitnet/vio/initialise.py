"""The filter's first state: from the first AprilTag board pose, else from gravity and the floor.

Thesis sec. 3.4: the first tag pose initialises attitude and position (3.33). Users without
tag sheets still get a run: roll and pitch from the accelerometer's mean while the subject
stands at the start, the camera height from the floor plane fitted in the first frame, yaw 0
chosen so that the camera's optical axis, projected on the floor, points along world +x (the
walking direction of a belly camera looking down-forward), x = y = 0. The gyroscope bias starts
at the gyroscope's mean over the same standing window when it is quiet enough (a standing body
turns by well under 1°/s).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from gaitnet.errors import SessionError
from gaitnet.geometry import quat_from_rotmat
from gaitnet.geometry.floor_plane import FloorParams, fit_floor_depth
from gaitnet.io.types import Frame, ImuSamples, SessionCalibration
from gaitnet.vio.apriltags import AprilTagParams, detect_board_pose, imu_pose_from_camera
from gaitnet.vio.state import FilterState, ImuState

log = logging.getLogger(__name__)

__all__ = ["Initialisation", "InitParams", "initialise", "standing_up", "up_in_camera"]


@dataclass(frozen=True)
class InitParams:
    """Initialisation settings (docs/vio.md, *Initialisation*)."""

    standing_window_s: float = 0.5
    """IMU window at the start averaged for gravity and the gyroscope bias [s]; the protocol
    starts with ≥ 1 s of standing (thesis sec. 5.1)."""
    max_tag_frames: int = 15
    """Frames searched for the first tag pose (0.5 s at 30 Hz) before falling back to gravity
    and the floor."""
    quiet_gyro_rad_s: float = 0.05
    """The gyroscope counts as still (its mean is taken as the bias) when its standard deviation
    over the window is below this [rad/s] (sway is ~0.01 rad/s, steps are > 0.5 rad/s)."""
    std_velocity_mps: float = 0.05
    """Initial velocity standard deviation [m/s] (standing with postural sway)."""
    std_gyro_bias_rad_s: float = 0.005
    """Initial gyroscope-bias standard deviation [rad/s]: the BMI055's zero-rate offset is
    ±1°/s before calibration; after averaging a still window the residual is ~0.1°/s."""
    std_accel_bias_mps2: float = 0.1
    """Initial accelerometer-bias standard deviation [m/s²] (BMI055 zero-g offset ±70 mg is the
    worst case; RealSense units are calibrated at the factory)."""
    std_attitude_no_tag_rad: float = 0.02
    """Roll/pitch standard deviation without tags [rad] (gravity averaged while standing)."""
    std_yaw_no_tag_rad: float = 0.01
    """Yaw standard deviation without tags [rad]: yaw 0 is a definition of the world frame."""
    std_position_no_tag_m: float = 0.01
    """Position standard deviation without tags [m] (x = y = 0 by definition; height from the
    floor fit)."""


@dataclass(frozen=True)
class Initialisation:
    """The first state, how it was found (``"apriltag"`` or ``"gravity_floor"``), a sentence for
    the summary, the index of the frame it belongs to, the gravity magnitude the
    accelerometer measured while standing (``|mean specific force|`` over the standing window;
    it includes the accelerometer's scale error along the vertical, which is what the filter
    must subtract), and the board that initialised it (empty without tags)."""

    state: FilterState
    method: str
    note: str
    frame_index: int
    measured_gravity_mps2: float
    board: str = ""


def up_in_camera(R_WfromI: np.ndarray, T_CfromI: np.ndarray) -> np.ndarray:
    """World up ``[0, 0, 1]`` in the camera frame for an IMU attitude."""
    return T_CfromI[:3, :3] @ (R_WfromI.T @ np.array([0.0, 0.0, 1.0]))


def _window(imu: ImuSamples, t0_ns: int, seconds: float) -> tuple[np.ndarray, np.ndarray]:
    sel = (imu.t_ns >= t0_ns - int(0.05e9)) & (imu.t_ns <= t0_ns + int(seconds * 1e9))
    if sel.sum() < 5:
        sel = np.zeros(len(imu), dtype=bool)
        sel[: min(len(imu), 20)] = True
    return imu.accel[sel], imu.gyro[sel]


def standing_up(imu: ImuSamples, t0_ns: int, params: InitParams) -> np.ndarray:
    """Up in the IMU frame (unit): the accelerometer's mean specific force over the standing
    window from ``t0_ns`` (a still accelerometer reads +g upwards)."""
    accel, _ = _window(imu, t0_ns, params.standing_window_s)
    mean = accel.mean(axis=0)
    return mean / max(float(np.linalg.norm(mean)), 1e-12)


def _gyro_bias(gyro: np.ndarray, params: InitParams) -> np.ndarray:
    if len(gyro) > 1 and float(np.max(np.std(gyro, axis=0))) < params.quiet_gyro_rad_s:
        return gyro.mean(axis=0)
    log.info("the IMU is not still at the start: gyroscope bias starts at 0")
    return np.zeros(3)


def _gravity_attitude(accel_mean: np.ndarray, T_CfromI: np.ndarray) -> np.ndarray:
    """``R_WfromI`` with world z along the measured up and yaw so that the camera's optical
    axis points along +x on the floor."""
    up_I = accel_mean / np.linalg.norm(accel_mean)  # a still accelerometer reads +g upwards
    z_C_in_I = T_CfromI[:3, :3].T @ np.array([0.0, 0.0, 1.0])
    fwd = z_C_in_I - (z_C_in_I @ up_I) * up_I
    if np.linalg.norm(fwd) < 1e-6:  # camera looking straight down: use its image-up
        y_C_in_I = T_CfromI[:3, :3].T @ np.array([0.0, -1.0, 0.0])
        fwd = y_C_in_I - (y_C_in_I @ up_I) * up_I
    x_I = fwd / np.linalg.norm(fwd)
    y_I = np.cross(up_I, x_I)
    R_IfromW = np.stack([x_I, y_I, up_I], axis=1)  # columns: world axes in the IMU frame
    return R_IfromW.T


def initialise(
    frames: list[Frame],
    imu: ImuSamples,
    calib: SessionCalibration,
    t_ref_ns: int,
    params: InitParams,
    tag_params: AprilTagParams,
    floor_params: FloorParams,
) -> Initialisation:
    """The first filter state (module docstring). ``frames`` are the first frames of the
    session (at least one); the state's time is that of the frame it was found in."""
    T_CfromI = calib.T_CfromI
    accel, gyro = _window(imu, int(frames[0].t_ns), params.standing_window_s)
    b_g = _gyro_bias(gyro, params)
    g = float(np.linalg.norm(accel.mean(axis=0)))
    P = np.zeros((15, 15))
    P[6:9, 6:9] = np.eye(3) * params.std_velocity_mps**2
    P[9:12, 9:12] = np.eye(3) * params.std_gyro_bias_rad_s**2
    P[12:15, 12:15] = np.eye(3) * params.std_accel_bias_mps2**2
    if calib.apriltag_boards:
        for frame in frames[: params.max_tag_frames]:
            obs = detect_board_pose(frame, calib, tag_params)
            if obs is None:
                continue
            T_WfromI, cov = imu_pose_from_camera(obs.T_WfromC, obs.cov6, T_CfromI)
            P[:6, :6] = cov
            t = (frame.t_ns - t_ref_ns) * 1e-9
            state = ImuState(
                quat_from_rotmat(T_WfromI[:3, :3]),
                T_WfromI[:3, 3].copy(),
                np.zeros(3),
                b_g,
                np.zeros(3),
                t,
            )
            note = (
                f"from AprilTag board '{obs.board}' ({obs.n_tags} tags, {obs.rms_px:.2f} px "
                f"reprojection RMS) in frame {frame.index}"
            )
            return Initialisation(
                FilterState.new(state, P), "apriltag", note, frame.index, g, obs.board
            )
        log.warning("no AprilTag board decoded in the first %d frames", params.max_tag_frames)
    R_WfromI = _gravity_attitude(accel.mean(axis=0), T_CfromI)
    frame = frames[0]
    plane = fit_floor_depth(
        frame.depth_m, calib.color.K, up_in_camera(R_WfromI, T_CfromI), floor_params
    )
    if plane is None:
        raise SessionError(
            f"frame {frame.index}: no AprilTag board and no floor plane in the first frame; "
            "cannot place the camera above the floor"
        )
    p_IinC = T_CfromI[:3, 3]
    p_CinW = np.array([0.0, 0.0, plane.h])  # camera height = plane offset (n·0 + h)
    p_IinW = p_CinW + R_WfromI @ T_CfromI[:3, :3].T @ p_IinC
    world_att = np.diag([params.std_attitude_no_tag_rad**2] * 2 + [params.std_yaw_no_tag_rad**2])
    P[0:3, 0:3] = R_WfromI.T @ world_att @ R_WfromI  # body-frame attitude errors (state.py)
    P[3:6, 3:6] = np.eye(3) * params.std_position_no_tag_m**2
    t = (frame.t_ns - t_ref_ns) * 1e-9
    state = ImuState(quat_from_rotmat(R_WfromI), p_IinW, np.zeros(3), b_g, np.zeros(3), t)
    note = (
        "no AprilTag board seen: roll and pitch from gravity, camera height "
        f"{plane.h:.3f} m from the floor plane, yaw 0 along the camera's view on the floor"
    )
    return Initialisation(FilterState.new(state, P), "gravity_floor", note, frame.index, g)
