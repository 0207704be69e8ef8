"""Read a RealSense SDK / Viewer recording (ROS1 ``.bag``) as a :class:`SessionSource`.

Topic layout written by librealsense (``src/media/ros/ros_file_format.h``); streams are found
by pattern, not by sensor number (a D455 has depth on ``sensor_0``, colour on ``sensor_1`` and
the IMU on ``sensor_2``)::

    /file_version                                      std_msgs/UInt32 (absent in bags
                                                       re-recorded with ROS tools: tolerated)
    /device_<d>/info                                   diagnostic_msgs/KeyValue (Name, serial …)
    /device_<d>/sensor_<s>/<Stream>_<i>/image/data     sensor_msgs/Image     (Depth, Color)
    /device_<d>/sensor_<s>/<Stream>_<i>/imu/data       sensor_msgs/Imu       (Accel, Gyro)
    /device_<d>/sensor_<s>/<Stream>_<i>/info           realsense_msgs/StreamInfo (fps, …)
    /device_<d>/sensor_<s>/<Stream>_<i>/info/camera_info  sensor_msgs/CameraInfo
    /device_<d>/sensor_<s>/<Stream>_<i>/imu_intrinsic  realsense_msgs/ImuIntrinsic
    /device_<d>/sensor_<s>/<Stream>_<i>/tf/<group>     geometry_msgs/Transform (extrinsic)
    /device_<d>/sensor_<s>/option/<Option Name>/value  std_msgs/Float32 (e.g. "Depth Units")

Messages are deserialized with ``rosbags``; every message type is registered from the bag's own
message definitions (``connection.msgdef``), so the SDK's ``realsense_msgs/*`` types work.

Timestamps
    A frame's ``t_ns`` is the colour image's ``header.stamp`` (the SDK writes the device frame
    timestamp there; the bag's own record time is the host capture time since the recording
    started and is not used). IMU samples use their ``header.stamp`` too.

Laziness
    Opening reads the bag index (via ``rosbags``), the few static messages (calibration,
    options), and the first 12 bytes of every image message's payload (its header stamp; for
    uncompressed chunks these are small positioned reads, compressed chunks are decompressed
    once each). :meth:`RealSenseBag.frame` reads and decodes just the two messages of that
    frame by their byte position (no scan of the bag). The IMU is read on first access to
    :attr:`RealSenseBag.imu`.

Frames
    Colour and depth frames are paired by nearest header stamp; pairs further apart than half
    the colour frame period are dropped with a warning. ``rgb`` is uint8 RGB (``rgb8``,
    ``bgr8``, ``rgba8``, ``bgra8`` accepted); ``depth_m`` is float32 metres (``mono16`` /
    ``16UC1`` times the "Depth Units" option, default 0.001 m; ``32FC1`` is taken as metres),
    0 = invalid, always aligned to colour: a depth image of colour's size whose camera_info
    equals colour's is taken as aligned already, otherwise it is aligned here with
    :func:`align_depth_to_color`. The calibration therefore describes the delivered data:
    ``depth`` intrinsics are the colour intrinsics and ``depth_aligned_to_color`` is True; the
    bag's own depth intrinsics are in ``extra["bag_depth_intrinsics"]``.

Extrinsics and IMU noise
    How the SDK's ``tf`` extrinsics are read (``tf_convention``: :data:`TF_REF_TO_STREAM` or
    :data:`TF_STREAM_TO_REF`) and how ``imu_intrinsic`` variances become
    :class:`~gaitnet.io.types.ImuNoise` is documented in :mod:`gaitnet.io.realsense_extrinsics`.

Module layout: low-level bag reads are in :mod:`gaitnet.io.bag_index`, depth re-projection in
:mod:`gaitnet.io.depth_align`; their public names are re-exported here.

Errors (a missing colour, depth or IMU topic, an empty bag, a file that is not a bag or is
truncated, an unsupported image encoding, damaged records) raise :class:`SessionError` with a
one-line message that names the bag file.
"""

from __future__ import annotations

import logging
import math
import re
import struct
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gaitnet.errors import SessionError
from gaitnet.io.bag_index import (
    _DamagedError,
    _Entry,
    _parse_imu,
    _Records,
    _stamp_ns,
    _Types,
)
from gaitnet.io.depth_align import align_depth_to_color
from gaitnet.io.imu_merge import merge_imu_streams
from gaitnet.io.realsense_extrinsics import (
    TF_REF_TO_STREAM,
    TF_STREAM_TO_REF,
    imu_noise_from_intrinsics,
    invert_rigid,
    quaternion_to_matrix,
    relative_extrinsic,
    transform_to_matrix,
)
from gaitnet.io.types import (
    CameraIntrinsics,
    Frame,
    ImuNoise,
    ImuSamples,
    SessionCalibration,
)

__all__ = [
    "DEFAULT_DEPTH_UNITS_M",
    "TF_REF_TO_STREAM",
    "TF_STREAM_TO_REF",
    "RealSenseBag",
    "align_depth_to_color",
    "invert_rigid",
    "quaternion_to_matrix",
    "relative_extrinsic",
    "transform_to_matrix",
]

log = logging.getLogger(__name__)

DEFAULT_DEPTH_UNITS_M = 0.001

_DATA_TOPIC = re.compile(
    r"^/device_(\d+)/sensor_(\d+)/(Depth|Color|Accel|Gyro)_(\d+)/(image|imu)/data$"
)
_KIND_TO_MEDIUM = {"Depth": "image", "Color": "image", "Accel": "imu", "Gyro": "imu"}
_KIND_NAME = {
    "Color": "colour image",
    "Depth": "depth image",
    "Accel": "accelerometer",
    "Gyro": "gyroscope",
}

_COLOR_ENCODINGS = {  # encoding -> (channels, indices of R, G, B)
    "rgb8": (3, (0, 1, 2)),
    "bgr8": (3, (2, 1, 0)),
    "rgba8": (4, (0, 1, 2)),
    "bgra8": (4, (2, 1, 0)),
}
_DEPTH_ENCODINGS = {"mono16": "u2", "16uc1": "u2", "32fc1": "f4"}


@dataclass(frozen=True)
class _Stream:
    kind: str
    device: int
    sensor: int
    index: int

    @property
    def prefix(self) -> str:
        return f"/device_{self.device}/sensor_{self.sensor}/{self.kind}_{self.index}"

    @property
    def data_topic(self) -> str:
        return f"{self.prefix}/{_KIND_TO_MEDIUM[self.kind]}/data"


def _intrinsics_dict(c: CameraIntrinsics) -> dict:
    return {
        "width": int(c.width),
        "height": int(c.height),
        "fx": float(c.fx),
        "fy": float(c.fy),
        "cx": float(c.cx),
        "cy": float(c.cy),
        "distortion": [float(d) for d in c.distortion],
    }


def _nominal_float32(value: float) -> float:
    """Undo float32 storage of a decimal option value (0.0010000000474974513 -> 0.001)."""
    return float(f"{float(np.float32(value)):.7g}")


# --------------------------------------------------------------------------------------------
# The reader
# --------------------------------------------------------------------------------------------


class RealSenseBag:
    """A RealSense SDK/Viewer ``.bag`` recording (implements :class:`SessionSource`).

    Args:
        path: the ``.bag`` file.
        imu_gap_warn_s: IMU gaps longer than this are logged as warnings.
        tf_convention: how to read the SDK's ``tf`` extrinsics
            (:mod:`gaitnet.io.realsense_extrinsics`);
            :data:`TF_REF_TO_STREAM` (default) or :data:`TF_STREAM_TO_REF`.
        T_CfromI: 4×4 IMU→colour extrinsic to use instead of the bag's tf (required when the
            bag has no tf for the colour or IMU stream).
    """

    def __init__(
        self,
        path: str | Path,
        imu_gap_warn_s: float = 0.05,
        *,
        tf_convention: str = TF_REF_TO_STREAM,
        T_CfromI: np.ndarray | None = None,
    ) -> None:
        if tf_convention not in (TF_REF_TO_STREAM, TF_STREAM_TO_REF):
            raise ValueError(f"unknown tf convention {tf_convention!r}")
        self.path = Path(path)
        self._src = str(self.path)
        self._imu_gap_warn_s = float(imu_gap_warn_s)
        self._tf_convention = tf_convention
        self._imu: ImuSamples | None = None
        if not self.path.is_file():
            raise SessionError(f"{self._src}: bag file not found")
        self._records = _Records(self.path, self._src)
        try:
            self._open(T_CfromI)
        except BaseException:
            self._records.close()
            raise

    # -- SessionSource --------------------------------------------------------------------

    @property
    def calibration(self) -> SessionCalibration:
        return self._calib

    @property
    def frame_times_ns(self) -> np.ndarray:
        return self._times

    @property
    def imu(self) -> ImuSamples:
        if self._imu is None:
            self._imu = self._read_imu()
        return self._imu

    def __len__(self) -> int:
        return int(self._times.shape[0])

    def frame(self, index: int) -> Frame:
        n = len(self)
        if not -n <= index < n:
            raise IndexError(f"frame {index} out of range (bag has {n})")
        index %= n
        rgb = self._decode_color(self._color_entries[index])
        depth_m = self._decode_depth(self._depth_entries[index])
        if not self._depth_aligned:
            depth_m = align_depth_to_color(
                depth_m, self._bag_depth_intr, self._calib.color, self._T_CfromD
            )
        return Frame(index=index, t_ns=int(self._times[index]), rgb=rgb, depth_m=depth_m)

    def frames(self) -> Iterator[Frame]:
        for i in range(len(self)):
            yield self.frame(i)

    # -- extras ---------------------------------------------------------------------------

    def close(self) -> None:
        """Close the file handle (reopened automatically if frames are read later)."""
        self._records.close()

    def __enter__(self) -> RealSenseBag:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"RealSenseBag({self._src!r}, frames={len(self)})"

    # -- opening --------------------------------------------------------------------------

    def _open(self, T_CfromI_override: np.ndarray | None) -> None:
        self._read_index()
        self._find_streams()
        statics = self._read_static()
        self._build_frame_index(statics)
        self._calib = self._build_calibration(statics, T_CfromI_override)
        self._check_first_frame()
        # Keep only the index of what is read later (the IMU, on first access).
        keep = {c for s in (self._accel, self._gyro) for c in self._topics[s.data_topic]}
        self._index = {cid: idx for cid, idx in self._index.items() if cid in keep}

    def _read_index(self) -> None:
        from rosbags.rosbag1 import Reader

        try:
            reader = Reader(self.path)
            reader.open()
        except Exception as exc:
            why = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            raise SessionError(f"{self._src}: not a readable ROS1 bag ({why})") from None
        try:
            topics: dict[str, list[int]] = {}
            defs: dict[int, tuple[str, str]] = {}
            for conn in reader.connections:
                topics.setdefault(conn.topic, []).append(conn.id)
                defs[conn.id] = (conn.msgtype, conn.msgdef.data)
            # rosbags' per-connection index lists (time, chunk_pos, offset), kept as they are;
            # _Entry objects are made only for the topics that are read.
            index = {cid: list(idx) for cid, idx in reader.indexes.items()}
            chunk_positions = [info.pos for info in reader.chunk_infos]
        finally:
            reader.close()
        if not any(index.values()):
            raise SessionError(f"{self._src}: the bag contains no messages")
        try:
            self._records.chunks = {p: self._records.scan_chunk(p) for p in chunk_positions}
        except (_DamagedError, struct.error) as exc:
            raise SessionError(f"{self._src}: bag data looks damaged ({exc})") from None
        self._topics = topics
        self._index = index
        self._types = _Types(defs, self._src)

    def _topic_entries(self, topic: str) -> list[_Entry]:
        out: list[_Entry] = []
        for cid in self._topics.get(topic, []):
            out.extend(_Entry(e[0], e[1], e[2], cid) for e in self._index.get(cid, ()))
        out.sort(key=lambda e: (e.time, e.chunk_pos, e.offset))
        return out

    def _read_topic(self, topic: str) -> list[Any]:
        """Decode every message on a (small, static) topic, in record-time order."""
        return [
            self._types.decode(e.conn, self._records.message(e), topic)
            for e in self._topic_entries(topic)
        ]

    def _find_streams(self) -> None:
        found: dict[str, list[_Stream]] = {k: [] for k in _KIND_TO_MEDIUM}
        for topic in self._topics:
            m = _DATA_TOPIC.match(topic)
            if m and _KIND_TO_MEDIUM[m.group(3)] == m.group(5):
                s = _Stream(m.group(3), int(m.group(1)), int(m.group(2)), int(m.group(4)))
                if any(self._index.get(cid) for cid in self._topics[topic]):
                    found[s.kind].append(s)
        if not found["Color"]:
            raise SessionError(
                f"{self._src}: no colour image topic with messages "
                "(expected /device_*/sensor_*/Color_*/image/data)"
            )
        color = min(found["Color"], key=lambda s: (s.device, s.index, s.sensor))
        chosen = {"Color": color}
        for kind in ("Depth", "Accel", "Gyro"):
            same = [s for s in found[kind] if s.device == color.device]
            if not same:
                raise SessionError(
                    f"{self._src}: no {_KIND_NAME[kind]} topic with messages for device "
                    f"{color.device} (expected /device_{color.device}/sensor_*/{kind}_*/"
                    f"{_KIND_TO_MEDIUM[kind]}/data)"
                )
            chosen[kind] = min(same, key=lambda s: (s.index, s.sensor))
        for kind, streams in found.items():
            if len(streams) > 1:
                log.warning(
                    "%s: %d %s streams, using %s",
                    self._src,
                    len(streams),
                    _KIND_NAME[kind],
                    chosen[kind].data_topic,
                )
        self._color, self._depth = chosen["Color"], chosen["Depth"]
        self._accel, self._gyro = chosen["Accel"], chosen["Gyro"]

    def _read_static(self) -> dict[str, Any]:
        statics: dict[str, Any] = {}
        versions = self._read_topic("/file_version")
        statics["file_version"] = int(versions[0].data) if versions else None
        if not versions:
            log.debug("%s: no /file_version (bag not written by the RealSense SDK?)", self._src)

        info: dict[str, str] = {}
        for msg in self._read_topic(f"/device_{self._color.device}/info"):
            key, value = getattr(msg, "key", None), getattr(msg, "value", None)
            if isinstance(key, str) and isinstance(value, str):
                info.setdefault(key, value)
        statics["device_info"] = info

        for s in (self._color, self._depth, self._accel, self._gyro):
            cams = self._read_topic(f"{s.prefix}/info/camera_info")
            statics[f"camera_info/{s.kind}"] = cams[0] if cams else None
            imu_intr = self._read_topic(f"{s.prefix}/imu_intrinsic")
            statics[f"imu_intrinsic/{s.kind}"] = imu_intr[0] if imu_intr else None
            stream_info = self._read_topic(f"{s.prefix}/info")
            statics[f"stream_info/{s.kind}"] = stream_info[0] if stream_info else None
            tfs: dict[str, np.ndarray] = {}
            tf_pattern = re.compile(re.escape(s.prefix) + r"/tf/([^/]+)$")
            for topic in sorted(self._topics):
                m = tf_pattern.match(topic)
                if not m:
                    continue
                msgs = self._read_topic(topic)
                if msgs:
                    try:
                        tfs[m.group(1)] = transform_to_matrix(msgs[0])
                    except (ValueError, AttributeError) as exc:
                        raise SessionError(
                            f"{self._src}: bad extrinsic on {topic} ({exc})"
                        ) from None
            statics[f"tf/{s.kind}"] = tfs

        statics["depth_units"] = self._depth_units_m = self._depth_units()
        return statics

    def _depth_units(self) -> float:
        name = "Depth Units"
        d, s = self._depth.device, self._depth.sensor
        topics = [f"/device_{d}/sensor_{s}/option/{name}/value"]
        pattern = re.compile(rf"^/device_{d}/sensor_\d+/option/{re.escape(name)}/value$")
        topics += sorted(t for t in self._topics if pattern.match(t) and t not in topics)
        for topic in topics:
            values = [float(m.data) for m in self._read_topic(topic)]
            if not values:
                continue
            value = values[0]
            if not math.isfinite(value) or value <= 0:
                raise SessionError(f"{self._src}: invalid depth units {value!r} on {topic}")
            if any(v != value for v in values[1:]):
                log.warning(
                    "%s: depth units change during the recording (%s), using the first",
                    self._src,
                    sorted(set(values)),
                )
            return _nominal_float32(value)
        log.info("%s: no '%s' option, assuming %g m", self._src, name, DEFAULT_DEPTH_UNITS_M)
        return DEFAULT_DEPTH_UNITS_M

    def _stamps(self, entries: list[_Entry], topic: str) -> np.ndarray:
        """Header stamps of messages, reading only the first bytes of each payload."""
        stamps = np.zeros(len(entries), dtype=np.int64)
        order = sorted(range(len(entries)), key=lambda k: (entries[k].chunk_pos, entries[k].offset))
        fast: dict[int, bool] = {}
        for k in order:
            e = entries[k]
            if e.conn not in fast:
                fast[e.conn] = self._types.header_first(e.conn)
            if fast[e.conn]:
                head = self._records.message(e, limit=12)
                if len(head) < 12:
                    raise SessionError(f"{self._src}: truncated message on {topic}")
                _, sec, nsec = struct.unpack("<III", head)
                stamps[k] = sec * 1_000_000_000 + nsec
            else:
                msg = self._types.decode(e.conn, self._records.message(e), topic)
                stamps[k] = _stamp_ns(msg.header.stamp)
        return stamps

    def _stream_fps(self, statics: dict[str, Any], stream: _Stream) -> float | None:
        info = statics.get(f"stream_info/{stream.kind}")
        fps = getattr(info, "fps", None) if info is not None else None
        if fps is not None and float(fps) > 0:
            return float(fps)
        times = np.array([e.time for e in self._topic_entries(stream.data_topic)], dtype=np.int64)
        dt = np.diff(np.unique(times))
        if dt.size:
            return 1e9 / float(np.median(dt))
        return None

    def _build_frame_index(self, statics: dict[str, Any]) -> None:
        color_entries = self._topic_entries(self._color.data_topic)
        depth_entries = self._topic_entries(self._depth.data_topic)
        tc = self._stamps(color_entries, self._color.data_topic)
        td = self._stamps(depth_entries, self._depth.data_topic)

        def dedupe(t: np.ndarray, entries: list[_Entry], what: str):
            order = np.argsort(t, kind="stable")
            t = t[order]
            keep = np.ones(t.shape[0], dtype=bool)
            keep[1:] = t[1:] != t[:-1]
            if (~keep).any():
                log.warning(
                    "%s: dropped %d %s frame(s) with a repeated timestamp",
                    self._src,
                    int((~keep).sum()),
                    what,
                )
            return t[keep], [entries[i] for i in order[keep]]

        tc, color_entries = dedupe(tc, color_entries, "colour")
        td, depth_entries = dedupe(td, depth_entries, "depth")

        if tc.shape[0] > 1:
            period_ns = float(np.median(np.diff(tc)))
        else:
            fps = self._stream_fps(statics, self._color) or 30.0
            period_ns = 1e9 / fps
        tol_ns = period_ns / 2.0
        pos = np.searchsorted(td, tc)
        left = np.clip(pos - 1, 0, td.shape[0] - 1)
        right = np.clip(pos, 0, td.shape[0] - 1)
        d_left = np.abs(tc - td[left])
        d_right = np.abs(tc - td[right])
        match = np.where(d_right < d_left, right, left)
        dist = np.minimum(d_left, d_right)
        paired = dist <= tol_ns
        # One depth frame serves at most one colour frame (the nearest; ties: the earlier).
        best: dict[int, int] = {}
        for i in np.flatnonzero(paired):
            j = int(match[i])
            if j not in best or dist[i] < dist[best[j]]:
                best[j] = int(i)
        color_idx = np.array(sorted(best.values()), dtype=np.int64)
        n_color_drop = tc.shape[0] - color_idx.shape[0]
        n_depth_drop = td.shape[0] - color_idx.shape[0]
        if n_color_drop or n_depth_drop:
            log.warning(
                "%s: dropped %d colour and %d depth frame(s) without a partner within %.1f ms",
                self._src,
                n_color_drop,
                n_depth_drop,
                tol_ns * 1e-6,
            )
        if color_idx.shape[0] == 0:
            raise SessionError(
                f"{self._src}: no colour frame has a depth frame within half a frame period"
            )
        self._times = tc[color_idx]
        self._color_entries = [color_entries[i] for i in color_idx]
        self._depth_entries = [depth_entries[int(match[i])] for i in color_idx]

    def _intrinsics(self, msg: Any, topic: str) -> CameraIntrinsics:
        K = np.asarray(msg.K if hasattr(msg, "K") else msg.k, dtype=np.float64).ravel()
        D = np.asarray(msg.D if hasattr(msg, "D") else msg.d, dtype=np.float64).ravel()
        width, height = int(msg.width), int(msg.height)
        if K.shape != (9,) or not np.isfinite(K).all() or K[0] <= 0 or K[4] <= 0:
            raise SessionError(f"{self._src}: invalid camera matrix on {topic}: {K.tolist()}")
        if width <= 0 or height <= 0:
            raise SessionError(f"{self._src}: invalid image size {width}×{height} on {topic}")
        distortion = tuple(float(d) for d in D) if D.size else (0.0,) * 5
        return CameraIntrinsics(
            width=width,
            height=height,
            fx=float(K[0]),
            fy=float(K[4]),
            cx=float(K[2]),
            cy=float(K[5]),
            distortion=distortion,
        )

    def _extrinsic(
        self, statics: dict[str, Any], target: _Stream, source: _Stream
    ) -> np.ndarray | None:
        """``T_{target from source}`` from the two streams' tf, or None if not composable."""
        tf_t: dict[str, np.ndarray] = statics[f"tf/{target.kind}"]
        tf_s: dict[str, np.ndarray] = statics[f"tf/{source.kind}"]
        common = sorted(set(tf_t) & set(tf_s))
        if common:
            return relative_extrinsic(tf_t[common[0]], tf_s[common[0]], self._tf_convention)
        return None

    def _build_calibration(
        self, statics: dict[str, Any], T_CfromI_override: np.ndarray | None
    ) -> SessionCalibration:
        color_topic = f"{self._color.prefix}/info/camera_info"
        depth_topic = f"{self._depth.prefix}/info/camera_info"
        if statics["camera_info/Color"] is None:
            raise SessionError(f"{self._src}: no colour intrinsics ({color_topic} is missing)")
        color = self._intrinsics(statics["camera_info/Color"], color_topic)

        if not statics["tf/Depth"]:
            # The depth stream is the reference ("pin") stream of D400 devices.
            statics["tf/Depth"] = {g: np.eye(4) for g in statics["tf/Color"]}

        depth_msg = statics["camera_info/Depth"]
        if depth_msg is not None:
            depth = self._intrinsics(depth_msg, depth_topic)
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
        T_CfromD = self._extrinsic(statics, self._color, self._depth)
        if depth is None:
            # Without depth intrinsics only an already aligned image is usable; the frame check
            # at open confirms the size.
            log.warning("%s: no depth camera_info, assuming depth is aligned to colour", self._src)
            depth, aligned = color, True
        if not aligned and T_CfromD is None:
            raise SessionError(
                f"{self._src}: depth is not aligned to colour and the bag has no depth→colour "
                f"extrinsic (tf topics under {self._color.prefix} and {self._depth.prefix})"
            )
        self._bag_depth_intr = depth
        self._depth_aligned = aligned
        self._T_CfromD = T_CfromD if T_CfromD is not None else np.eye(4)

        if T_CfromI_override is not None:
            T_CfromI = np.asarray(T_CfromI_override, dtype=np.float64)
            if T_CfromI.shape != (4, 4):
                raise ValueError(f"T_CfromI must be 4×4, got {T_CfromI.shape}")
        else:
            imu_stream = self._gyro if statics["tf/Gyro"] else self._accel
            T_CfromI = self._extrinsic(statics, self._color, imu_stream)
            if T_CfromI is None:
                raise SessionError(
                    f"{self._src}: no IMU→colour extrinsic (tf of {self._color.prefix} and of "
                    f"{self._gyro.prefix} or {self._accel.prefix} in one group); pass T_CfromI"
                )
            if statics["tf/Gyro"] and statics["tf/Accel"]:
                T_alt = self._extrinsic(statics, self._color, self._accel)
                if T_alt is not None and not np.allclose(T_alt, T_CfromI, atol=1e-6):
                    log.warning(
                        "%s: accelerometer and gyro extrinsics differ; using the gyro's",
                        self._src,
                    )

        fps_acc = self._stream_fps(statics, self._accel)
        fps_gyr = self._stream_fps(statics, self._gyro)
        noise = self._imu_noise(
            statics["imu_intrinsic/Accel"], statics["imu_intrinsic/Gyro"], fps_acc, fps_gyr
        )

        info = statics["device_info"]
        device = info.get("Name", "unknown")
        extra: dict[str, Any] = {
            "source": "realsense_bag",
            "bag": self._src,
            "file_version": statics["file_version"],
            "device_info": dict(info),
            "depth_aligned_in_bag": bool(aligned),
            "bag_depth_intrinsics": _intrinsics_dict(depth),
            "T_CfromD": [[float(v) for v in row] for row in self._T_CfromD],
            "tf_convention": self._tf_convention,
            "topics": {
                "color": self._color.data_topic,
                "depth": self._depth.data_topic,
                "accel": self._accel.data_topic,
                "gyro": self._gyro.data_topic,
            },
        }
        return SessionCalibration(
            color=color,
            depth=color,
            depth_scale_m=statics["depth_units"],
            depth_aligned_to_color=True,
            T_CfromI=T_CfromI,
            imu_noise=noise,
            device=device,
            extra=extra,
        )

    def _imu_noise(
        self, acc_intr: Any, gyr_intr: Any, fps_acc: float | None, fps_gyr: float | None
    ) -> ImuNoise | None:
        noise = imu_noise_from_intrinsics(acc_intr, gyr_intr, fps_acc, fps_gyr)
        if noise is None:
            log.info("%s: no IMU noise variances in imu_intrinsic, imu_noise = None", self._src)
        return noise

    def _check_first_frame(self) -> None:
        rgb = self._decode_color(self._color_entries[0])
        c = self._calib.color
        if rgb.shape[:2] != (c.height, c.width):
            raise SessionError(
                f"{self._src}: colour images are {rgb.shape[1]}×{rgb.shape[0]} but camera_info "
                f"says {c.width}×{c.height}"
            )
        depth = self._decode_depth(self._depth_entries[0])
        d = self._bag_depth_intr
        if depth.shape != (d.height, d.width):
            raise SessionError(
                f"{self._src}: depth images are {depth.shape[1]}×{depth.shape[0]} but "
                f"{'camera_info' if not self._depth_aligned else 'colour'} says "
                f"{d.width}×{d.height}"
            )

    # -- decoding -------------------------------------------------------------------------

    def _image_msg(self, entry: _Entry, topic: str) -> Any:
        return self._types.decode(entry.conn, self._records.message(entry), topic)

    def _pixels(self, msg: Any, topic: str, channels: int, itemsize: int) -> np.ndarray:
        h, w, step = int(msg.height), int(msg.width), int(msg.step)
        data = np.asarray(msg.data, dtype=np.uint8).ravel()
        row = w * channels * itemsize
        if h <= 0 or w <= 0 or step < row or data.size < step * h:
            raise SessionError(
                f"{self._src}: malformed image on {topic} ({w}×{h}, step {step}, {data.size} bytes)"
            )
        return data[: step * h].reshape(h, step)[:, :row]

    def _decode_color(self, entry: _Entry) -> np.ndarray:
        topic = self._color.data_topic
        msg = self._image_msg(entry, topic)
        enc = str(msg.encoding)
        if enc.lower() not in _COLOR_ENCODINGS:
            raise SessionError(
                f"{self._src}: unsupported colour encoding {enc!r} on {topic} "
                f"(supported: {', '.join(_COLOR_ENCODINGS)})"
            )
        channels, rgb_idx = _COLOR_ENCODINGS[enc.lower()]
        px = self._pixels(msg, topic, channels, 1).reshape(
            int(msg.height), int(msg.width), channels
        )
        return np.ascontiguousarray(px[:, :, list(rgb_idx)])

    def _decode_depth(self, entry: _Entry) -> np.ndarray:
        topic = self._depth.data_topic
        msg = self._image_msg(entry, topic)
        enc = str(msg.encoding)
        kind = _DEPTH_ENCODINGS.get(enc.lower())
        if kind is None:
            raise SessionError(
                f"{self._src}: unsupported depth encoding {enc!r} on {topic} "
                "(supported: mono16, 16UC1, 32FC1)"
            )
        dtype = np.dtype(("<" if not msg.is_bigendian else ">") + kind)
        px = self._pixels(msg, topic, 1, dtype.itemsize)
        values = np.ascontiguousarray(px).view(dtype).reshape(int(msg.height), int(msg.width))
        if kind == "u2":
            return (values.astype(np.float64) * self._depth_units_m).astype(np.float32)
        depth = values.astype(np.float32)
        depth[~np.isfinite(depth) | (depth < 0)] = 0.0
        return depth

    # -- IMU ------------------------------------------------------------------------------

    def _read_imu(self) -> ImuSamples:
        acc_topic, gyr_topic = self._accel.data_topic, self._gyro.data_topic
        jobs = [(e, 0) for e in self._topic_entries(acc_topic)]
        jobs += [(e, 1) for e in self._topic_entries(gyr_topic)]
        jobs.sort(key=lambda j: (j[0].chunk_pos, j[0].offset))
        t: list[list[int]] = [[], []]
        v: list[list[tuple[float, float, float]]] = [[], []]
        standard: dict[int, bool] = {}
        for entry, which in jobs:
            raw = self._records.message(entry)
            if entry.conn not in standard:
                standard[entry.conn] = self._types.is_standard(entry.conn, "sensor_msgs/msg/Imu")
            parsed = _parse_imu(raw, which) if standard[entry.conn] else None
            if parsed is None:
                topic = gyr_topic if which else acc_topic
                msg = self._types.decode(entry.conn, raw, topic)
                vec = msg.angular_velocity if which else msg.linear_acceleration
                parsed = (_stamp_ns(msg.header.stamp), (vec.x, vec.y, vec.z))
            t[which].append(parsed[0])
            v[which].append(parsed[1])
        imu = merge_imu_streams(
            np.array(t[0], dtype=np.int64),
            np.array(v[0], dtype=np.float64).reshape(-1, 3),
            np.array(t[1], dtype=np.int64),
            np.array(v[1], dtype=np.float64).reshape(-1, 3),
            gap_warn_s=self._imu_gap_warn_s,
            source=self._src,
        )
        if imu.t_ns[0] > self._times[0] or imu.t_ns[-1] < self._times[-1]:
            log.warning(
                "%s: IMU covers %.3f–%.3f s but frames span %.3f–%.3f s",
                self._src,
                imu.t_ns[0] * 1e-9,
                imu.t_ns[-1] * 1e-9,
                self._times[0] * 1e-9,
                self._times[-1] * 1e-9,
            )
        return imu
