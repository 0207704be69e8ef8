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


def encode_png(image: np.ndarray) -> bytes:
    """Lossless, deterministic PNG bytes of a uint8/uint16 image (colour given as RGB)."""
    if image.ndim == 3:
        image = image[:, :, ::-1]
    # One fixed PNG row filter instead of libpng's per-row choice (AVG for colour, UP for
    # 16-bit depth, none for label maps), then zlib's Huffman-only strategy for colour and
    # depth (camera noise leaves few repeats for LZ77 to find: files within 0.2 % of the RLE
    # strategy's, ~20 % faster) and RLE for label maps (long runs of one value); measured in
    # docs/benchmarks.md.
    if image.ndim == 3:
        row_filter, strategy = cv2.IMWRITE_PNG_FILTER_AVG, cv2.IMWRITE_PNG_STRATEGY_HUFFMAN_ONLY
    elif image.dtype == np.uint16:
        row_filter, strategy = cv2.IMWRITE_PNG_FILTER_UP, cv2.IMWRITE_PNG_STRATEGY_HUFFMAN_ONLY
    else:
        row_filter, strategy = cv2.IMWRITE_PNG_FILTER_NONE, cv2.IMWRITE_PNG_STRATEGY_RLE
    params = [cv2.IMWRITE_PNG_COMPRESSION, 3, cv2.IMWRITE_PNG_STRATEGY, strategy]
    params += [cv2.IMWRITE_PNG_FILTER, row_filter]
    ok, buf = cv2.imencode(".png", np.ascontiguousarray(image), params)
    if not ok:
        raise ValueError("PNG encoding failed")
    return buf.tobytes()


def depth_to_units(depth_m: np.ndarray, depth_scale_m: float) -> np.ndarray:
    """Metres → uint16 depth units; non-finite, non-positive or out-of-range depths become 0."""
    depth = np.asarray(depth_m, dtype=np.float64)
    units = np.round(np.where(np.isfinite(depth), depth, 0.0) / depth_scale_m)
    units[(units <= 0) | (units > 65535)] = 0
    return units.astype(np.uint16)
