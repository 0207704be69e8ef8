"""The RealSense SDK's topic layout in a ``.bag``: finding the streams and their clock.

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

Stream choice
    Only data topics with messages count. The colour stream is the one with the lowest device,
    then stream index, then sensor number; the depth, accelerometer and gyro streams must be on
    the colour stream's device (of each kind, the lowest stream index, then sensor number, is
    used). Several streams of one kind are logged as a warning naming the one used.

Timestamp domain (**refused when they differ**)
    The SDK stores each frame's clock in its metadata (key ``timestamp_domain``: ``Hardware
    Clock``, ``System Time`` or ``Global Time``). Frames and IMU samples stamped by different
    clocks cannot be synchronised (the offset between them is arbitrary), so a bag whose colour,
    depth, accelerometer and gyro streams report different domains — or a stream that changes
    domain during the recording — is refused with a :class:`SessionError` naming the domains.
    Record again with one clock for all sensors (e.g. enable "Global Time" on every sensor in
    RealSense Viewer). A bag without metadata (re-recorded with ROS tools) is accepted with an
    info message; a stream without metadata is assumed to share the others' clock (a warning).
    Only the first and last 64 metadata messages of each stream are read.
    The domain found is stored in the calibration's ``extra["timestamp_domain"]``
    (:mod:`gaitnet.io.realsense_calibration`).
"""

from __future__ import annotations

import logging
import re
from dataclasses import dataclass
from typing import Any

import numpy as np

from gaitnet.errors import SessionError
from gaitnet.io.bag_index import RosBag

__all__ = [
    "BagStreams",
    "Stream",
    "find_streams",
    "stream_fps",
    "timestamp_domain",
]

log = logging.getLogger(__name__)

_METADATA_PROBE = 64  # metadata messages read at each end of a stream to find its domain

_KIND_TO_MEDIUM = {"Depth": "image", "Color": "image", "Accel": "imu", "Gyro": "imu"}

_DATA_TOPIC = re.compile(
    r"^/device_(\d+)/sensor_(\d+)/(Depth|Color|Accel|Gyro)_(\d+)/(image|imu)/data$"
)
_KIND_NAME = {
    "Color": "colour image",
    "Depth": "depth image",
    "Accel": "accelerometer",
    "Gyro": "gyroscope",
}


@dataclass(frozen=True)
class Stream:
    """One SDK stream, ``/device_<device>/sensor_<sensor>/<kind>_<index>``.

    ``kind`` is ``Color``, ``Depth``, ``Accel`` or ``Gyro``.
    """

    kind: str
    device: int
    sensor: int
    index: int

    @property
    def name(self) -> str:
        """What the stream holds, for messages: ``colour image``, ``gyroscope``, …"""
        return _KIND_NAME[self.kind]

    @property
    def prefix(self) -> str:
        """The stream's topic prefix (its ``info``, ``tf`` … topics are below it)."""
        return f"/device_{self.device}/sensor_{self.sensor}/{self.kind}_{self.index}"

    @property
    def data_topic(self) -> str:
        """The topic of its images or IMU samples."""
        return f"{self.prefix}/{_KIND_TO_MEDIUM[self.kind]}/data"

    @property
    def metadata_topic(self) -> str:
        """The topic of its per-frame (per-sample) metadata key/value messages."""
        return f"{self.prefix}/{_KIND_TO_MEDIUM[self.kind]}/metadata"


@dataclass(frozen=True)
class BagStreams:
    """The four streams a session is read from, all of one device."""

    color: Stream
    depth: Stream
    accel: Stream
    gyro: Stream

    @property
    def all(self) -> tuple[Stream, Stream, Stream, Stream]:
        """Colour, depth, accelerometer and gyro, in that order."""
        return (self.color, self.depth, self.accel, self.gyro)


def find_streams(bag: RosBag) -> BagStreams:
    """The colour, depth, accelerometer and gyro streams of ``bag`` (module docstring).

    :class:`SessionError` naming the bag when a stream is missing.
    """
    found: dict[str, list[Stream]] = {k: [] for k in _KIND_TO_MEDIUM}
    for topic in bag.topics:
        m = _DATA_TOPIC.match(topic)
        if m and _KIND_TO_MEDIUM[m.group(3)] == m.group(5) and bag.count(topic):
            s = Stream(m.group(3), int(m.group(1)), int(m.group(2)), int(m.group(4)))
            found[s.kind].append(s)
    if not found["Color"]:
        raise SessionError(
            f"{bag.src}: no colour image topic with messages "
            "(expected /device_*/sensor_*/Color_*/image/data)"
        )
    color = min(found["Color"], key=lambda s: (s.device, s.index, s.sensor))
    chosen = {"Color": color}
    for kind in ("Depth", "Accel", "Gyro"):
        same = [s for s in found[kind] if s.device == color.device]
        if not same:
            raise SessionError(
                f"{bag.src}: no {_KIND_NAME[kind]} topic with messages for device "
                f"{color.device} (expected /device_{color.device}/sensor_*/{kind}_*/"
                f"{_KIND_TO_MEDIUM[kind]}/data)"
            )
        chosen[kind] = min(same, key=lambda s: (s.index, s.sensor))
    for kind, streams in found.items():
        if len(streams) > 1:
            log.warning(
                "%s: %d %s streams, using %s",
                bag.src,
                len(streams),
                _KIND_NAME[kind],
                chosen[kind].data_topic,
            )
    return BagStreams(chosen["Color"], chosen["Depth"], chosen["Accel"], chosen["Gyro"])


def stream_fps(bag: RosBag, stream: Stream, stream_info: Any | None) -> float | None:
    """A stream's rate (Hz): its StreamInfo ``fps``, else from the median record interval.

    ``stream_info`` is the stream's ``realsense_msgs/StreamInfo`` message (or None). None when
    neither gives a rate.
    """
    fps = getattr(stream_info, "fps", None) if stream_info is not None else None
    if fps is not None and float(fps) > 0:
        return float(fps)
    times = np.array([e.time for e in bag.refs(stream.data_topic)], dtype=np.int64)
    dt = np.diff(np.unique(times))
    if dt.size:
        return 1e9 / float(np.median(dt))
    return None


def _domains_of(bag: RosBag, stream: Stream) -> list[str]:
    """Timestamp domains named in the first and last metadata messages of a stream."""
    topic = stream.metadata_topic
    refs = bag.refs(topic)
    found: list[str] = []
    for probe in (refs[:_METADATA_PROBE], refs[::-1][:_METADATA_PROBE]):
        for ref in probe:
            msg = bag.decode(ref, topic)
            if getattr(msg, "key", None) == "timestamp_domain":
                found.append(str(getattr(msg, "value", "")))
                break
    return found


def timestamp_domain(bag: RosBag, streams: BagStreams) -> str | None:
    """The one clock of all four streams (module docstring); None without metadata.

    :class:`SessionError` naming the bag when the streams use different clocks or a stream
    changes clock during the recording.
    """
    domains: dict[str, str] = {}
    for s in streams.all:
        found = _domains_of(bag, s)
        if len(set(found)) > 1:
            raise SessionError(
                f"{bag.src}: the {s.name} timestamps change clock during the recording "
                f"({found[0]!r} → {found[-1]!r}); they cannot be synchronised"
            )
        if found:
            domains[s.kind] = found[0]
    if not domains:
        log.info("%s: no timestamp domain metadata; assuming one clock", bag.src)
        return None
    if len(set(domains.values())) > 1:
        listed = ", ".join(f"{_KIND_NAME[k]} {v!r}" for k, v in domains.items())
        raise SessionError(
            f"{bag.src}: streams are stamped by different clocks ({listed}) and cannot be "
            "synchronised; record with one clock for all sensors (e.g. enable "
            "'Global Time' on every sensor)"
        )
    missing = [_KIND_NAME[s] for s in ("Color", "Depth", "Accel", "Gyro") if s not in domains]
    if missing:
        log.warning(
            "%s: no timestamp domain for the %s stream(s); assuming %r like the others",
            bag.src,
            ", ".join(missing),
            next(iter(domains.values())),
        )
    return next(iter(domains.values()))
