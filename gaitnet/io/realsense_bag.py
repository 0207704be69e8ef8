"""Read a RealSense SDK / Viewer recording (ROS1 ``.bag``) as a :class:`SessionSource`.

Topic layout written by librealsense (``src/media/ros/ros_file_format.h``); streams are found
by pattern, not by sensor number (a D455 has depth on ``sensor_0``, colour on ``sensor_1`` and
the IMU on ``sensor_2``)::

    /file_version                                      std_msgs/UInt32 (absent in bags
                                                       re-recorded with ROS tools: tolerated)
    /device_<d>/info                                   diagnostic_msgs/KeyValue (Name, serial …)
    /device_<d>/sensor_<s>/<Stream>_<i>/image/data     sensor_msgs/Image     (Depth, Color)
    /device_<d>/sensor_<s>/<Stream>_<i>/image/metadata diagnostic_msgs/KeyValue per frame
    /device_<d>/sensor_<s>/<Stream>_<i>/imu/data       sensor_msgs/Imu       (Accel, Gyro)
    /device_<d>/sensor_<s>/<Stream>_<i>/imu/metadata   diagnostic_msgs/KeyValue per sample
    /device_<d>/sensor_<s>/<Stream>_<i>/info           realsense_msgs/StreamInfo (fps, …)
    /device_<d>/sensor_<s>/<Stream>_<i>/info/camera_info  sensor_msgs/CameraInfo
    /device_<d>/sensor_<s>/<Stream>_<i>/imu_intrinsic  realsense_msgs/ImuIntrinsic
    /device_<d>/sensor_<s>/<Stream>_<i>/tf/<group>     geometry_msgs/Transform (extrinsic)
    /device_<d>/sensor_<s>/option/<Option Name>/value  std_msgs/Float32 (e.g. "Depth Units")

The file itself (index, positioned reads, decoding with the bag's own message definitions) is
:class:`gaitnet.io.bag_index.RosBag`; image messages become arrays in
:mod:`gaitnet.io.ros_image`; extrinsics and IMU noise are read as documented in
:mod:`gaitnet.io.realsense_extrinsics`; depth is re-projected by
:func:`gaitnet.io.depth_align.align_depth_to_color`. This module maps the SDK's layout onto a
session.

Timestamps
    A frame's ``t_ns`` is the colour image's ``header.stamp`` (the SDK writes the device frame
    timestamp there; the bag's own record time is the host capture time since the recording
    started and is not used). IMU samples use their ``header.stamp`` too. Every stamp must
    stay within :data:`STAMP_RECORD_TOLERANCE_S` of where its record time puts it (header
    stamp minus record time is a constant offset up to USB latency), which catches damaged
    stamps; frames a little out of order are sorted with a warning.

Timestamp domain (**refused when they differ**)
    The SDK stores each frame's clock in its metadata (key ``timestamp_domain``: ``Hardware
    Clock``, ``System Time`` or ``Global Time``). Frames and IMU samples stamped by different
    clocks cannot be synchronised (the offset between them is arbitrary), so a bag whose colour,
    depth, accelerometer and gyro streams report different domains — or a stream that changes
    domain during the recording — is refused with a :class:`SessionError` naming the domains.
    Record again with one clock for all sensors (e.g. enable "Global Time" on every sensor in
    RealSense Viewer). A bag without metadata (re-recorded with ROS tools) is accepted with an
    info message; the domain found is stored in ``extra["timestamp_domain"]``.

Laziness
    Opening reads the bag index, the few static messages (calibration, options), a few
    metadata messages per stream, and the first bytes of every image message (its header:
    stamp, size, encoding, step, data length); for uncompressed chunks these are small
    positioned reads, compressed chunks are decompressed once each. :meth:`RealSenseBag.frame`
    reads and decodes just the two messages of that frame. The IMU is read on first access to
    :attr:`RealSenseBag.imu`.

Frames
    Colour and depth frames are paired by nearest header stamp; pairs further apart than half
    the colour frame period are dropped with a warning. ``rgb`` is uint8 RGB (``rgb8``,
    ``bgr8``, ``rgba8``, ``bgra8`` accepted); ``depth_m`` is float32 metres (``mono16`` /
    ``16UC1`` times the "Depth Units" option, default 0.001 m, with 65535 = no data; ``32FC1``
    is taken as metres), 0 = invalid, always aligned to colour: a depth image of colour's size
    whose camera_info equals colour's is taken as aligned already, otherwise it is aligned
    here. The calibration therefore describes the delivered data: ``depth`` intrinsics are the
    colour intrinsics and ``depth_aligned_to_color`` is True; the bag's own depth intrinsics
    are in ``extra["bag_depth_intrinsics"]``. Every frame of a stream must have the size,
    encoding and row step of the first and exactly ``step · height`` bytes of pixels: checked
    for all frames at open (from the image headers) and again when a frame is decoded.

Errors (a missing colour, depth or IMU topic, an empty, unindexed or truncated bag, a file
that is not a bag, an unsupported image encoding, frames whose size changes, NaN or a
non-rigid transform in the tf, non-finite calibration values, damaged stamps or records,
mixed timestamp domains, physically impossible IMU values) raise :class:`SessionError` with a
one-line message that names the bag file.
"""

from __future__ import annotations

import logging
import math
import re
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gaitnet.errors import SessionError
from gaitnet.io.bag_index import MessageRef, RosBag, parse_imu_payload, stamp_ns
from gaitnet.io.depth_align import align_depth_to_color
from gaitnet.io.imu_merge import merge_imu_streams
from gaitnet.io.realsense_extrinsics import (
    TF_REF_TO_STREAM,
    TF_STREAM_TO_REF,
    imu_noise_from_intrinsics,
    relative_extrinsic,
    transform_to_matrix,
)
from gaitnet.io.ros_image import (
    HEAD_BYTES,
    ImageHead,
    check_layout,
    color_format,
    decode_color,
    decode_depth,
    depth_format,
    parse_image_head,
)
from gaitnet.io.types import (
    CameraIntrinsics,
    Frame,
    ImuNoise,
    ImuSamples,
    SessionCalibration,
    rigid_transform,
)

__all__ = [
    "DEFAULT_DEPTH_UNITS_M",
    "STAMP_RECORD_TOLERANCE_S",
    "TF_REF_TO_STREAM",
    "TF_STREAM_TO_REF",
    "RealSenseBag",
]

log = logging.getLogger(__name__)

DEFAULT_DEPTH_UNITS_M = 0.001
STAMP_RECORD_TOLERANCE_S = 1.0
"""How far (s) a header stamp may stray from the offset its record time implies."""
_METADATA_PROBE = 64  # metadata messages read at each end of a stream to find its domain

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
_IMAGE_TYPE = "sensor_msgs/msg/Image"
_IMU_TYPE = "sensor_msgs/msg/Imu"


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

    @property
    def metadata_topic(self) -> str:
        return f"{self.prefix}/{_KIND_TO_MEDIUM[self.kind]}/metadata"


def _nominal_float32(value: float) -> float:
    """Undo float32 storage of a decimal option value (0.0010000000474974513 -> 0.001)."""
    return float(f"{float(np.float32(value)):.7g}")


def _header_stamp(msg: Any) -> int:
    stamp = msg.header.stamp
    nsec = getattr(stamp, "nanosec", None)
    return stamp_ns(stamp.sec, stamp.nsec if nsec is None else nsec)


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
        if T_CfromI is not None:
            T_CfromI = rigid_transform(T_CfromI, "T_CfromI")
        self.path = Path(path)
        self._src = str(self.path)
        self._imu_gap_warn_s = float(imu_gap_warn_s)
        self._tf_convention = tf_convention
        self._imu: ImuSamples | None = None
        if not self.path.is_file():
            raise SessionError(f"{self._src}: bag file not found")
        self._bag = RosBag(self.path, self._src)
        try:
            self._open(T_CfromI)
        except BaseException:
            self._bag.close()
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
        rgb = self._decode_color(index)
        depth_m = self._decode_depth(index)
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
        self._bag.close()

    def __enter__(self) -> RealSenseBag:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"RealSenseBag({self._src!r}, frames={len(self)})"

    def _error(self, what: str) -> SessionError:
        return SessionError(f"{self._src}: {what}")

    # -- opening --------------------------------------------------------------------------

    def _open(self, T_CfromI_override: np.ndarray | None) -> None:
        self._find_streams()
        statics = self._read_static()
        domain = self._timestamp_domain()
        self._build_frame_index(statics)
        self._calib = self._build_calibration(statics, T_CfromI_override, domain)
        self._check_first_frame()
        # Keep only the index of what is read later (the IMU, on first access).
        self._bag.keep_only({self._accel.data_topic, self._gyro.data_topic})

    def _find_streams(self) -> None:
        found: dict[str, list[_Stream]] = {k: [] for k in _KIND_TO_MEDIUM}
        for topic in self._bag.topics:
            m = _DATA_TOPIC.match(topic)
            if m and _KIND_TO_MEDIUM[m.group(3)] == m.group(5) and self._bag.count(topic):
                s = _Stream(m.group(3), int(m.group(1)), int(m.group(2)), int(m.group(4)))
                found[s.kind].append(s)
        if not found["Color"]:
            raise self._error(
                "no colour image topic with messages "
                "(expected /device_*/sensor_*/Color_*/image/data)"
            )
        color = min(found["Color"], key=lambda s: (s.device, s.index, s.sensor))
        chosen = {"Color": color}
        for kind in ("Depth", "Accel", "Gyro"):
            same = [s for s in found[kind] if s.device == color.device]
            if not same:
                raise self._error(
                    f"no {_KIND_NAME[kind]} topic with messages for device "
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
        versions = self._bag.decode_all("/file_version")
        statics["file_version"] = int(versions[0].data) if versions else None
        if not versions:
            log.debug("%s: no /file_version (bag not written by the RealSense SDK?)", self._src)

        info: dict[str, str] = {}
        for msg in self._bag.decode_all(f"/device_{self._color.device}/info"):
            key, value = getattr(msg, "key", None), getattr(msg, "value", None)
            if isinstance(key, str) and isinstance(value, str):
                info.setdefault(key, value)
        statics["device_info"] = info

        for s in (self._color, self._depth, self._accel, self._gyro):
            cams = self._bag.decode_all(f"{s.prefix}/info/camera_info")
            statics[f"camera_info/{s.kind}"] = cams[0] if cams else None
            imu_intr = self._bag.decode_all(f"{s.prefix}/imu_intrinsic")
            statics[f"imu_intrinsic/{s.kind}"] = imu_intr[0] if imu_intr else None
            stream_info = self._bag.decode_all(f"{s.prefix}/info")
            statics[f"stream_info/{s.kind}"] = stream_info[0] if stream_info else None
            tfs: dict[str, np.ndarray] = {}
            tf_pattern = re.compile(re.escape(s.prefix) + r"/tf/([^/]+)$")
            for topic in sorted(self._bag.topics):
                m = tf_pattern.match(topic)
                if not m:
                    continue
                msgs = self._bag.decode_all(topic)
                if msgs:
                    try:
                        tfs[m.group(1)] = rigid_transform(transform_to_matrix(msgs[0]), "tf")
                    except (ValueError, AttributeError, TypeError) as exc:
                        raise self._error(f"bad extrinsic on {topic} ({exc})") from None
            statics[f"tf/{s.kind}"] = tfs

        statics["depth_units"] = self._depth_units_m = self._depth_units()
        return statics

    def _depth_units(self) -> float:
        name = "Depth Units"
        d, s = self._depth.device, self._depth.sensor
        topics = [f"/device_{d}/sensor_{s}/option/{name}/value"]
        pattern = re.compile(rf"^/device_{d}/sensor_\d+/option/{re.escape(name)}/value$")
        topics += sorted(t for t in self._bag.topics if pattern.match(t) and t not in topics)
        for topic in topics:
            values = [float(m.data) for m in self._bag.decode_all(topic)]
            if not values:
                continue
            value = values[0]
            if not math.isfinite(value) or value <= 0:
                raise self._error(f"invalid depth units {value!r} on {topic}")
            if any(v != value for v in values[1:]):
                log.warning(
                    "%s: depth units change during the recording (%s), using the first",
                    self._src,
                    sorted(set(values)),
                )
            return _nominal_float32(value)
        log.info("%s: no '%s' option, assuming %g m", self._src, name, DEFAULT_DEPTH_UNITS_M)
        return DEFAULT_DEPTH_UNITS_M

    # -- timestamp domain -----------------------------------------------------------------

    def _domains_of(self, stream: _Stream) -> list[str]:
        """Timestamp domains named in the first and last metadata messages of a stream."""
        topic = stream.metadata_topic
        refs = self._bag.refs(topic)
        found: list[str] = []
        for probe in (refs[:_METADATA_PROBE], refs[::-1][:_METADATA_PROBE]):
            for ref in probe:
                msg = self._bag.decode(ref, topic)
                if getattr(msg, "key", None) == "timestamp_domain":
                    found.append(str(getattr(msg, "value", "")))
                    break
        return found

    def _timestamp_domain(self) -> str | None:
        """The one clock of all four streams (module docstring); refuses mixed clocks."""
        domains: dict[str, str] = {}
        for s in (self._color, self._depth, self._accel, self._gyro):
            found = self._domains_of(s)
            if len(set(found)) > 1:
                raise self._error(
                    f"the {_KIND_NAME[s.kind]} timestamps change clock during the recording "
                    f"({found[0]!r} → {found[-1]!r}); they cannot be synchronised"
                )
            if found:
                domains[s.kind] = found[0]
        if not domains:
            log.info("%s: no timestamp domain metadata; assuming one clock", self._src)
            return None
        if len(set(domains.values())) > 1:
            listed = ", ".join(f"{_KIND_NAME[k]} {v!r}" for k, v in domains.items())
            raise self._error(
                f"streams are stamped by different clocks ({listed}) and cannot be "
                "synchronised; record with one clock for all sensors (e.g. enable "
                "'Global Time' on every sensor)"
            )
        missing = [_KIND_NAME[s] for s in ("Color", "Depth", "Accel", "Gyro") if s not in domains]
        if missing:
            log.warning(
                "%s: no timestamp domain for the %s stream(s); assuming %r like the others",
                self._src,
                ", ".join(missing),
                next(iter(domains.values())),
            )
        return next(iter(domains.values()))

    # -- frame index ----------------------------------------------------------------------

    def _heads(self, refs: list[MessageRef], stream: _Stream) -> list[ImageHead]:
        """The header fields of every image message (only their first bytes are read)."""
        topic = stream.data_topic
        heads: list[ImageHead | None] = [None] * len(refs)
        order = sorted(range(len(refs)), key=lambda k: (refs[k].chunk_pos, refs[k].offset))
        fast: dict[int, bool] = {}
        for k in order:
            ref = refs[k]
            if ref.conn not in fast:
                fast[ref.conn] = self._bag.is_standard(ref.conn, _IMAGE_TYPE)
            try:
                if fast[ref.conn]:
                    raw, total = self._bag.read_head(ref, HEAD_BYTES)
                    head = parse_image_head(raw)
                    if head is None:
                        raise ValueError(f"message of {total} bytes is too short for an image")
                    if head.payload_len != total:
                        raise ValueError(
                            f"message is {total} bytes but its fields describe "
                            f"{head.payload_len} ({head.data_len} bytes of pixels)"
                        )
                else:
                    msg = self._bag.decode(ref, topic)
                    head = ImageHead(
                        _header_stamp(msg),
                        int(msg.height),
                        int(msg.width),
                        str(msg.encoding),
                        bool(msg.is_bigendian),
                        int(msg.step),
                        len(msg.data),
                        0,
                    )
            except ValueError as exc:
                what = f"{_KIND_NAME[stream.kind]} message {k} on {topic}"
                raise self._error(f"{what}: {exc}") from None
            heads[k] = head
        return heads  # type: ignore[return-value]

    def _check_stamps(self, t: np.ndarray, record: np.ndarray, what: str) -> None:
        """Header stamps must follow the record times (damaged stamps are refused)."""
        if t.shape[0] == 0:
            return
        offset = t - record
        median = int(np.median(offset))
        off = np.abs(offset - median) > STAMP_RECORD_TOLERANCE_S * 1e9
        if off.any():
            k = int(np.flatnonzero(off)[0])
            raise self._error(
                f"{what} {k} has header stamp {int(t[k])} ns, {(offset[k] - median) * 1e-9:+.3f} "
                f"s away from where its record time puts it (damaged stamps?)"
            )

    def _check_layouts(self, heads: list[ImageHead], stream: _Stream) -> None:
        what = _KIND_NAME[stream.kind]
        first = heads[0]
        try:
            if stream.kind == "Color":
                channels, itemsize = color_format(first.encoding)[0], 1
            else:
                channels, itemsize = 1, depth_format(first.encoding, first.is_bigendian).itemsize
        except ValueError as exc:
            raise self._error(f"{exc} on {stream.data_topic}") from None
        for k, head in enumerate(heads):
            if head.layout() != first.layout():
                raise self._error(
                    f"{what} frame {k} (t_ns={head.t_ns}) is {head.width}×{head.height} "
                    f"{head.encoding} (step {head.step}) but frame 0 is {first.width}×"
                    f"{first.height} {first.encoding} (step {first.step}); frames may not "
                    "change size or format"
                )
            try:
                check_layout(head, channels, itemsize)
            except ValueError as exc:
                raise self._error(f"{what} frame {k} (t_ns={head.t_ns}): {exc}") from None

    def _stream_fps(self, statics: dict[str, Any], stream: _Stream) -> float | None:
        info = statics.get(f"stream_info/{stream.kind}")
        fps = getattr(info, "fps", None) if info is not None else None
        if fps is not None and float(fps) > 0:
            return float(fps)
        times = np.array([e.time for e in self._bag.refs(stream.data_topic)], dtype=np.int64)
        dt = np.diff(np.unique(times))
        if dt.size:
            return 1e9 / float(np.median(dt))
        return None

    def _sorted_frames(self, stream: _Stream) -> tuple[np.ndarray, list[MessageRef]]:
        """Header stamps (increasing, unique) and references of one image stream."""
        refs = self._bag.refs(stream.data_topic)
        heads = self._heads(refs, stream)
        self._check_layouts(heads, stream)
        what = f"{_KIND_NAME[stream.kind]} frame"
        t = np.array([h.t_ns for h in heads], dtype=np.int64)
        self._check_stamps(t, np.array([r.time for r in refs], dtype=np.int64), what)
        back = np.flatnonzero(np.diff(t) < 0)
        if back.size:
            log.warning(
                "%s: %d %s(s) out of order by up to %.1f ms; sorted by header stamp",
                self._src,
                back.size,
                what,
                float(-np.diff(t).min()) * 1e-6,
            )
        order = np.argsort(t, kind="stable")
        t = t[order]
        keep = np.ones(t.shape[0], dtype=bool)
        keep[1:] = t[1:] != t[:-1]
        if (~keep).any():
            log.warning(
                "%s: dropped %d %s(s) with a repeated timestamp",
                self._src,
                int((~keep).sum()),
                what,
            )
        return t[keep], [refs[i] for i in order[keep]]

    def _build_frame_index(self, statics: dict[str, Any]) -> None:
        tc, color_refs = self._sorted_frames(self._color)
        td, depth_refs = self._sorted_frames(self._depth)

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
            raise self._error("no colour frame has a depth frame within half a frame period")
        self._times = tc[color_idx]
        self._color_refs = [color_refs[i] for i in color_idx]
        self._depth_refs = [depth_refs[int(match[i])] for i in color_idx]

    # -- calibration ----------------------------------------------------------------------

    def _intrinsics(self, msg: Any, topic: str) -> CameraIntrinsics:
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
            raise self._error(f"invalid camera_info on {topic}: {exc}") from None

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
        self, statics: dict[str, Any], T_CfromI_override: np.ndarray | None, domain: str | None
    ) -> SessionCalibration:
        color_topic = f"{self._color.prefix}/info/camera_info"
        depth_topic = f"{self._depth.prefix}/info/camera_info"
        if statics["camera_info/Color"] is None:
            raise self._error(f"no colour intrinsics ({color_topic} is missing)")
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
            raise self._error(
                "depth is not aligned to colour and the bag has no depth→colour "
                f"extrinsic (tf topics under {self._color.prefix} and {self._depth.prefix})"
            )
        self._bag_depth_intr = depth
        self._depth_aligned = aligned
        self._T_CfromD = T_CfromD if T_CfromD is not None else np.eye(4)

        if T_CfromI_override is not None:
            T_CfromI = T_CfromI_override
        else:
            imu_stream = self._gyro if statics["tf/Gyro"] else self._accel
            T_CfromI = self._extrinsic(statics, self._color, imu_stream)
            if T_CfromI is None:
                raise self._error(
                    f"no IMU→colour extrinsic (tf of {self._color.prefix} and of "
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
            "bag_depth_intrinsics": {
                "width": depth.width,
                "height": depth.height,
                "fx": depth.fx,
                "fy": depth.fy,
                "cx": depth.cx,
                "cy": depth.cy,
                "distortion": list(depth.distortion),
            },
            "T_CfromD": self._T_CfromD.tolist(),
            "tf_convention": self._tf_convention,
            "topics": {
                "color": self._color.data_topic,
                "depth": self._depth.data_topic,
                "accel": self._accel.data_topic,
                "gyro": self._gyro.data_topic,
            },
        }
        if domain is not None:
            extra["timestamp_domain"] = domain
        try:
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
        except ValueError as exc:
            raise self._error(f"invalid calibration: {exc}") from None

    def _imu_noise(
        self, acc_intr: Any, gyr_intr: Any, fps_acc: float | None, fps_gyr: float | None
    ) -> ImuNoise | None:
        noise = imu_noise_from_intrinsics(acc_intr, gyr_intr, fps_acc, fps_gyr)
        if noise is None:
            log.info("%s: no IMU noise variances in imu_intrinsic, imu_noise = None", self._src)
        return noise

    def _check_first_frame(self) -> None:
        self._first_checked = False
        rgb = self._decode_color(0)
        c = self._calib.color
        if rgb.shape[:2] != (c.height, c.width):
            raise self._error(
                f"colour images are {rgb.shape[1]}×{rgb.shape[0]} but camera_info "
                f"says {c.width}×{c.height}"
            )
        depth = self._decode_depth(0)
        d = self._bag_depth_intr
        if depth.shape != (d.height, d.width):
            raise self._error(
                f"depth images are {depth.shape[1]}×{depth.shape[0]} but "
                f"{'camera_info' if not self._depth_aligned else 'colour'} says "
                f"{d.width}×{d.height}"
            )
        self._first_checked = True

    # -- decoding -------------------------------------------------------------------------

    def _decode(self, index: int, stream: _Stream) -> np.ndarray:
        refs = self._color_refs if stream.kind == "Color" else self._depth_refs
        topic = stream.data_topic
        msg = self._bag.decode(refs[index], topic)
        what = f"{_KIND_NAME[stream.kind]} of frame {index} (t_ns={int(self._times[index])})"
        try:
            if stream.kind == "Color":
                image = decode_color(msg)
            else:
                image = decode_depth(msg, self._depth_units_m)
        except ValueError as exc:
            raise self._error(f"{what} on {topic}: {exc}") from None
        if self._first_checked:  # every frame has the size of frame 0 (checked at open)
            if stream.kind == "Color":
                expected = (self._calib.color.height, self._calib.color.width)
            else:
                expected = (self._bag_depth_intr.height, self._bag_depth_intr.width)
            if image.shape[:2] != expected:
                raise self._error(
                    f"{what} is {image.shape[1]}×{image.shape[0]}, expected "
                    f"{expected[1]}×{expected[0]}; frames may not change size"
                )
        return image

    def _decode_color(self, index: int) -> np.ndarray:
        return self._decode(index, self._color)

    def _decode_depth(self, index: int) -> np.ndarray:
        return self._decode(index, self._depth)

    # -- IMU ------------------------------------------------------------------------------

    def _read_imu(self) -> ImuSamples:
        streams = (self._accel, self._gyro)
        jobs = [(r, which) for which, s in enumerate(streams) for r in self._bag.refs(s.data_topic)]
        jobs.sort(key=lambda j: (j[0].chunk_pos, j[0].offset))
        t: list[list[int]] = [[], []]
        rec: list[list[int]] = [[], []]
        v: list[list[tuple[float, float, float]]] = [[], []]
        standard: dict[int, bool] = {}
        for ref, which in jobs:
            topic = streams[which].data_topic
            raw = self._bag.read(ref)
            if ref.conn not in standard:
                standard[ref.conn] = self._bag.is_standard(ref.conn, _IMU_TYPE)
            try:
                parsed = parse_imu_payload(raw, bool(which)) if standard[ref.conn] else None
                if parsed is None:
                    msg = self._bag.decode(ref, topic, raw)
                    vec = msg.angular_velocity if which else msg.linear_acceleration
                    parsed = (_header_stamp(msg), (vec.x, vec.y, vec.z))
            except ValueError as exc:
                raise self._error(f"IMU message on {topic}: {exc}") from None
            t[which].append(parsed[0])
            rec[which].append(ref.time)
            v[which].append(parsed[1])
        t_arr = [np.array(x, dtype=np.int64) for x in t]
        for which, s in enumerate(streams):
            # restore record-time order (jobs were read in file order) for the stamp check
            order = np.argsort(np.array(rec[which], dtype=np.int64), kind="stable")
            self._check_stamps(
                t_arr[which][order],
                np.array(rec[which], dtype=np.int64)[order],
                f"{_KIND_NAME[s.kind]} sample",
            )
        imu = merge_imu_streams(
            t_arr[0],
            np.array(v[0], dtype=np.float64).reshape(-1, 3),
            t_arr[1],
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
