"""The frame index of a RealSense SDK ``.bag``: colour/depth pairs, with stamp and layout checks.

:func:`build_frame_index` reads the header of every colour and depth image message (only its
first bytes: stamp, size, encoding, step, data length; for uncompressed chunks these are small
positioned reads, compressed chunks are decompressed once each), checks them, and pairs the
two streams. :class:`gaitnet.io.realsense_bag.RealSenseBag` decodes the pairs on demand.

Timestamps
    A frame's ``t_ns`` is the colour image's ``header.stamp`` (the SDK writes the device frame
    timestamp there; the bag's own record time is the host capture time since the recording
    started and is not used). IMU samples use their ``header.stamp`` too. Every stamp must
    stay within :data:`STAMP_RECORD_TOLERANCE_S` of where its record time puts it (header
    stamp minus record time is a constant offset up to USB latency), which catches damaged
    stamps (:func:`check_stamps`, for frames and IMU samples); frames a little out of order are
    sorted with a warning, frames with a repeated stamp dropped with a warning.

Pairing
    Colour and depth frames are paired by nearest header stamp; pairs further apart than half
    the colour frame period (the median colour stamp interval; for a single frame the stream's
    rate, else 30 fps) are dropped with a warning. One depth frame serves at most one colour
    frame (the nearest; ties: the earlier).

Layout
    Every frame of a stream must have the size, encoding and row step of the first and exactly
    ``step · height`` bytes of pixels (:func:`gaitnet.io.ros_image.check_layout`), and its
    encoding must be a supported one. A message whose length differs from what its fields
    describe is damaged.

Errors raise :class:`SessionError` with a one-line message that names the bag file.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Any

import numpy as np

from gaitnet.errors import SessionError
from gaitnet.io.bag_index import MessageRef, RosBag, stamp_ns
from gaitnet.io.realsense_streams import Stream, stream_fps
from gaitnet.io.ros_image import (
    HEAD_BYTES,
    ImageHead,
    check_layout,
    color_format,
    depth_format,
    parse_image_head,
)

__all__ = [
    "STAMP_RECORD_TOLERANCE_S",
    "FrameIndex",
    "build_frame_index",
    "check_stamps",
    "header_stamp",
]

log = logging.getLogger(__name__)

STAMP_RECORD_TOLERANCE_S = 1.0
"""How far (s) a header stamp may stray from the offset its record time implies."""

_IMAGE_TYPE = "sensor_msgs/msg/Image"


@dataclass(frozen=True)
class FrameIndex:
    """The paired frames: colour header stamps (ns, increasing) and each pair's messages."""

    t_ns: np.ndarray
    color_refs: list[MessageRef]
    depth_refs: list[MessageRef]


def header_stamp(msg: Any) -> int:
    """Nanoseconds of a decoded message's ``header.stamp`` (ROS1 ``nsec`` or ROS2 ``nanosec``).

    ``ValueError`` for an invalid stamp.
    """
    stamp = msg.header.stamp
    nsec = getattr(stamp, "nanosec", None)
    return stamp_ns(stamp.sec, stamp.nsec if nsec is None else nsec)


def check_stamps(t: np.ndarray, record: np.ndarray, what: str, src: str) -> None:
    """Header stamps ``t`` must follow the record times (damaged stamps are refused).

    ``t`` and ``record`` (ns) are in record order; ``what`` names one item in the message
    (``colour image frame``), ``src`` the bag. :class:`SessionError` for a stamp more than
    :data:`STAMP_RECORD_TOLERANCE_S` away from the median offset.
    """
    if t.shape[0] == 0:
        return
    offset = t - record
    median = int(np.median(offset))
    off = np.abs(offset - median) > STAMP_RECORD_TOLERANCE_S * 1e9
    if off.any():
        k = int(np.flatnonzero(off)[0])
        raise SessionError(
            f"{src}: {what} {k} has header stamp {int(t[k])} ns, "
            f"{(offset[k] - median) * 1e-9:+.3f} s away from where its record time puts it "
            "(damaged stamps?)"
        )


def _heads(bag: RosBag, refs: list[MessageRef], stream: Stream) -> list[ImageHead]:
    """The header fields of every image message (only their first bytes are read)."""
    topic = stream.data_topic
    heads: list[ImageHead | None] = [None] * len(refs)
    order = sorted(range(len(refs)), key=lambda k: (refs[k].chunk_pos, refs[k].offset))
    fast: dict[int, bool] = {}
    for k in order:
        ref = refs[k]
        if ref.conn not in fast:
            fast[ref.conn] = bag.is_standard(ref.conn, _IMAGE_TYPE)
        try:
            if fast[ref.conn]:
                raw, total = bag.read_head(ref, HEAD_BYTES)
                head = parse_image_head(raw)
                if head is None:
                    raise ValueError(f"message of {total} bytes is too short for an image")
                if head.payload_len != total:
                    raise ValueError(
                        f"message is {total} bytes but its fields describe "
                        f"{head.payload_len} ({head.data_len} bytes of pixels)"
                    )
            else:
                msg = bag.decode(ref, topic)
                head = ImageHead(
                    header_stamp(msg),
                    int(msg.height),
                    int(msg.width),
                    str(msg.encoding),
                    bool(msg.is_bigendian),
                    int(msg.step),
                    len(msg.data),
                    0,
                )
        except ValueError as exc:
            raise SessionError(f"{bag.src}: {stream.name} message {k} on {topic}: {exc}") from None
        heads[k] = head
    return heads  # type: ignore[return-value]


def _check_layouts(heads: list[ImageHead], stream: Stream, src: str) -> None:
    what = stream.name
    first = heads[0]
    try:
        if stream.kind == "Color":
            channels, itemsize = color_format(first.encoding)[0], 1
        else:
            channels, itemsize = 1, depth_format(first.encoding, first.is_bigendian).itemsize
    except ValueError as exc:
        raise SessionError(f"{src}: {exc} on {stream.data_topic}") from None
    for k, head in enumerate(heads):
        if head.layout() != first.layout():
            raise SessionError(
                f"{src}: {what} frame {k} (t_ns={head.t_ns}) is {head.width}×{head.height} "
                f"{head.encoding} (step {head.step}) but frame 0 is {first.width}×"
                f"{first.height} {first.encoding} (step {first.step}); frames may not "
                "change size or format"
            )
        try:
            check_layout(head, channels, itemsize)
        except ValueError as exc:
            raise SessionError(f"{src}: {what} frame {k} (t_ns={head.t_ns}): {exc}") from None


def _sorted_frames(bag: RosBag, stream: Stream) -> tuple[np.ndarray, list[MessageRef]]:
    """Header stamps (increasing, unique) and references of one image stream."""
    refs = bag.refs(stream.data_topic)
    heads = _heads(bag, refs, stream)
    _check_layouts(heads, stream, bag.src)
    what = f"{stream.name} frame"
    t = np.array([h.t_ns for h in heads], dtype=np.int64)
    check_stamps(t, np.array([r.time for r in refs], dtype=np.int64), what, bag.src)
    back = np.flatnonzero(np.diff(t) < 0)
    if back.size:
        log.warning(
            "%s: %d %s(s) out of order by up to %.1f ms; sorted by header stamp",
            bag.src,
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
            bag.src,
            int((~keep).sum()),
            what,
        )
    return t[keep], [refs[i] for i in order[keep]]


def build_frame_index(
    bag: RosBag, color: Stream, depth: Stream, color_info: Any | None
) -> FrameIndex:
    """The checked, paired frames of the ``color`` and ``depth`` streams (module docstring).

    ``color_info`` is the colour stream's ``realsense_msgs/StreamInfo`` (or None), for the
    frame period of a single-frame bag. :class:`SessionError` naming the bag for a damaged or
    inconsistent frame, or when no colour frame has a depth partner.
    """
    tc, color_refs = _sorted_frames(bag, color)
    td, depth_refs = _sorted_frames(bag, depth)

    if tc.shape[0] > 1:
        period_ns = float(np.median(np.diff(tc)))
    else:
        fps = stream_fps(bag, color, color_info) or 30.0
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
            bag.src,
            n_color_drop,
            n_depth_drop,
            tol_ns * 1e-6,
        )
    if color_idx.shape[0] == 0:
        raise SessionError(
            f"{bag.src}: no colour frame has a depth frame within half a frame period"
        )
    return FrameIndex(
        tc[color_idx],
        [color_refs[i] for i in color_idx],
        [depth_refs[int(match[i])] for i in color_idx],
    )
