"""``session.yaml`` of the session folder v1: schema, parsing and serialisation.

The file is validated with the same typed-config machinery as every other YAML file
(:mod:`gaitnet.config`), so an unknown or mistyped key names the file and the key.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from gaitnet.config import config_to_dict, parse_config
from gaitnet.errors import ConfigError, SessionError
from gaitnet.io.types import (
    SESSION_FORMAT_VERSION,
    AprilTagBoard,
    CameraIntrinsics,
    ImuNoise,
    SessionCalibration,
)

Matrix4 = tuple[tuple[float, ...], ...]


@dataclass(frozen=True)
class IntrinsicsEntry:
    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    distortion: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0)


@dataclass(frozen=True)
class ImuNoiseEntry:
    gyro_noise_density: float
    accel_noise_density: float
    gyro_bias_random_walk: float
    accel_bias_random_walk: float


@dataclass(frozen=True)
class BoardEntry:
    name: str
    family: str
    rows: int
    cols: int
    tag_size_m: float
    gap_m: float
    first_id: int
    T_WfromBoard: Matrix4


@dataclass(frozen=True)
class SessionYaml:
    format_version: int
    color: IntrinsicsEntry
    depth: IntrinsicsEntry
    depth_scale_m: float
    depth_aligned_to_color: bool
    T_CfromI: Matrix4
    device: str = "unknown"
    imu_noise: ImuNoiseEntry | None = None
    apriltag_boards: tuple[BoardEntry, ...] = ()
    extra: dict | None = None


def _matrix4(rows: Matrix4, source: str, key: str) -> np.ndarray:
    T = np.asarray(rows, dtype=np.float64)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise SessionError(f"{source}: key '{key}' must be a finite 4×4 matrix")
    if not np.allclose(T[3], [0, 0, 0, 1]) or not np.allclose(
        T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-5
    ):
        raise SessionError(f"{source}: key '{key}' is not a rigid transform")
    return T


def _intrinsics(entry: IntrinsicsEntry, source: str, key: str) -> CameraIntrinsics:
    if entry.width <= 0 or entry.height <= 0 or entry.fx <= 0 or entry.fy <= 0:
        raise SessionError(f"{source}: key '{key}' has non-positive size or focal length")
    return CameraIntrinsics(**config_to_dict(entry) | {"distortion": tuple(entry.distortion)})


def read_session_yaml(path: Path) -> SessionCalibration:
    """Parse and validate ``session.yaml`` into a :class:`SessionCalibration`."""
    source = str(path)
    if not path.is_file():
        raise SessionError(f"{source}: missing (every session folder needs session.yaml)")
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (yaml.YAMLError, UnicodeDecodeError) as exc:
        raise SessionError(f"{source}: not valid YAML ({exc})".replace("\n", " ")) from exc
    if not isinstance(data, dict):
        raise SessionError(f"{source}: must be a mapping of keys")
    try:
        entry = parse_config(SessionYaml, data, source)
    except ConfigError as exc:
        raise SessionError(str(exc)) from exc
    if entry.format_version != SESSION_FORMAT_VERSION:
        raise SessionError(
            f"{source}: format_version {entry.format_version} is not supported "
            f"(this gaitnet reads version {SESSION_FORMAT_VERSION})"
        )
    if entry.depth_scale_m <= 0:
        raise SessionError(f"{source}: key 'depth_scale_m' must be positive")
    boards = tuple(
        AprilTagBoard(
            name=b.name,
            family=b.family,
            rows=b.rows,
            cols=b.cols,
            tag_size_m=b.tag_size_m,
            gap_m=b.gap_m,
            first_id=b.first_id,
            T_WfromBoard=_matrix4(b.T_WfromBoard, source, f"apriltag_boards[{i}].T_WfromBoard"),
        )
        for i, b in enumerate(entry.apriltag_boards)
    )
    noise = ImuNoise(**config_to_dict(entry.imu_noise)) if entry.imu_noise else None
    return SessionCalibration(
        color=_intrinsics(entry.color, source, "color"),
        depth=_intrinsics(entry.depth, source, "depth"),
        depth_scale_m=entry.depth_scale_m,
        depth_aligned_to_color=entry.depth_aligned_to_color,
        T_CfromI=_matrix4(entry.T_CfromI, source, "T_CfromI"),
        imu_noise=noise,
        apriltag_boards=boards,
        device=entry.device,
        extra=dict(entry.extra or {}),
    )


def _intrinsics_dict(cam: CameraIntrinsics) -> dict:
    return {
        "width": int(cam.width),
        "height": int(cam.height),
        "fx": float(cam.fx),
        "fy": float(cam.fy),
        "cx": float(cam.cx),
        "cy": float(cam.cy),
        "distortion": [float(d) for d in cam.distortion],
    }


def _matrix_list(T: np.ndarray) -> list[list[float]]:
    return [[float(v) for v in row] for row in np.asarray(T, dtype=np.float64)]


def session_yaml_text(calib: SessionCalibration) -> str:
    """Serialise a calibration to the text of ``session.yaml`` (deterministic)."""
    data: dict = {
        "format_version": SESSION_FORMAT_VERSION,
        "device": calib.device,
        "color": _intrinsics_dict(calib.color),
        "depth": _intrinsics_dict(calib.depth),
        "depth_scale_m": float(calib.depth_scale_m),
        "depth_aligned_to_color": bool(calib.depth_aligned_to_color),
        "T_CfromI": _matrix_list(calib.T_CfromI),
        "imu_noise": None,
        "apriltag_boards": [],
    }
    if calib.imu_noise is not None:
        n = calib.imu_noise
        data["imu_noise"] = {
            "gyro_noise_density": float(n.gyro_noise_density),
            "accel_noise_density": float(n.accel_noise_density),
            "gyro_bias_random_walk": float(n.gyro_bias_random_walk),
            "accel_bias_random_walk": float(n.accel_bias_random_walk),
        }
    for b in calib.apriltag_boards:
        data["apriltag_boards"].append(
            {
                "name": b.name,
                "family": b.family,
                "rows": int(b.rows),
                "cols": int(b.cols),
                "tag_size_m": float(b.tag_size_m),
                "gap_m": float(b.gap_m),
                "first_id": int(b.first_id),
                "T_WfromBoard": _matrix_list(b.T_WfromBoard),
            }
        )
    if calib.extra:
        data["extra"] = calib.extra
    header = "# gaitnet recorded session, folder format v1 (see docs/session-format.md)\n"
    return header + yaml.safe_dump(data, sort_keys=False, default_flow_style=None)
