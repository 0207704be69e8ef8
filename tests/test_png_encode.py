"""The PNG encoder: lossless for every image kind it accepts, by two independent decoders."""

from __future__ import annotations

import io
import struct
import zlib

import cv2
import numpy as np
import pytest
from PIL import Image

from gaitnet.io.images import encode_png, png_header

KINDS = [
    ((31, 17), np.uint8),  # label map: no filter, run-length coding
    ((31, 17), np.uint16),  # depth: Up filter
    ((31, 17, 3), np.uint8),  # colour: Average filter
    ((31, 17, 4), np.uint8),
    ((31, 17, 2), np.uint8),
    ((31, 17, 3), np.uint16),
    ((31, 17, 2), np.uint16),
    ((31, 17, 4), np.uint16),
    ((1, 1), np.uint8),
    ((1, 9, 3), np.uint8),  # one row: nothing above
    ((9, 1, 3), np.uint8),  # one column: nothing to the left
]


def _cv2_rgb(decoded: np.ndarray, channels: int) -> np.ndarray:
    if channels in (3, 4):
        order = [2, 1, 0, 3][:channels]
        return decoded[..., order]
    return decoded


# OpenCV expands grey + alpha to BGRA; Pillow checks that kind
@pytest.mark.parametrize("compress", [True, False])
@pytest.mark.parametrize(("shape", "dtype"), [k for k in KINDS if k[0][2:] != (2,)])
def test_round_trip_through_opencv(shape, dtype, compress) -> None:
    rng = np.random.default_rng(7)
    # noise, constant runs and the extremes, where the Average filter's sums overflow a byte
    image = rng.integers(0, np.iinfo(dtype).max + 1, shape, dtype=dtype)
    image[: shape[0] // 2, : max(1, shape[1] // 3)] = np.iinfo(dtype).max
    image[-1, -1] = 0
    png = encode_png(image, compress=compress)
    decoded = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_UNCHANGED)
    channels = 1 if image.ndim == 2 else shape[2]
    np.testing.assert_array_equal(_cv2_rgb(decoded, channels), image)


@pytest.mark.parametrize("compress", [True, False])
@pytest.mark.parametrize(
    ("shape", "dtype"), [k for k in KINDS if k[1] == np.uint8 or len(k[0]) == 2]
)
def test_round_trip_through_pillow(shape, dtype, compress) -> None:
    image = np.random.default_rng(8).integers(0, np.iinfo(dtype).max + 1, shape, dtype=dtype)
    decoded = np.asarray(Image.open(io.BytesIO(encode_png(image, compress=compress))))
    np.testing.assert_array_equal(decoded.astype(dtype), image)


def test_header_and_determinism(tmp_path) -> None:
    image = np.random.default_rng(9).integers(0, 65536, (12, 20), dtype=np.uint16)
    data = encode_png(image)
    assert data == encode_png(image.copy())
    path = tmp_path / "d.png"
    path.write_bytes(data)
    header = png_header(path)
    assert (header.width, header.height, header.bit_depth, header.channels) == (20, 12, 16, 1)
    assert header.complete


@pytest.mark.parametrize(
    "image",
    [np.zeros((4, 4), np.float32), np.zeros((4, 4, 5), np.uint8), np.zeros((0, 4), np.uint8)],
)
def test_refuses_what_png_cannot_hold(image) -> None:
    with pytest.raises(ValueError, match="cannot encode"):
        encode_png(image)


def _rows(png: bytes) -> bytes:
    """The inflated scanlines of a PNG with one IDAT chunk."""
    pos, data = 8, b""
    while pos < len(png):
        (length,) = struct.unpack(">I", png[pos : pos + 4])
        if png[pos + 4 : pos + 8] == b"IDAT":
            data += png[pos + 8 : pos + 8 + length]
        pos += 12 + length
    return zlib.decompress(data)


@pytest.mark.parametrize(
    ("shape", "dtype", "row_filter"),
    [((6, 5, 3), np.uint8, 3), ((6, 5), np.uint16, 2), ((6, 5), np.uint8, 0)],
)
def test_every_row_has_the_kinds_filter(shape, dtype, row_filter) -> None:
    """Average for colour, Up for 16-bit, none for label maps (PNG filter types 3, 2, 0)."""
    image = np.random.default_rng(4).integers(0, 200, shape, dtype=dtype)
    rows = _rows(encode_png(image))
    stride = 1 + image[0].nbytes
    assert len(rows) == shape[0] * stride
    assert {rows[k * stride] for k in range(shape[0])} == {row_filter}


@pytest.mark.parametrize(("shape", "dtype"), [((40, 30, 3), np.uint8), ((40, 30), np.uint16)])
def test_uncompressed_rows_are_the_raw_bytes_stored(shape, dtype) -> None:
    """compress=False: no row filter, the image's own bytes (16-bit big-endian) in stored
    deflate blocks, so the file is the raw image plus a few bytes per row and block."""
    image = np.random.default_rng(6).integers(0, np.iinfo(dtype).max + 1, shape, dtype=dtype)
    png = encode_png(image, compress=False)
    rows = _rows(png)
    raw = image.astype(">u2").tobytes() if dtype == np.uint16 else image.tobytes()
    stride = 1 + len(raw) // shape[0]
    assert b"".join(rows[k * stride + 1 : (k + 1) * stride] for k in range(shape[0])) == raw
    assert {rows[k * stride] for k in range(shape[0])} == {0}
    assert len(raw) < len(png) < len(raw) + shape[0] + 100
    ramp = np.add.outer(np.arange(shape[0]), np.arange(shape[1])).astype(dtype)
    smooth = np.broadcast_to(ramp.reshape(ramp.shape + (1,) * (len(shape) - 2)), shape)
    assert len(encode_png(smooth)) < len(encode_png(smooth, compress=False)) // 2


def test_views_encode_as_their_values() -> None:
    """Sliced and column-major arrays encode the values they show."""
    base = np.random.default_rng(5).integers(0, 256, (40, 30, 3), dtype=np.uint8)
    for view in (base[::2, 1::3], np.asfortranarray(base), base[:, :, :3][5:20]):
        decoded = cv2.imdecode(np.frombuffer(encode_png(view), np.uint8), cv2.IMREAD_UNCHANGED)
        np.testing.assert_array_equal(decoded[..., ::-1], view)
