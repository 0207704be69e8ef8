"""Read a RealSense SDK / Viewer recording (ROS1 ``.bag``) as a :class:`SessionSource`.

:class:`RealSenseBag` opens the bag, serves its frames (decoding the two messages of a frame,
aligning depth to colour) and reads its IMU. Its parts, one job each:

- :class:`gaitnet.io.bag_index.RosBag` — the file itself (index, positioned reads, decoding
  with the bag's own message definitions);
- :mod:`gaitnet.io.realsense_streams` — the SDK's topic layout, which streams are read, and
  their timestamp domain (one clock for all streams; **mixed clocks are refused**);
- :mod:`gaitnet.io.realsense_calibration` — intrinsics, extrinsics (read as documented in
  :mod:`gaitnet.io.realsense_extrinsics`), depth units, IMU noise: the
  :class:`SessionCalibration`;
- :mod:`gaitnet.io.realsense_frames` — the frame index: timestamps (``t_ns`` is the colour
  image's ``header.stamp``; damaged stamps refused), every image header checked at open,
  colour/depth pairing;
- :mod:`gaitnet.io.ros_image` (image messages become arrays),
  :func:`gaitnet.io.depth_align.align_depth_to_color` (depth re-projected onto colour) and
  :func:`gaitnet.io.imu_merge.merge_imu_streams` (accelerometer and gyro merged).

Laziness
    Opening reads the bag index, the few static messages (calibration, options), a few
    metadata messages per stream, and the first bytes of every image message (its header:
    stamp, size, encoding, step, data length); for uncompressed chunks these are small
    positioned reads, compressed chunks are decompressed once each. :meth:`RealSenseBag.frame`
    reads and decodes just the two messages of that frame. The IMU is read on first access to
    :attr:`RealSenseBag.imu`.

Frames
    ``rgb`` is uint8 RGB (``rgb8``, ``bgr8``, ``rgba8``, ``bgra8`` accepted); ``depth_m`` is
    float32 metres (``mono16`` / ``16UC1`` times the "Depth Units" option, default 0.001 m,
    with 65535 = no data; ``32FC1`` is taken as metres), 0 = invalid, always aligned to colour:
    a depth image of colour's size whose camera_info equals colour's is taken as aligned
    already, otherwise it is aligned here. The calibration therefore describes the delivered
    data (``depth`` intrinsics are the colour intrinsics; see
    :mod:`gaitnet.io.realsense_calibration`). The first frame's sizes must match the
    calibration, and every decoded frame must have the size of the first.

IMU
    Accelerometer and gyro samples use their ``header.stamp`` (checked against the record
    times like the frames' stamps) and are merged onto the gyro timestamps; a warning when the
    IMU does not cover the frames.

Errors (a missing colour, depth or IMU topic, an empty, unindexed or truncated bag, a file
that is not a bag, an unsupported image encoding, frames whose size changes, NaN or a
non-rigid transform in the tf, non-finite calibration values, damaged stamps or records,
mixed timestamp domains, physically impossible IMU values) raise :class:`SessionError` with a
one-line message that names the bag file.
"""

from __future__ import annotations

import logging
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from gaitnet.errors import SessionError
from gaitnet.io.bag_index import RosBag, parse_imu_payload
from gaitnet.io.depth_align import align_depth_to_color
from gaitnet.io.imu_merge import merge_imu_streams
from gaitnet.io.realsense_calibration import DEFAULT_DEPTH_UNITS_M, build_calibration, read_statics
from gaitnet.io.realsense_extrinsics import TF_REF_TO_STREAM, TF_STREAM_TO_REF
from gaitnet.io.realsense_frames import (
    STAMP_RECORD_TOLERANCE_S,
    build_frame_index,
    check_stamps,
    header_stamp,
)
from gaitnet.io.realsense_streams import Stream, find_streams, timestamp_domain
from gaitnet.io.ros_image import decode_color, decode_depth
from gaitnet.io.types import Frame, ImuSamples, SessionCalibration, rigid_transform

__all__ = [
    "DEFAULT_DEPTH_UNITS_M",
    "STAMP_RECORD_TOLERANCE_S",
    "TF_REF_TO_STREAM",
    "TF_STREAM_TO_REF",
    "RealSenseBag",
]

log = logging.getLogger(__name__)

_IMU_TYPE = "sensor_msgs/msg/Imu"


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
        streams = find_streams(self._bag)
        self._color, self._depth = streams.color, streams.depth
        self._accel, self._gyro = streams.accel, streams.gyro
        statics = read_statics(self._bag, streams)
        self._depth_units_m = statics.depth_units_m
        domain = timestamp_domain(self._bag, streams)
        index = build_frame_index(self._bag, self._color, self._depth, statics.stream_info["Color"])
        self._times = index.t_ns
        self._color_refs, self._depth_refs = index.color_refs, index.depth_refs
        calib = build_calibration(
            self._bag, streams, statics, self._tf_convention, T_CfromI_override, domain
        )
        self._calib = calib.session
        self._bag_depth_intr = calib.bag_depth
        self._depth_aligned = calib.depth_aligned
        self._T_CfromD = calib.T_CfromD
        self._check_first_frame()
        # Keep only the index of what is read later (the IMU, on first access).
        self._bag.keep_only({self._accel.data_topic, self._gyro.data_topic})

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

    def _decode(self, index: int, stream: Stream) -> np.ndarray:
        refs = self._color_refs if stream.kind == "Color" else self._depth_refs
        topic = stream.data_topic
        msg = self._bag.decode(refs[index], topic)
        what = f"{stream.name} of frame {index} (t_ns={int(self._times[index])})"
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
                    parsed = (header_stamp(msg), (vec.x, vec.y, vec.z))
            except ValueError as exc:
                raise self._error(f"IMU message on {topic}: {exc}") from None
            t[which].append(parsed[0])
            rec[which].append(ref.time)
            v[which].append(parsed[1])
        t_arr = [np.array(x, dtype=np.int64) for x in t]
        for which, s in enumerate(streams):
            # restore record-time order (jobs were read in file order) for the stamp check
            order = np.argsort(np.array(rec[which], dtype=np.int64), kind="stable")
            check_stamps(
                t_arr[which][order],
                np.array(rec[which], dtype=np.int64)[order],
                f"{s.name} sample",
                self._src,
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
