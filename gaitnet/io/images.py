"""PNG reading and writing for session frames, with errors that name the file.

Colour frames are 8-bit RGB PNGs; depth frames are 16-bit single-channel PNGs in units of the
session's depth scale (0 = invalid). :func:`png_header` reads only the 33-byte signature and
IHDR chunk plus the last 12 bytes, so a folder of thousands of frames can be checked for size,
type and truncation without decoding a pixel.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from zlib_ng import zlib_ng

from gaitnet.errors import SessionError

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
PNG_IEND = b"\x00\x00\x00\x00IEND\xaeB`\x82"
# PNG colour types: 0 gray, 2 RGB, 3 palette, 4 gray+alpha, 6 RGBA.
_CHANNELS = {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}


@dataclass(frozen=True)
class PngHeader:
    width: int
    height: int
    bit_depth: int
    channels: int
    complete: bool


def png_header(path: Path) -> PngHeader:
    """Size, bit depth and channel count of a PNG, and whether it ends with an IEND chunk."""
    try:
        with open(path, "rb") as handle:
            head = handle.read(33)
            handle.seek(0, 2)
            size = handle.tell()
            handle.seek(max(0, size - 12))
            tail = handle.read(12)
    except OSError as exc:
        raise SessionError(f"{path}: cannot read ({exc.strerror})") from exc
    if len(head) < 33 or head[:8] != PNG_SIGNATURE or head[12:16] != b"IHDR":
        raise SessionError(f"{path}: not a PNG file (bad signature or header)")
    width, height, bit_depth, colour_type = struct.unpack(">IIBB", head[16:26])
    return PngHeader(
        width=width,
        height=height,
        bit_depth=bit_depth,
        channels=_CHANNELS.get(colour_type, 0),
        complete=tail == PNG_IEND,
    )


def check_png(path: Path, width: int, height: int, bit_depth: int, channels: int) -> None:
    """Raise :class:`SessionError` unless the PNG is complete and has the expected layout."""
    h = png_header(path)
    if not h.complete:
        raise SessionError(f"{path}: truncated PNG (no IEND chunk at the end)")
    if (h.width, h.height) != (width, height):
        raise SessionError(
            f"{path}: image is {h.width}×{h.height}, expected {width}×{height} (session.yaml)"
        )
    if h.bit_depth != bit_depth or h.channels != channels:
        raise SessionError(
            f"{path}: {h.channels}-channel {h.bit_depth}-bit PNG, expected "
            f"{channels}-channel {bit_depth}-bit"
        )


def read_rgb(path: Path, width: int, height: int) -> np.ndarray:
    """Decode an 8-bit RGB PNG to an (H, W, 3) uint8 array in RGB order."""
    image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if image is None:
        raise SessionError(f"{path}: cannot decode colour image (corrupt or truncated PNG)")
    if image.dtype != np.uint8 or image.ndim != 3 or image.shape[2] != 3:
        raise SessionError(
            f"{path}: colour image must be 8-bit RGB, got {image.dtype} {image.shape}"
        )
    if image.shape[:2] != (height, width):
        raise SessionError(
            f"{path}: image is {image.shape[1]}×{image.shape[0]}, expected {width}×{height}"
        )
    return np.ascontiguousarray(image[:, :, ::-1])


def read_depth(path: Path, width: int, height: int, depth_scale_m: float) -> np.ndarray:
    """Decode a 16-bit depth PNG to float32 metres (0 = invalid)."""
    image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if image is None:
        raise SessionError(f"{path}: cannot decode depth image (corrupt or truncated PNG)")
    if image.dtype != np.uint16 or image.ndim != 2:
        raise SessionError(
            f"{path}: depth image must be single-channel 16-bit, got {image.dtype} {image.shape}"
        )
    if image.shape != (height, width):
        raise SessionError(
            f"{path}: depth image is {image.shape[1]}×{image.shape[0]}, expected {width}×{height}"
        )
    return image.astype(np.float32) * np.float32(depth_scale_m)


# PNG filter types (PNG spec sec. 9.2) and the colour type per channel count.
_FILTER_NONE, _FILTER_UP, _FILTER_AVERAGE = 0, 2, 3
_COLOUR_TYPE = {1: 0, 2: 4, 3: 2, 4: 6}


def _png_chunk(kind: bytes, data: bytes) -> bytes:
    return (
        struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib_ng.crc32(kind + data))
    )


def _filtered_rows(image: np.ndarray, compress: bool = True) -> tuple[np.ndarray, int]:
    """The PNG scanlines of ``image`` (H, W[, C]) with one fixed filter, a filter-type byte in
    front of each row; also the deflate strategy that suits the filter.

    8-bit colour: Average (each byte minus the floor-mean of the byte one pixel left and the
    byte above, both unfiltered) with Huffman-only coding (camera noise leaves few repeats for
    LZ77 to find); 16-bit: Up (big-endian bytes minus those above), Huffman-only; 8-bit
    single-channel (label maps) and anything not to ``compress``: no filter, run-length coding
    (long runs of one value; unused when the rows are stored)."""
    height = image.shape[0]
    channels = 1 if image.ndim == 2 else image.shape[2]
    if image.dtype == np.uint16:
        raw = image.astype(">u2").view(np.uint8).reshape(height, -1)
    else:
        raw = image.reshape(height, -1)
    if not compress or (image.dtype == np.uint8 and channels == 1):
        body, kind, strategy = raw, _FILTER_NONE, zlib_ng.Z_RLE
    elif image.dtype == np.uint16:
        kind, strategy = _FILTER_UP, zlib_ng.Z_HUFFMAN_ONLY
        body = raw.copy()
        body[1:] -= raw[:-1]
    else:
        kind, strategy = _FILTER_AVERAGE, zlib_ng.Z_HUFFMAN_ONLY
        pair = np.zeros(raw.shape, np.uint16)
        pair[:, channels:] = raw[:, :-channels]
        pair[1:] += raw[:-1]
        pair >>= 1
        body = raw - pair.astype(np.uint8)
    rows = np.empty((height, body.shape[1] + 1), np.uint8)
    rows[:, 0] = kind
    rows[:, 1:] = body
    return rows, strategy


def encode_png(image: np.ndarray, compress: bool = True) -> bytes:
    """Lossless, deterministic PNG bytes of a uint8/uint16 image of 1–4 channels (colour given
    as RGB[A]); not ``compress``: the rows stored unfiltered in uncompressed deflate blocks
    (as large as the raw image, like a RealSense recording, but about ten times faster to
    write and six times faster to read: ``benchmarks/bench_png.py``, docs/benchmarks.md).

    One fixed row filter per image kind (:func:`_filtered_rows`) and zlib-ng's deflate at
    level 3, about twice as fast as libpng with zlib for the same files (docs/benchmarks.md);
    every PNG reader decodes them. Compression releases the GIL, so encoding on a thread
    overlaps with other work."""
    image = np.asarray(image)
    channels = 1 if image.ndim == 2 else (image.shape[2] if image.ndim == 3 else 0)
    if image.dtype not in (np.uint8, np.uint16) or channels not in _COLOUR_TYPE or 0 in image.shape:
        raise ValueError(f"cannot encode a {image.dtype} {image.shape} image as PNG")
    rows, strategy = _filtered_rows(image, compress)
    deflate = zlib_ng.compressobj(3 if compress else 0, zlib_ng.DEFLATED, 15, 8, strategy)
    data = deflate.compress(rows) + deflate.flush()
    height, width = image.shape[:2]
    bit_depth = 16 if image.dtype == np.uint16 else 8
    header = struct.pack(">IIBBBBB", width, height, bit_depth, _COLOUR_TYPE[channels], 0, 0, 0)
    return PNG_SIGNATURE + _png_chunk(b"IHDR", header) + _png_chunk(b"IDAT", data) + PNG_IEND


def depth_to_units(depth_m: np.ndarray, depth_scale_m: float) -> np.ndarray:
    """Metres → uint16 depth units; non-finite, non-positive or out-of-range depths become 0."""
    scaled = np.divide(depth_m, depth_scale_m, dtype=np.float64)
    np.rint(scaled, out=scaled)  # half to even, as np.round
    valid = (scaled > 0) & (scaled <= 65535)  # NaN compares false
    with np.errstate(invalid="ignore"):  # the invalid ones cast to garbage, then to 0
        units = scaled.astype(np.uint16)
    units[~valid] = 0
    return units
