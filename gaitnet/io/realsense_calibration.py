"""The calibration of a RealSense SDK ``.bag``: intrinsics, extrinsics, depth units, IMU noise.

:func:`read_statics` reads the few static messages of the four streams found by
:func:`gaitnet.io.realsense_streams.find_streams` (``/file_version``, the device info, each
stream's ``info``, ``info/camera_info``, ``imu_intrinsic`` and ``tf/<group>``, the "Depth
Units" option); :func:`build_calibration` turns them into a :class:`SessionCalibration`.

Intrinsics
    From ``info/camera_info`` (``K``, ``D``; no distortion coefficients mean five zeros). The
    colour stream's are required. Depth is aligned to colour already when its camera_info has
    colour's size and camera matrix; without a depth camera_info it is assumed aligned (a
    warning; the first frame's size is checked when the bag is opened); otherwise it is
    re-projected by the reader, which needs the depth→colour extrinsic.

Delivered calibration
    Depth is always delivered aligned to colour, so the calibration describes the delivered
    data: ``depth`` intrinsics are the colour intrinsics and ``depth_aligned_to_color`` is True;
    the bag's own depth intrinsics are in ``extra["bag_depth_intrinsics"]``. ``extra`` also
    holds ``source`` (``realsense_bag``), ``bag``, ``file_version`` (None without
    ``/file_version``), ``device_info``, ``depth_aligned_in_bag``, ``T_CfromD``,
    ``tf_convention``, the four data ``topics`` and, when the bag has metadata,
    ``timestamp_domain`` (:mod:`gaitnet.io.realsense_streams`). ``device`` is the device
    info's ``Name`` (``unknown`` without it).

Extrinsics
    Each stream's ``tf/<group>`` is read as documented in :mod:`gaitnet.io.realsense_extrinsics`
    (direction convention ``tf_convention``); two streams compose through the first group both
    have. A depth stream without a tf is the reference stream (identity in every group of the
    colour stream's). ``T_CfromI`` is the gyro stream's extrinsic (the accelerometer's if the
    gyro has no tf; a warning if both exist and differ), unless one is passed in. A tf with
    NaN or a non-rigid transform is refused.

Depth units
    The "Depth Units" option (metres per depth count) of the depth stream's sensor, else of any
    sensor of that device; default :data:`DEFAULT_DEPTH_UNITS_M` with an info message. The
    value's float32 storage is undone (0.0010000000474974513 → 0.001); a value that changes
    during the recording is logged as a warning and the first used; a non-positive or
    non-finite value is refused.

IMU noise
    From the accelerometer and gyro ``imu_intrinsic`` and the streams' rates
    (:func:`gaitnet.io.realsense_extrinsics.imu_noise_from_intrinsics`); ``imu_noise`` is None
    (an info message) when the bag has no such calibration.

Errors (missing colour intrinsics, invalid camera_info, a bad tf, invalid depth units, depth
that cannot be aligned, no IMU→colour extrinsic, non-finite calibration values) raise
:class:`SessionError` with a one-line message that names the bag file.
"""

from __future__ import annotations

import logging
import math
import re
from dataclasses import dataclass
from typing import Any

import numpy as np

from gaitnet.errors import SessionError
from gaitnet.io.bag_index import RosBag
from gaitnet.io.realsense_extrinsics import (
    imu_noise_from_intrinsics,
    relative_extrinsic,
    transform_to_matrix,
)
from gaitnet.io.realsense_streams import BagStreams, Stream, stream_fps
from gaitnet.io.types import CameraIntrinsics, SessionCalibration, rigid_transform

__all__ = [
    "DEFAULT_DEPTH_UNITS_M",
    "BagCalibration",
    "BagStatics",
    "build_calibration",
    "read_statics",
]

log = logging.getLogger(__name__)

DEFAULT_DEPTH_UNITS_M = 0.001
"""Metres per depth count when the bag has no "Depth Units" option."""


@dataclass
class BagStatics:
    """The static messages of a bag; the per-stream dicts are keyed by stream kind.

    ``camera_info``, ``imu_intrinsic`` and ``stream_info`` hold each stream's first message of
    that topic (None when absent); ``tf`` maps each stream's tf groups to validated rigid 4×4
    matrices (as stored; direction per the tf convention).
    """

    file_version: int | None
    device_info: dict[str, str]
    camera_info: dict[str, Any]
    imu_intrinsic: dict[str, Any]
    stream_info: dict[str, Any]
    tf: dict[str, dict[str, np.ndarray]]
    depth_units_m: float


@dataclass(frozen=True)
class BagCalibration:
    """:func:`build_calibration`'s result: the session's calibration and how to align depth.

    ``bag_depth`` are the bag's own depth intrinsics, ``depth_aligned`` says whether the bag's
    depth is aligned to colour already, ``T_CfromD`` is the depth→colour extrinsic (identity
    when the bag has none, which is only allowed for aligned depth).
    """

    session: SessionCalibration
    bag_depth: CameraIntrinsics
    depth_aligned: bool
    T_CfromD: np.ndarray


def _nominal_float32(value: float) -> float:
    """Undo float32 storage of a decimal option value (0.0010000000474974513 -> 0.001)."""
    return float(f"{float(np.float32(value)):.7g}")


def read_statics(bag: RosBag, streams: BagStreams) -> BagStatics:
    """The static messages of ``streams`` (module docstring); refuses a bad tf or depth units."""
    versions = bag.decode_all("/file_version")
    file_version = int(versions[0].data) if versions else None
    if not versions:
        log.debug("%s: no /file_version (bag not written by the RealSense SDK?)", bag.src)

    info: dict[str, str] = {}
    for msg in bag.decode_all(f"/device_{streams.color.device}/info"):
        key, value = getattr(msg, "key", None), getattr(msg, "value", None)
        if isinstance(key, str) and isinstance(value, str):
            info.setdefault(key, value)

    statics = BagStatics(file_version, info, {}, {}, {}, {}, DEFAULT_DEPTH_UNITS_M)
    for s in streams.all:
        cams = bag.decode_all(f"{s.prefix}/info/camera_info")
        statics.camera_info[s.kind] = cams[0] if cams else None
        imu_intr = bag.decode_all(f"{s.prefix}/imu_intrinsic")
        statics.imu_intrinsic[s.kind] = imu_intr[0] if imu_intr else None
        stream_info = bag.decode_all(f"{s.prefix}/info")
        statics.stream_info[s.kind] = stream_info[0] if stream_info else None
        tfs: dict[str, np.ndarray] = {}
        tf_pattern = re.compile(re.escape(s.prefix) + r"/tf/([^/]+)$")
        for topic in sorted(bag.topics):
            m = tf_pattern.match(topic)
            if not m:
                continue
            msgs = bag.decode_all(topic)
            if msgs:
                try:
                    tfs[m.group(1)] = rigid_transform(transform_to_matrix(msgs[0]), "tf")
                except (ValueError, AttributeError, TypeError) as exc:
                    raise SessionError(f"{bag.src}: bad extrinsic on {topic} ({exc})") from None
        statics.tf[s.kind] = tfs

    statics.depth_units_m = _depth_units(bag, streams.depth)
    return statics


def _depth_units(bag: RosBag, depth: Stream) -> float:
    name = "Depth Units"
    d, s = depth.device, depth.sensor
    topics = [f"/device_{d}/sensor_{s}/option/{name}/value"]
    pattern = re.compile(rf"^/device_{d}/sensor_\d+/option/{re.escape(name)}/value$")
    topics += sorted(t for t in bag.topics if pattern.match(t) and t not in topics)
    for topic in topics:
        values = [float(m.data) for m in bag.decode_all(topic)]
        if not values:
            continue
        value = values[0]
        if not math.isfinite(value) or value <= 0:
            raise SessionError(f"{bag.src}: invalid depth units {value!r} on {topic}")
        if any(v != value for v in values[1:]):
            log.warning(
                "%s: depth units change during the recording (%s), using the first",
                bag.src,
                sorted(set(values)),
            )
        return _nominal_float32(value)
    log.info("%s: no '%s' option, assuming %g m", bag.src, name, DEFAULT_DEPTH_UNITS_M)
    return DEFAULT_DEPTH_UNITS_M


def _intrinsics(msg: Any, topic: str, src: str) -> CameraIntrinsics:
    try:
        K = np.asarray(msg.K if hasattr(msg, "K") else msg.k, dtype=np.float64).ravel()
        D = np.asarray(msg.D if hasattr(msg, "D") else msg.d, dtype=np.float64).ravel()
        if K.shape != (9,):
            raise ValueError(f"camera matrix has {K.size} values, expected 9")
        return CameraIntrinsics(
            width=int(msg.width),
            height=int(msg.height),
            fx=float(K[0]),
            fy=float(K[4]),
            cx=float(K[2]),
            cy=float(K[5]),
            distortion=tuple(float(d) for d in D) if D.size else (0.0,) * 5,
        )
    except ValueError as exc:
        raise SessionError(f"{src}: invalid camera_info on {topic}: {exc}") from None


def _extrinsic(
    tf: dict[str, dict[str, np.ndarray]], target: Stream, source: Stream, convention: str
) -> np.ndarray | None:
    """``T_{target from source}`` from the two streams' tf, or None if not composable."""
    tf_t, tf_s = tf[target.kind], tf[source.kind]
    common = sorted(set(tf_t) & set(tf_s))
    if common:
        return relative_extrinsic(tf_t[common[0]], tf_s[common[0]], convention)
    return None


def build_calibration(
    bag: RosBag,
    streams: BagStreams,
    statics: BagStatics,
    tf_convention: str,
    T_CfromI_override: np.ndarray | None,
    domain: str | None,
) -> BagCalibration:
    """The session calibration of a bag (module docstring).

    ``T_CfromI_override`` (a validated rigid 4×4) replaces the bag's IMU→colour extrinsic;
    ``domain`` (from :func:`gaitnet.io.realsense_streams.timestamp_domain`) goes into
    ``extra``. :class:`SessionError` naming the bag when the calibration is missing or invalid.
    """
    src = bag.src
    color_s, depth_s, accel_s, gyro_s = streams.all
    color_topic = f"{color_s.prefix}/info/camera_info"
    depth_topic = f"{depth_s.prefix}/info/camera_info"
    if statics.camera_info["Color"] is None:
        raise SessionError(f"{src}: no colour intrinsics ({color_topic} is missing)")
    color = _intrinsics(statics.camera_info["Color"], color_topic, src)

    tf = dict(statics.tf)
    if not tf["Depth"]:
        # The depth stream is the reference ("pin") stream of D400 devices.
        tf["Depth"] = {g: np.eye(4) for g in tf["Color"]}

    depth_msg = statics.camera_info["Depth"]
    if depth_msg is not None:
        depth = _intrinsics(depth_msg, depth_topic, src)
        same_size = (depth.width, depth.height) == (color.width, color.height)
        same_k = np.allclose(
            [depth.fx, depth.fy, depth.cx, depth.cy],
            [color.fx, color.fy, color.cx, color.cy],
            rtol=1e-6,
            atol=1e-6,
        )
        aligned = same_size and same_k
    else:
        depth = None
        aligned = False
    T_CfromD = _extrinsic(tf, color_s, depth_s, tf_convention)
    if depth is None:
        # Without depth intrinsics only an already aligned image is usable; the frame check
        # at open confirms the size.
        log.warning("%s: no depth camera_info, assuming depth is aligned to colour", src)
        depth, aligned = color, True
    if not aligned and T_CfromD is None:
        raise SessionError(
            f"{src}: depth is not aligned to colour and the bag has no depth→colour "
            f"extrinsic (tf topics under {color_s.prefix} and {depth_s.prefix})"
        )
    T_CfromD = T_CfromD if T_CfromD is not None else np.eye(4)

    if T_CfromI_override is not None:
        T_CfromI = T_CfromI_override
    else:
        imu_stream = gyro_s if tf["Gyro"] else accel_s
        T_CfromI = _extrinsic(tf, color_s, imu_stream, tf_convention)
        if T_CfromI is None:
            raise SessionError(
                f"{src}: no IMU→colour extrinsic (tf of {color_s.prefix} and of "
                f"{gyro_s.prefix} or {accel_s.prefix} in one group); pass T_CfromI"
            )
        if tf["Gyro"] and tf["Accel"]:
            T_alt = _extrinsic(tf, color_s, accel_s, tf_convention)
            if T_alt is not None and not np.allclose(T_alt, T_CfromI, atol=1e-6):
                log.warning("%s: accelerometer and gyro extrinsics differ; using the gyro's", src)

    fps_acc = stream_fps(bag, accel_s, statics.stream_info["Accel"])
    fps_gyr = stream_fps(bag, gyro_s, statics.stream_info["Gyro"])
    noise = imu_noise_from_intrinsics(
        statics.imu_intrinsic["Accel"], statics.imu_intrinsic["Gyro"], fps_acc, fps_gyr
    )
    if noise is None:
        log.info("%s: no IMU noise variances in imu_intrinsic, imu_noise = None", src)

    info = statics.device_info
    extra: dict[str, Any] = {
        "source": "realsense_bag",
        "bag": src,
        "file_version": statics.file_version,
        "device_info": dict(info),
        "depth_aligned_in_bag": bool(aligned),
        "bag_depth_intrinsics": {
            "width": depth.width,
            "height": depth.height,
            "fx": depth.fx,
            "fy": depth.fy,
            "cx": depth.cx,
            "cy": depth.cy,
            "distortion": list(depth.distortion),
        },
        "T_CfromD": T_CfromD.tolist(),
        "tf_convention": tf_convention,
        "topics": {
            "color": color_s.data_topic,
            "depth": depth_s.data_topic,
            "accel": accel_s.data_topic,
            "gyro": gyro_s.data_topic,
        },
    }
    if domain is not None:
        extra["timestamp_domain"] = domain
    try:
        session = SessionCalibration(
            color=color,
            depth=color,
            depth_scale_m=statics.depth_units_m,
            depth_aligned_to_color=True,
            T_CfromI=T_CfromI,
            imu_noise=noise,
            device=info.get("Name", "unknown"),
            extra=extra,
        )
    except ValueError as exc:
        raise SessionError(f"{src}: invalid calibration: {exc}") from None
    return BagCalibration(session, depth, bool(aligned), T_CfromD)
