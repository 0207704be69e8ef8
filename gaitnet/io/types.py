"""Plain data types shared by every session source (folder, RealSense bag, simulator).

A *session* is what one recording holds: calibration, a list of RGB-D frames and the IMU
stream. Frames load lazily: a source lists its frame timestamps up front and decodes a frame
only when asked (:meth:`SessionSource.frame`).

Frames of reference are named in variable names: ``T_CfromI`` maps points in the IMU frame to
the camera frame (``p_C = R_CfromI @ p_I + t_CfromI``). The camera frame is OpenCV's (x right,
y down, z forward).

The calibration types (:class:`CameraIntrinsics`, :class:`ImuNoise`, :class:`AprilTagBoard`,
:class:`SessionCalibration`) are also the schema of ``session.yaml``: the file is parsed into
them with :func:`gaitnet.config.parse_config` and written from them with
:func:`gaitnet.config.config_to_dict` (:mod:`gaitnet.io.session_yaml`). Each type checks its
values in ``__post_init__`` (ranges, finiteness, rigid transforms) and raises ``ValueError``;
every reader turns that into a :class:`~gaitnet.errors.SessionError` naming its file and key,
so one set of checks guards session folders, bags and the simulator alike. Fields are
normalised to plain Python numbers and float64 arrays, so a calibration built from numpy
values serialises to the same text as one built from literals.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from gaitnet.checks import check_int_range, check_positive, check_range
from gaitnet.errors import SessionError

SESSION_FORMAT_VERSION = 1
T_NS_MAX = 2**63 - 1
"""Largest timestamp [ns] a session can hold (int64); timestamps are never negative."""
RIGID_TOLERANCE = 1e-5
"""Largest deviation of ``R Rᵀ`` from the identity accepted in a rigid transform."""
APRILTAG_FAMILIES = ("tag36h11",)
"""The AprilTag families the filter decodes (``gaitnet.vio.tag_detectors``); a board of another
family is refused where the calibration is read, not when the filter meets it."""


def _set(obj: Any, name: str, value: Any) -> None:
    object.__setattr__(obj, name, value)


def rigid_transform(T: Any, name: str) -> np.ndarray:
    """``T`` as a float64 4×4 array; ``ValueError`` unless finite, rigid and proper.

    Rigid: bottom row ``[0, 0, 0, 1]``, ``R Rᵀ = I`` within :data:`RIGID_TOLERANCE` and
    ``det R > 0`` (no reflection).
    """
    try:
        M = np.array(T, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"{name} must be a 4×4 matrix of numbers") from None
    if M.shape != (4, 4):
        raise ValueError(f"{name} must be a 4×4 matrix, got shape {M.shape}")
    if not np.isfinite(M).all():
        raise ValueError(f"{name} must be finite (has NaN or infinity)")
    R = M[:3, :3]
    if (
        not np.allclose(M[3], [0.0, 0.0, 0.0, 1.0], atol=RIGID_TOLERANCE)
        or not np.allclose(R @ R.T, np.eye(3), atol=RIGID_TOLERANCE)
        or np.linalg.det(R) <= 0
    ):
        raise ValueError(f"{name} is not a rigid transform (rotation and translation)")
    M[3] = [0.0, 0.0, 0.0, 1.0]
    return M


def plain_data(value: Any, name: str = "extra") -> Any:
    """A copy of ``value`` made of YAML-safe plain data: dict (str keys), list, str, bool, int,
    finite float, None. Tuples become lists, numpy scalars Python numbers; anything else (or a
    non-finite float) is a ``ValueError`` naming the key."""
    if value is None or isinstance(value, (str, bool)):
        return value
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, numbers.Integral):
        return int(value)
    if isinstance(value, numbers.Real):
        return check_range(name, value)
    if isinstance(value, Mapping):
        out = {}
        for key, item in value.items():
            if not isinstance(key, str):
                raise ValueError(f"{name} keys must be strings, got {key!r}")
            out[key] = plain_data(item, f"{name}.{key}")
        return out
    if isinstance(value, (list, tuple)):
        return [plain_data(item, f"{name}[{i}]") for i, item in enumerate(value)]
    if isinstance(value, np.ndarray):
        return plain_data(value.tolist(), name)
    raise ValueError(
        f"{name} must be plain data (numbers, strings, lists, mappings), got {type(value).__name__}"
    )


@dataclass(frozen=True)
class CameraIntrinsics:
    """Pinhole intrinsics of one image stream (pixels).

    ``distortion`` holds OpenCV-ordered coefficients ``(k1, k2, p1, p2, k3)``; the D455's
    colour stream reports an (inverse) Brown-Conrady model whose coefficients are near zero and
    the pipeline treats images as undistorted pinhole images.

    Checked: ``width``, ``height`` positive integers; ``fx``, ``fy`` positive and finite;
    ``cx``, ``cy`` and at most 14 distortion coefficients finite.
    """

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    distortion: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        _set(self, "width", check_int_range("width", self.width, 1))
        _set(self, "height", check_int_range("height", self.height, 1))
        for name in ("fx", "fy"):
            _set(self, name, check_positive(name, getattr(self, name)))
        for name in ("cx", "cy"):
            _set(self, name, check_range(name, getattr(self, name)))
        if isinstance(self.distortion, (str, bytes)) or not hasattr(self.distortion, "__len__"):
            raise ValueError(f"distortion must be a list of numbers, got {self.distortion!r}")
        if len(self.distortion) > 14:
            raise ValueError(f"distortion has {len(self.distortion)} coefficients (at most 14)")
        _set(
            self,
            "distortion",
            tuple(check_range(f"distortion[{i}]", d) for i, d in enumerate(self.distortion)),
        )

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
    A discrete per-sample variance at rate f is ``density² · f``. Checked: finite, ≥ 0.
    """

    gyro_noise_density: float
    accel_noise_density: float
    gyro_bias_random_walk: float
    accel_bias_random_walk: float

    def __post_init__(self) -> None:
        for name in (
            "gyro_noise_density",
            "accel_noise_density",
            "gyro_bias_random_walk",
            "accel_bias_random_walk",
        ):
            _set(self, name, check_range(name, getattr(self, name), 0.0))


@dataclass(frozen=True)
class AprilTagBoard:
    """A printed sheet of AprilTags lying on the floor at a known pose.

    ``T_WfromBoard`` (4×4) places the board frame in the world; tag ``first_id + r * cols + c``
    has its centre at ``(s/2 + c * spacing, s/2 + r * spacing, 0)`` in the board frame, where
    ``s = tag_size_m`` and ``spacing = tag_size_m + gap_m``.

    Corner convention (:func:`tag_corners_in_board`): the board frame has z out of the paper
    (up when the sheet lies face up on the floor) and each tag reads correctly when seen from
    +z with board +x to the right and board +y up; corners are in OpenCV's aruco order
    (top-left, top-right, bottom-right, bottom-left of the marker as read), i.e. the classic
    ArUco marker frame ``(-s/2, +s/2), (+s/2, +s/2), (+s/2, -s/2), (-s/2, -s/2)`` shifted to
    the tag centre. A sheet lying face up on the floor therefore has ``T_WfromBoard`` = a
    rotation about world z and z = 0.

    Checked: ``family`` one of :data:`APRILTAG_FAMILIES`; ``rows``, ``cols`` ≥ 1;
    ``tag_size_m`` positive and finite; ``gap_m`` finite, ≥ 0; ``first_id`` ≥ 0;
    ``T_WfromBoard`` a finite rigid transform.
    """

    name: str
    family: str
    rows: int
    cols: int
    tag_size_m: float
    gap_m: float
    first_id: int
    T_WfromBoard: np.ndarray

    def __post_init__(self) -> None:
        for name in ("name", "family"):
            if not isinstance(getattr(self, name), str) or not getattr(self, name):
                raise ValueError(f"{name} must be a non-empty string, got {getattr(self, name)!r}")
        if self.family not in APRILTAG_FAMILIES:
            raise ValueError(
                f"family {self.family!r} cannot be decoded (supported: "
                f"{', '.join(APRILTAG_FAMILIES)})"
            )
        _set(self, "rows", check_int_range("rows", self.rows, 1))
        _set(self, "cols", check_int_range("cols", self.cols, 1))
        _set(self, "tag_size_m", check_positive("tag_size_m", self.tag_size_m))
        _set(self, "gap_m", check_range("gap_m", self.gap_m, 0.0))
        _set(self, "first_id", check_int_range("first_id", self.first_id, 0))
        _set(self, "T_WfromBoard", rigid_transform(self.T_WfromBoard, "T_WfromBoard"))

    @property
    def tag_ids(self) -> range:
        """The ids of the tags on this board."""
        return range(self.first_id, self.first_id + self.rows * self.cols)

    def tag_centre_in_board(self, tag_id: int) -> np.ndarray:
        """Centre of tag ``tag_id`` in the board frame (z = 0)."""
        k = tag_id - self.first_id
        if not 0 <= k < self.rows * self.cols:
            raise KeyError(f"tag id {tag_id} is not on board {self.name!r}")
        r, c = divmod(k, self.cols)
        spacing = self.tag_size_m + self.gap_m
        half = self.tag_size_m / 2.0
        return np.array([half + c * spacing, half + r * spacing, 0.0])


def tag_corners_in_board(board: AprilTagBoard, tag_id: int) -> np.ndarray:
    """(4, 3) corners of tag ``tag_id`` in the board frame, OpenCV aruco order.

    See :class:`AprilTagBoard` for the convention. ``KeyError`` if the tag is not on the board.
    """
    c = board.tag_centre_in_board(tag_id)
    h = board.tag_size_m / 2.0
    return c + np.array([[-h, h, 0.0], [h, h, 0.0], [h, -h, 0.0], [-h, -h, 0.0]])


@dataclass(frozen=True)
class SessionCalibration:
    """Everything ``session.yaml`` states about the sensors of one recording.

    Checked: ``color`` and ``depth`` are :class:`CameraIntrinsics`; ``depth_scale_m`` positive
    and finite; ``T_CfromI`` a finite rigid transform; boards have distinct names and disjoint
    tag ids; ``extra`` is YAML-safe plain data with finite numbers.
    """

    color: CameraIntrinsics
    depth: CameraIntrinsics
    depth_scale_m: float
    depth_aligned_to_color: bool
    T_CfromI: np.ndarray
    imu_noise: ImuNoise | None = None
    apriltag_boards: tuple[AprilTagBoard, ...] = ()
    device: str = "unknown"
    extra: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        for name in ("color", "depth"):
            if not isinstance(getattr(self, name), CameraIntrinsics):
                raise ValueError(f"{name} must be CameraIntrinsics, got {getattr(self, name)!r}")
        _set(self, "depth_scale_m", check_positive("depth_scale_m", self.depth_scale_m))
        if not isinstance(self.depth_aligned_to_color, (bool, np.bool_)):
            raise ValueError("depth_aligned_to_color must be true or false")
        _set(self, "depth_aligned_to_color", bool(self.depth_aligned_to_color))
        _set(self, "T_CfromI", rigid_transform(self.T_CfromI, "T_CfromI"))
        if self.imu_noise is not None and not isinstance(self.imu_noise, ImuNoise):
            raise ValueError(f"imu_noise must be ImuNoise or None, got {self.imu_noise!r}")
        boards = tuple(self.apriltag_boards)
        if not all(isinstance(b, AprilTagBoard) for b in boards):
            raise ValueError("apriltag_boards must be AprilTagBoard entries")
        for i, a in enumerate(boards):
            for b in boards[:i]:
                if a.name == b.name:
                    raise ValueError(f"two AprilTag boards are named {a.name!r}")
                if a.family == b.family and set(a.tag_ids) & set(b.tag_ids):
                    raise ValueError(f"AprilTag boards {b.name!r} and {a.name!r} share tag ids")
        _set(self, "apriltag_boards", boards)
        if not isinstance(self.device, str):
            raise ValueError(f"device must be a string, got {self.device!r}")
        if not isinstance(self.extra, Mapping):
            raise ValueError(f"extra must be a mapping, got {self.extra!r}")
        _set(self, "extra", plain_data(self.extra))


@dataclass(frozen=True)
class Frame:
    """One RGB-D frame. ``depth_m`` is float32 metres aligned to colour, 0 where invalid."""

    index: int
    t_ns: int
    rgb: np.ndarray
    depth_m: np.ndarray


IMU_ACCEL_LIMIT_MS2 = 16 * 9.80665
"""Largest possible specific force [m/s²]: ±16 g, the widest range of MEMS IMUs such as the
D455's (BMI055: ±2 … ±16 g). A larger value is a damaged sample, not a measurement."""
IMU_GYRO_LIMIT_RADS = math.radians(2000.0)
"""Largest possible angular rate [rad/s]: ±2000 °/s, the widest range of the same IMUs."""


def implausible_imu(accel: np.ndarray, gyro: np.ndarray) -> np.ndarray:
    """Rows where ``accel`` (N, 3) or ``gyro`` (N, 3) exceed :data:`IMU_ACCEL_LIMIT_MS2` /
    :data:`IMU_GYRO_LIMIT_RADS` on any axis (boolean (N,)); NaN rows are not flagged here."""
    with np.errstate(invalid="ignore"):
        return (np.abs(accel) > IMU_ACCEL_LIMIT_MS2).any(axis=1) | (
            np.abs(gyro) > IMU_GYRO_LIMIT_RADS
        ).any(axis=1)


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


def require_depth_aligned(source: SessionSource, needed_by: str) -> None:
    """Refuse a session whose ``session.yaml`` says ``depth_aligned_to_color: false``:
    ``needed_by`` (e.g. "the filter", "the segmenter") reads a frame's depth at its colour
    pixels. The one check every consumer of depth uses; the message names the session's
    ``session.yaml`` (a folder's; a bag's file), a :class:`~gaitnet.errors.SessionError`."""
    if source.calibration.depth_aligned_to_color:
        return
    root = getattr(source, "root", None)
    where = root / "session.yaml" if root is not None else getattr(source, "path", "session")
    raise SessionError(
        f"{where}: depth_aligned_to_color is false, but {needed_by} needs depth aligned to "
        "colour (align the depth frames to the colour camera and set it to true)"
    )
