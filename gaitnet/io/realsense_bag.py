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

Extrinsics: direction convention of the SDK's ``tf`` topics (assumption, documented here)
    Each stream's ``tf/<group>`` holds the extrinsic between that stream and its group's
    reference ("pin") stream — the depth stream on D400 devices. We take it as the transform
    **from the reference stream to this stream**: ``p_stream = R p_ref + t``, i.e.
    ``T_{stream from ref}`` (:data:`TF_REF_TO_STREAM`). Evidence in librealsense:
    ``ros_writer::write_extrinsics`` stores ``device::get_extrinsics(stream)``, which returns
    ``try_fetch_extrinsics(*pin_stream, stream)`` — extrinsics *from* the pin stream *to* the
    stream, and ``rs2_extrinsics`` from→to maps points as ``p_to = R p_from + t``
    (``rs2_transform_point_to_point``; the column-major rotation is converted to the quaternion
    of that same R by ``rot2quat``). Playback (``playback_device::calc_extrinsic``) registers
    stream1→stream2 as ``E2 · E1⁻¹``, which is only right with this reading — although a
    comment there says the opposite ("from the stream at hand to some reference point").
    Because of that contradiction the convention is a parameter: pass
    ``tf_convention=TF_STREAM_TO_REF`` to read ``tf`` as ``T_{ref from stream}``. Then
    ``T_CfromI = E_color · E_imu⁻¹`` (default) or ``E_color⁻¹ · E_imu`` (the other reading); see
    :func:`relative_extrinsic`. The IMU extrinsic is the gyro stream's tf (the accel's if the
    gyro has none). A depth stream without a tf is taken as the reference (identity).

IMU noise
    ``realsense_msgs/ImuIntrinsic`` carries ``noise_variances`` and ``bias_variances`` per
    axis. We read them as discrete per-sample variances at the stream's rate ``f`` (the
    StreamInfo fps, else the median record interval): noise density ``sqrt(var / f)`` and bias
    random walk ``sqrt(var_b · f)`` (Kalibr's discrete↔continuous relations), averaging the
    three axes' variances. ``imu_noise`` is None unless both the accelerometer and the gyro
    report positive, finite noise *and* bias variances (the SDK writes zeros when the device
    has no such calibration, which is the usual case).

Errors (a missing colour, depth or IMU topic, an empty bag, a file that is not a bag or is
truncated, an unsupported image encoding, damaged records) raise :class:`SessionError` with a
one-line message that names the bag file.
"""

from __future__ import annotations

import bz2
import logging
import math
import os
import re
import struct
import threading
from collections import OrderedDict
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gaitnet.errors import SessionError
from gaitnet.io.imu_merge import merge_imu_streams
from gaitnet.io.types import (
    CameraIntrinsics,
    Frame,
    ImuNoise,
    ImuSamples,
    SessionCalibration,
)

log = logging.getLogger(__name__)

TF_REF_TO_STREAM = "ref_to_stream"
"""``tf`` of a stream maps reference-stream points into that stream (librealsense's writer)."""
TF_STREAM_TO_REF = "stream_to_ref"
"""``tf`` of a stream maps that stream's points into the reference stream."""

DEFAULT_DEPTH_UNITS_M = 0.001
_SPLAT_MARGIN_PX = 0.25  # see align_depth_to_color

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

_U32 = struct.Struct("<I")
_OP_MSGDATA = 2
_OP_CHUNK = 5
_OP_CONNECTION = 7


# --------------------------------------------------------------------------------------------
# Geometry helpers (public: usable and tested on their own)
# --------------------------------------------------------------------------------------------


def quaternion_to_matrix(x: float, y: float, z: float, w: float) -> np.ndarray:
    """3×3 rotation of the unit quaternion ``(x, y, z, w)`` (Hamilton, as ROS)."""
    q = np.array([x, y, z, w], dtype=np.float64)
    n = float(np.linalg.norm(q))
    if not math.isfinite(n) or n < 1e-9:
        raise ValueError(f"not a rotation quaternion: {q.tolist()}")
    x, y, z, w = q / n
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def transform_to_matrix(msg: Any) -> np.ndarray:
    """4×4 matrix of a ``geometry_msgs/Transform`` (``[R t; 0 1]``, direction as stored)."""
    T = np.eye(4)
    r, t = msg.rotation, msg.translation
    T[:3, :3] = quaternion_to_matrix(r.x, r.y, r.z, r.w)
    T[:3, 3] = [t.x, t.y, t.z]
    return T


def invert_rigid(T: np.ndarray) -> np.ndarray:
    """Inverse of a 4×4 rigid transform."""
    R, t = T[:3, :3], T[:3, 3]
    out = np.eye(4)
    out[:3, :3] = R.T
    out[:3, 3] = -R.T @ t
    return out


def relative_extrinsic(
    E_target: np.ndarray, E_source: np.ndarray, convention: str = TF_REF_TO_STREAM
) -> np.ndarray:
    """``T_{target from source}`` from two streams' tf extrinsics of the same reference group.

    With :data:`TF_REF_TO_STREAM` each ``E`` is ``T_{stream from ref}``, so the result is
    ``E_target · E_source⁻¹``; with :data:`TF_STREAM_TO_REF` each ``E`` is ``T_{ref from
    stream}`` and the result is ``E_target⁻¹ · E_source``.
    """
    if convention == TF_REF_TO_STREAM:
        return E_target @ invert_rigid(E_source)
    if convention == TF_STREAM_TO_REF:
        return invert_rigid(E_target) @ E_source
    raise ValueError(f"unknown tf convention {convention!r}")


def align_depth_to_color(
    depth_m: np.ndarray,
    depth: CameraIntrinsics,
    color: CameraIntrinsics,
    T_CfromD: np.ndarray,
) -> np.ndarray:
    """Re-project a depth image into the colour camera (pinhole models, distortion ignored).

    Every valid depth pixel (``> 0`` and finite) is treated as a small fronto-parallel square
    at its depth: its four corners are back-projected, moved with ``T_CfromD`` (``p_C = R p_D
    + t``) and projected into colour; every colour pixel whose centre falls inside the
    projected square's bounding box, grown by ``_SPLAT_MARGIN_PX`` on each side, receives the
    colour-frame depth of the pixel's centre point. Where several depth pixels land on one
    colour pixel the nearest wins (z-buffer). Splatting the footprint rather than a single
    point leaves no holes when colour has the finer resolution; the margin closes the thin
    cracks between neighbouring footprints of a slanted surface (their depths differ, so
    parallax separates them slightly) at the cost of growing foreground edges by at most one
    colour pixel.

    Returns float32 metres of shape ``(color.height, color.width)``, 0 where nothing landed.
    """
    z = np.asarray(depth_m, dtype=np.float64)
    if z.shape != (depth.height, depth.width):
        raise ValueError(f"depth image is {z.shape}, intrinsics say {(depth.height, depth.width)}")
    W, H = color.width, color.height
    out = np.full(H * W, np.inf)
    valid = np.isfinite(z) & (z > 0)
    v, u = np.nonzero(valid)
    if u.size:
        zs = z[v, u]
        R = np.asarray(T_CfromD, dtype=np.float64)[:3, :3]
        t = np.asarray(T_CfromD, dtype=np.float64)[:3, 3]

        def to_color(du: float, dv: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            x = (u + du - depth.cx) / depth.fx * zs
            y = (v + dv - depth.cy) / depth.fy * zs
            X = R[0, 0] * x + R[0, 1] * y + R[0, 2] * zs + t[0]
            Y = R[1, 0] * x + R[1, 1] * y + R[1, 2] * zs + t[1]
            Z = R[2, 0] * x + R[2, 1] * y + R[2, 2] * zs + t[2]
            with np.errstate(divide="ignore", invalid="ignore"):
                return color.fx * X / Z + color.cx, color.fy * Y / Z + color.cy, Z

        _, _, zc = to_color(0.0, 0.0)
        corners = [to_color(du, dv) for du in (-0.5, 0.5) for dv in (-0.5, 0.5)]
        ok = zc > 0
        for _, _, zk in corners:
            ok &= zk > 0
        us = np.stack([c[0] for c in corners])
        vs = np.stack([c[1] for c in corners])
        m = _SPLAT_MARGIN_PX
        with np.errstate(invalid="ignore"):
            x0 = np.ceil(us.min(axis=0) - m)
            x1 = np.floor(us.max(axis=0) + m)
            y0 = np.ceil(vs.min(axis=0) - m)
            y1 = np.floor(vs.max(axis=0) + m)
        ok &= np.isfinite(x0) & np.isfinite(x1) & np.isfinite(y0) & np.isfinite(y1)
        ok &= (x1 >= 0) & (x0 <= W - 1) & (y1 >= 0) & (y0 <= H - 1)
        x0 = np.clip(x0[ok], 0, W - 1).astype(np.int64)
        x1 = np.clip(x1[ok], 0, W - 1).astype(np.int64)
        y0 = np.clip(y0[ok], 0, H - 1).astype(np.int64)
        y1 = np.clip(y1[ok], 0, H - 1).astype(np.int64)
        zc = zc[ok]
        span_x, span_y = x1 - x0, y1 - y0
        keep = (span_x >= 0) & (span_y >= 0)
        if keep.any():
            # A footprint spans a few pixels at most (resolution ratio); cap it so that a
            # degenerate projection (a point grazing the image plane) cannot explode.
            max_x = min(int(span_x[keep].max()), 16)
            max_y = min(int(span_y[keep].max()), 16)
            for dy in range(max_y + 1):
                for dx in range(max_x + 1):
                    m = keep & (span_x >= dx) & (span_y >= dy)
                    if m.any():
                        idx = (y0[m] + dy) * W + (x0[m] + dx)
                        np.minimum.at(out, idx, zc[m])
    out[~np.isfinite(out)] = 0.0
    return out.reshape(H, W).astype(np.float32)


# --------------------------------------------------------------------------------------------
# Low-level bag access
# --------------------------------------------------------------------------------------------


class _DamagedError(Exception):
    pass


def _parse_header(buf: bytes) -> dict[bytes, bytes]:
    fields: dict[bytes, bytes] = {}
    pos, n = 0, len(buf)
    while pos < n:
        if pos + 4 > n:
            raise _DamagedError("record header field size is cut off")
        (size,) = _U32.unpack_from(buf, pos)
        pos += 4
        if pos + size > n:
            raise _DamagedError("record header field runs past the header")
        name, sep, value = buf[pos : pos + size].partition(b"=")
        if not sep:
            raise _DamagedError("record header field without '='")
        fields[name] = value
        pos += size
    return fields


@dataclass(frozen=True)
class _ChunkLoc:
    datapos: int
    datasize: int
    compression: str


@dataclass(frozen=True, slots=True)
class _Entry:
    """Where one message lies: record time, chunk, offset in the chunk, connection id."""

    time: int
    chunk_pos: int
    offset: int
    conn: int


class _Records:
    """Positioned reads of single messages (``os.pread``: safe across threads and forks)."""

    def __init__(self, path: Path, src: str) -> None:
        self.path = path
        self.src = src
        self.chunks: dict[int, _ChunkLoc] = {}
        self._fh = None
        self._pid = -1
        self._lock = threading.Lock()
        self._cache: OrderedDict[int, bytes] = OrderedDict()

    def __getstate__(self) -> dict:
        return {"path": self.path, "src": self.src, "chunks": self.chunks}

    def __setstate__(self, state: dict) -> None:
        self.__init__(state["path"], state["src"])
        self.chunks = state["chunks"]

    def close(self) -> None:
        with self._lock:
            if self._fh is not None:
                self._fh.close()
            self._fh = None
            self._cache.clear()

    def _fd(self) -> int:
        if self._fh is None or self._pid != os.getpid():
            try:
                self._fh = open(self.path, "rb")  # noqa: SIM115 - kept open, closed by close()
            except OSError as exc:
                raise SessionError(f"{self.src}: cannot open the bag ({exc.strerror})") from exc
            self._pid = os.getpid()
        return self._fh.fileno()

    def read_file(self, pos: int, n: int) -> bytes:
        data = os.pread(self._fd(), n, pos)
        if len(data) != n:
            raise _DamagedError(f"file ends at byte {pos + len(data)}, expected {n} bytes at {pos}")
        return data

    def scan_chunk(self, pos: int) -> _ChunkLoc:
        """Read the CHUNK record header at file position ``pos``."""
        (hl,) = _U32.unpack(self.read_file(pos, 4))
        header = _parse_header(self.read_file(pos + 4, hl))
        if header.get(b"op") != bytes([_OP_CHUNK]):
            raise _DamagedError(f"no chunk record at byte {pos}")
        (size,) = _U32.unpack(self.read_file(pos + 4 + hl, 4))
        compression = header.get(b"compression", b"none").decode(errors="replace")
        return _ChunkLoc(pos + 8 + hl, size, compression)

    def _chunk_data(self, chunk_pos: int) -> bytes:
        with self._lock:
            if chunk_pos in self._cache:
                self._cache.move_to_end(chunk_pos)
                return self._cache[chunk_pos]
        loc = self.chunks[chunk_pos]
        raw = self.read_file(loc.datapos, loc.datasize)
        try:
            if loc.compression == "lz4":
                from lz4.frame import decompress as lz4_decompress

                data = lz4_decompress(raw)
            elif loc.compression == "bz2":
                data = bz2.decompress(raw)
            else:
                raise SessionError(f"{self.src}: unsupported chunk compression {loc.compression!r}")
        except SessionError:
            raise
        except Exception as exc:
            raise _DamagedError(f"chunk at byte {chunk_pos} does not decompress ({exc})") from exc
        with self._lock:
            self._cache[chunk_pos] = data
            while len(self._cache) > 4:
                self._cache.popitem(last=False)
        return data

    def message(self, entry: _Entry, limit: int | None = None) -> bytes:
        """Serialized message at ``entry`` (its first ``limit`` bytes when given)."""
        try:
            return self._message(entry, limit)
        except _DamagedError as exc:
            raise SessionError(f"{self.src}: bag data looks damaged ({exc})") from None
        except struct.error as exc:
            raise SessionError(f"{self.src}: bag data looks damaged ({exc})") from None

    def _message(self, entry: _Entry, limit: int | None) -> bytes:
        loc = self.chunks.get(entry.chunk_pos)
        if loc is None:
            raise _DamagedError(f"index points to unknown chunk at byte {entry.chunk_pos}")
        if loc.compression == "none":
            # One read of a small window usually holds the record header and, for small
            # messages (IMU), the whole payload; anything beyond it is read separately.
            w0 = entry.offset
            window = self.read_file(loc.datapos + w0, max(0, min(4096, loc.datasize - w0)))

            def read(p: int, n: int) -> bytes:
                if p < 0 or p + n > loc.datasize:
                    raise _DamagedError(f"record runs past its chunk at byte {entry.chunk_pos}")
                if w0 <= p and p + n <= w0 + len(window):
                    return window[p - w0 : p - w0 + n]
                return self.read_file(loc.datapos + p, n)

        else:
            buf = self._chunk_data(entry.chunk_pos)

            def read(p: int, n: int) -> bytes:
                if p < 0 or p + n > len(buf):
                    raise _DamagedError(f"record runs past its chunk at byte {entry.chunk_pos}")
                return buf[p : p + n]

        pos = entry.offset
        while True:
            (hl,) = _U32.unpack(read(pos, 4))
            header = _parse_header(read(pos + 4, hl))
            (dl,) = _U32.unpack(read(pos + 4 + hl, 4))
            data_pos = pos + 8 + hl
            op = header.get(b"op")
            if op == bytes([_OP_CONNECTION]):
                pos = data_pos + dl
                continue
            if op != bytes([_OP_MSGDATA]):
                raise _DamagedError(f"no message record at offset {pos} of chunk {entry.chunk_pos}")
            return read(data_pos, dl if limit is None else min(dl, limit))


class _Types:
    """Typestores built from the bag's own message definitions, one per connection."""

    def __init__(self, defs: dict[int, tuple[str, str]], src: str) -> None:
        self.defs = defs  # connection id -> (normalized msgtype, msgdef text)
        self.src = src
        self._base = None
        self._stores: dict[tuple[str, str], Any] = {}

    def __getstate__(self) -> dict:
        return {"defs": self.defs, "src": self.src}

    def __setstate__(self, state: dict) -> None:
        self.__init__(state["defs"], state["src"])

    def store(self, conn: int) -> Any:
        from rosbags.typesys import Stores, TypesysError, get_types_from_msg, get_typestore

        key = self.defs[conn]
        if key in self._stores:
            return self._stores[key]
        msgtype, text = key
        if self._base is None:
            self._base = get_typestore(Stores.ROS1_NOETIC)
        store = self._base
        if text.strip():
            try:
                types = get_types_from_msg(text, msgtype)
            except Exception as exc:
                if msgtype not in self._base.types:
                    raise SessionError(
                        f"{self.src}: cannot parse the message definition of {msgtype} ({exc})"
                    ) from None
                types = None
            if types is not None:
                try:
                    self._base.register(types)
                except TypesysError:
                    # The bag defines a type differently from ROS1 Noetic (e.g. a vendor
                    # variant): decode this connection with its own store.
                    store = get_typestore(Stores.EMPTY)
                    store.register(types)
                    log.debug("%s: %s has a non-standard definition", self.src, msgtype)
        elif msgtype not in self._base.types:
            raise SessionError(f"{self.src}: no message definition for type {msgtype}")
        self._stores[key] = store
        return store

    def decode(self, conn: int, raw: bytes, topic: str) -> Any:
        msgtype = self.defs[conn][0]
        try:
            return self.store(conn).deserialize_ros1(raw, msgtype)
        except SessionError:
            raise
        except Exception as exc:
            raise SessionError(
                f"{self.src}: cannot decode a {msgtype} message on {topic} ({exc})"
            ) from None

    def is_standard(self, conn: int, msgtype: str) -> bool:
        """Whether ``conn`` carries ``msgtype`` exactly as ROS1 Noetic defines it."""
        if self.defs[conn][0] != msgtype:
            return False
        store = self.store(conn)
        return store is self._base and msgtype in store.fielddefs

    def header_first(self, conn: int) -> bool:
        """Whether messages of ``conn`` start with a ROS1 ``Header`` (seq, stamp, …)."""
        store = self.store(conn)
        msgtype = self.defs[conn][0]
        fields = store.fielddefs.get(msgtype, ([], []))[1]
        if not fields or fields[0][1][-1] != "std_msgs/msg/Header":
            return False
        hdr = store.fielddefs.get("std_msgs/msg/Header", ([], []))[1]
        return [f[0] for f in hdr[:2]] == ["seq", "stamp"]


_IMU_TAIL_DOUBLES = 4 + 9 + 3 + 9 + 3 + 9  # orientation, cov, gyro, cov, accel, cov


def _parse_imu(raw: bytes, gyro: bool) -> tuple[int, tuple[float, float, float]] | None:
    """Stamp and gyro (or accel) vector of a standard ROS1 ``sensor_msgs/Imu`` payload.

    A direct ``struct`` read, ~10× faster than generic deserialization (IMU streams have
    hundreds of thousands of messages); None if the size does not fit the standard layout.
    """
    if len(raw) < 16:
        return None
    _, sec, nsec, frame_id_len = struct.unpack_from("<IIII", raw, 0)
    base = 16 + frame_id_len
    if len(raw) != base + 8 * _IMU_TAIL_DOUBLES:
        return None
    vec = struct.unpack_from("<3d", raw, base + 8 * (13 if gyro else 25))
    return sec * 1_000_000_000 + nsec, vec


def _stamp_ns(stamp: Any) -> int:
    nsec = getattr(stamp, "nanosec", None)
    if nsec is None:
        nsec = stamp.nsec
    return int(stamp.sec) * 1_000_000_000 + int(nsec)


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
        tf_convention: how to read the SDK's ``tf`` extrinsics (module docstring);
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
        def variances(msg: Any, name: str) -> float | None:
            if msg is None:
                return None
            v = np.asarray(getattr(msg, name, []), dtype=np.float64).ravel()
            if v.size == 0 or not np.isfinite(v).all() or (v <= 0).any():
                return None
            return float(v.mean())

        a_n, a_b = variances(acc_intr, "noise_variances"), variances(acc_intr, "bias_variances")
        g_n, g_b = variances(gyr_intr, "noise_variances"), variances(gyr_intr, "bias_variances")
        if None in (a_n, a_b, g_n, g_b, fps_acc, fps_gyr):
            log.info("%s: no IMU noise variances in imu_intrinsic, imu_noise = None", self._src)
            return None
        return ImuNoise(
            gyro_noise_density=math.sqrt(g_n / fps_gyr),
            accel_noise_density=math.sqrt(a_n / fps_acc),
            gyro_bias_random_walk=math.sqrt(g_b * fps_gyr),
            accel_bias_random_walk=math.sqrt(a_b * fps_acc),
        )

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
