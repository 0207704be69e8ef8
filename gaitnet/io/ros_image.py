"""ROS ``sensor_msgs/Image`` messages → numpy colour and depth images, with strict checks.

:func:`parse_image_head` reads the fields in front of the pixel data of a standard ROS1
``sensor_msgs/Image`` payload (stamp, size, encoding, step, data length) from its first bytes,
so a reader can check every frame of a recording without reading its pixels.
:func:`decode_color` and :func:`decode_depth` turn decoded messages into arrays.

Checks (each a :class:`ValueError` whose message says what is wrong; readers add the file and
frame): the data length must equal ``step · height`` (no more, no less: a message with a
different length is damaged), ``step`` must hold a row, the encoding must be a supported one.

Depth: ``mono16`` / ``16UC1`` values times the depth units; 0 and 65535 are invalid (0 m) —
65535 is the RealSense "no data" code of some modes, not 65.535 m. ``32FC1`` is metres;
non-finite and negative values are invalid.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Any

import numpy as np

from gaitnet.io.bag_index import stamp_ns

COLOR_ENCODINGS = {  # encoding -> (channels, indices of R, G, B)
    "rgb8": (3, (0, 1, 2)),
    "bgr8": (3, (2, 1, 0)),
    "rgba8": (4, (0, 1, 2)),
    "bgra8": (4, (2, 1, 0)),
}
DEPTH_ENCODINGS = {"mono16": "u2", "16uc1": "u2", "32fc1": "f4"}
DEPTH_NO_DATA = 65535
"""16-bit depth value the RealSense SDK writes where it has no measurement (invalid)."""
HEAD_BYTES = 512
"""Bytes of a payload that :func:`parse_image_head` needs at most (short frame id/encoding)."""


@dataclass(frozen=True)
class ImageHead:
    """The fields of a ``sensor_msgs/Image`` in front of its pixels."""

    t_ns: int
    height: int
    width: int
    encoding: str
    is_bigendian: bool
    step: int
    data_len: int
    data_offset: int

    @property
    def payload_len(self) -> int:
        """Length of the whole serialized message these fields describe."""
        return self.data_offset + self.data_len

    def layout(self) -> tuple[int, int, str, bool, int]:
        """What must stay the same from frame to frame of one stream."""
        return (self.height, self.width, self.encoding.lower(), self.is_bigendian, self.step)


def parse_image_head(raw: bytes) -> ImageHead | None:
    """Parse the leading fields of a standard ROS1 ``sensor_msgs/Image`` payload.

    None when ``raw`` is too short to hold them (a longer prefix is needed); ``ValueError``
    when the fields are malformed (strings running past the payload, an invalid stamp).
    """
    try:
        _, sec, nsec, n_id = struct.unpack_from("<IIII", raw, 0)
        pos = 16 + n_id
        height, width, n_enc = struct.unpack_from("<III", raw, pos)
        pos += 12
        if pos + n_enc > len(raw):
            return None
        encoding = raw[pos : pos + n_enc].decode("ascii")
        pos += n_enc
        bigendian, step, data_len = struct.unpack_from("<BII", raw, pos)
        pos += 9
    except struct.error:
        return None
    except UnicodeDecodeError:
        raise ValueError("image encoding is not ASCII text") from None
    return ImageHead(
        stamp_ns(sec, nsec), height, width, encoding, bool(bigendian), step, data_len, pos
    )


def check_layout(head: ImageHead | Any, channels: int, itemsize: int) -> None:
    """``ValueError`` unless size, step and data length of an image fit together."""
    h, w, step = int(head.height), int(head.width), int(head.step)
    n = int(head.data_len) if isinstance(head, ImageHead) else len(head.data)
    row = w * channels * itemsize
    if h <= 0 or w <= 0:
        raise ValueError(f"image size {w}×{h}")
    if step < row:
        raise ValueError(f"row step {step} bytes is shorter than a row of {w} pixels ({row} bytes)")
    if n != step * h:
        raise ValueError(f"{n} bytes of pixel data, expected {step * h} for {w}×{h} (step {step})")


def color_format(encoding: str) -> tuple[int, tuple[int, int, int]]:
    """Channels and R, G, B channel indices of a colour encoding; ``ValueError`` if unsupported."""
    fmt = COLOR_ENCODINGS.get(encoding.lower())
    if fmt is None:
        raise ValueError(
            f"unsupported colour encoding {encoding!r} (supported: {', '.join(COLOR_ENCODINGS)})"
        )
    return fmt


def depth_format(encoding: str, is_bigendian: bool) -> np.dtype:
    """The pixel dtype of a depth encoding; ``ValueError`` if unsupported."""
    kind = DEPTH_ENCODINGS.get(encoding.lower())
    if kind is None:
        raise ValueError(
            f"unsupported depth encoding {encoding!r} (supported: mono16, 16UC1, 32FC1)"
        )
    return np.dtype((">" if is_bigendian else "<") + kind)


def _pixels(msg: Any, channels: int, itemsize: int) -> np.ndarray:
    check_layout(msg, channels, itemsize)
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    data = np.asarray(msg.data, dtype=np.uint8).ravel()
    return data.reshape(h, step)[:, : w * channels * itemsize]


def decode_color(msg: Any) -> np.ndarray:
    """(H, W, 3) uint8 RGB of a decoded colour ``sensor_msgs/Image``."""
    channels, rgb_idx = color_format(str(msg.encoding))
    px = _pixels(msg, channels, 1).reshape(int(msg.height), int(msg.width), channels)
    return np.ascontiguousarray(px[:, :, list(rgb_idx)])


def decode_depth(msg: Any, depth_units_m: float) -> np.ndarray:
    """(H, W) float32 metres of a decoded depth ``sensor_msgs/Image``, 0 where invalid."""
    dtype = depth_format(str(msg.encoding), bool(msg.is_bigendian))
    px = _pixels(msg, 1, dtype.itemsize)
    values = np.ascontiguousarray(px).view(dtype).reshape(int(msg.height), int(msg.width))
    if dtype.kind == "u":
        depth = (values.astype(np.float64) * depth_units_m).astype(np.float32)
        depth[values == DEPTH_NO_DATA] = 0.0
        return depth
    depth = values.astype(np.float32)
    depth[~np.isfinite(depth) | (depth < 0)] = 0.0
    return depth
