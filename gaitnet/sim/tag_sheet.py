"""AprilTag sheets: A3 paper with a grid of tag36h11 tags, as high-resolution floor decals.

A :class:`TagSheet` is stored at 0.5 mm texels (:data:`SHEET_TEXEL_M`) so the tag cells stay
sharp whatever the floor's texel size, as linear reflectance (float32) so that every average
taken over it — the mip levels and the renderer's average over each pixel's footprint — is an
average of light, as a camera pixel takes it (averaging sRGB codes darkens every mixed texel).
The renderer composites the sheets over the floor (:mod:`gaitnet.sim.render_env`) with
:func:`sheet_overlay`, the camera's integral of the printed pattern over each pixel.

The tag corner convention is :class:`gaitnet.io.types.AprilTagBoard`'s
(:func:`gaitnet.io.types.tag_corners_in_board`).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from gaitnet.errors import InputError
from gaitnet.io.types import AprilTagBoard
from gaitnet.sim.mipmap import build_pyramid, sample_mipmapped

Extent = tuple[tuple[float, float], tuple[float, float]]
F32 = NDArray[np.float32]

A3_PAPER_M = (0.420, 0.297)
SHEET_TEXEL_M = 0.0005
# Matte laser print on white office paper: paper ~80 % diffuse reflectance, black toner ~5 %
# (docs/references.md, "Simulator realism: rendering"); the paper's slight warm tint is kept.
PAPER_REFLECTANCE = 0.80
INK_REFLECTANCE = 0.05
PAPER_TINT = (1.0, 0.99, 0.95)


@dataclass(frozen=True, eq=False)
class TagSheet:
    """A printed sheet (decal) lying on the floor, in its board frame (see module docstring).

    ``levels`` is a pyramid of linear reflectance (float32, single channel; the colour is
    reflectance × ``tint``); ``levels[0]`` row ``i`` covers board ``y ∈ y1 - [i, i+1]·τ`` and
    column ``j`` covers ``x ∈ x0 + [j, j+1]·τ`` (the page as seen from above),
    ``(x0, x1), (y0, y1) = extent_b``.
    """

    name: str
    T_WfromBoard: np.ndarray
    extent_b: Extent
    texel_m: float
    levels: tuple[NDArray[np.float32], ...]
    tint: tuple[float, float, float] = PAPER_TINT


def _sheet_extent(board: AprilTagBoard, margin_m: float = 0.01) -> Extent:
    """A3 paper centred on the tag grid (long side along the longer grid side)."""
    s, g = board.tag_size_m, board.gap_m
    gw = board.cols * s + (board.cols - 1) * g
    gh = board.rows * s + (board.rows - 1) * g
    long_, short = A3_PAPER_M
    pw, ph = (long_, short) if gw >= gh else (short, long_)
    pw, ph = max(pw, gw + 2 * margin_m), max(ph, gh + 2 * margin_m)
    return ((gw - pw) / 2, (gw + pw) / 2), ((gh - ph) / 2, (gh + ph) / 2)


def _overlap(starts_tex: np.ndarray, tau: float, cell_starts: np.ndarray, w: float) -> np.ndarray:
    """Fraction of each texel interval ``[a, a+τ]`` covered by each cell ``[c, c+w]``."""
    a = starts_tex[:, None]
    c = cell_starts[None, :]
    return np.clip(np.minimum(a + tau, c + w) - np.maximum(a, c), 0.0, None) / tau


def _marker_bits(tag_id: int) -> np.ndarray:
    """8×8 cells of a tag36h11 marker (1 = black), rows top to bottom as read."""
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11)
    if not 0 <= tag_id < dictionary.bytesList.shape[0]:
        raise ValueError(f"tag36h11 has no id {tag_id}")
    img = cv2.aruco.generateImageMarker(dictionary, tag_id, 8, borderBits=1)
    return (img < 128).astype(np.float64)


def _sheet_blackness(board: AprilTagBoard, extent: Extent, tau: float) -> np.ndarray:
    """Exact box-filtered ink coverage of each sheet texel (rows along −y_b)."""
    (x0, x1), (y0, y1) = extent
    w, h = round((x1 - x0) / tau), round((y1 - y0) / tau)
    ink = np.zeros((h, w))
    cell = board.tag_size_m / 8
    for k in range(board.rows * board.cols):
        tag_id = board.first_id + k
        cx, cy, _ = board.tag_centre_in_board(tag_id)
        half = board.tag_size_m / 2
        c0, c1 = int((cx - half - x0) / tau) - 1, int((cx + half - x0) / tau) + 2
        r0, r1 = int((y1 - cy - half) / tau) - 1, int((y1 - cy + half) / tau) + 2
        c0, r0, c1, r1 = max(c0, 0), max(r0, 0), min(c1, w), min(r1, h)
        tex_x = x0 + np.arange(c0, c1) * tau
        tex_ny = -(y1 - np.arange(r0, r1) * tau)  # texel rows as intervals of −y
        cells_x = cx - half + np.arange(8) * cell
        cells_ny = -(cy + half) + np.arange(8) * cell  # marker row k spans −y ∈ [.., .. + cell]
        Ox = _overlap(tex_x, tau, cells_x, cell)
        Oy = _overlap(tex_ny, tau, cells_ny, cell)
        ink[r0:r1, c0:c1] += Oy @ _marker_bits(tag_id) @ Ox.T
    return np.clip(ink, 0.0, 1.0)


#: Paper sizes [m] (long side, short side) that :func:`printable_sheet` lays a board out on.
PAPER_SIZES_M = {"a4": (0.297, 0.210), "a3": A3_PAPER_M, "letter": (0.2794, 0.2159)}
PRINT_MARGIN_M = 0.01  # white paper kept around the tag grid (a quiet zone for detection)
TAG36H11_IDS = 587  # the family's size (OpenCV's DICT_APRILTAG_36h11)


def printable_sheet(board: AprilTagBoard, paper: str = "a4", dpi: int = 300) -> np.ndarray:
    """``board``'s tags on a page of ``paper`` (:data:`PAPER_SIZES_M`, portrait or landscape as
    the grid is) at ``dpi``, as seen from above when it lies on the floor in its board frame:
    a uint8 image (255 paper, 0 ink; each pixel the exact box-filtered ink coverage), to print
    at 100 %. A grid that does not fit on the page with :data:`PRINT_MARGIN_M` around it raises
    :class:`~gaitnet.errors.InputError`."""
    if paper not in PAPER_SIZES_M:
        raise InputError(f"paper {paper!r}: expected one of {', '.join(PAPER_SIZES_M)}")
    if not 50 <= dpi <= 2400:
        raise InputError(f"dpi {dpi}: expected 50–2400")
    if board.family.replace("_", "").lower() not in ("tag36h11", "apriltag36h11"):
        raise InputError(f"board {board.name!r}: only tag36h11 is printed, got {board.family!r}")
    last = board.first_id + board.rows * board.cols - 1
    if last >= TAG36H11_IDS:
        raise InputError(
            f"tag ids {board.first_id}–{last}: tag36h11 has ids 0–{TAG36H11_IDS - 1} only"
        )
    s, g = board.tag_size_m, board.gap_m
    gw = board.cols * s + (board.cols - 1) * g
    gh = board.rows * s + (board.rows - 1) * g
    long_, short = PAPER_SIZES_M[paper]
    pw, ph = (long_, short) if gw >= gh else (short, long_)
    if gw + 2 * PRINT_MARGIN_M > pw or gh + 2 * PRINT_MARGIN_M > ph:
        raise InputError(
            f"{board.rows}×{board.cols} tags of {1000 * s:g} mm with {1000 * g:g} mm gaps are "
            f"{1000 * gw:.0f} × {1000 * gh:.0f} mm: they do not fit on {paper.upper()} "
            f"({1000 * pw:.0f} × {1000 * ph:.0f} mm) with {1000 * PRINT_MARGIN_M:g} mm margins"
        )
    tau = 0.0254 / dpi
    extent = ((gw - pw) / 2, (gw + pw) / 2), ((gh - ph) / 2, (gh + ph) / 2)
    ink = _sheet_blackness(board, extent, tau)
    return np.round(255.0 * (1.0 - ink)).astype(np.uint8)


def _check_board_on_floor(board: AprilTagBoard) -> np.ndarray:
    T = np.asarray(board.T_WfromBoard, dtype=np.float64)
    if T.shape != (4, 4):
        raise ValueError(f"board {board.name!r}: T_WfromBoard must be 4x4")
    if abs(T[2, 3]) > 0.01 or T[2, 2] < 0.999:
        raise ValueError(
            f"board {board.name!r} must lie face up on the floor (board z = world z, height 0); "
            f"got z axis {T[:3, 2].round(3).tolist()} and height {T[2, 3]:.3f} m"
        )
    if board.family.replace("_", "").lower() not in ("tag36h11", "apriltag36h11"):
        raise ValueError(f"board {board.name!r}: only tag36h11 is rendered, got {board.family!r}")
    return T


def make_tag_sheet(
    board: AprilTagBoard, rng: np.random.Generator, texel_m: float = SHEET_TEXEL_M
) -> TagSheet:
    """Render ``board`` as an A3 sheet of white paper with its tags (module docstring frames):
    linear reflectance, exact box-filtered ink coverage per texel."""
    T = _check_board_on_floor(board)
    extent = _sheet_extent(board)
    ink = _sheet_blackness(board, extent, texel_m).astype(np.float32)
    shape = ink.shape
    paper = np.float32(PAPER_REFLECTANCE * rng.uniform(0.95, 1.05))
    grain = 1.0 + 0.01 * cv2.GaussianBlur(rng.standard_normal(shape, np.float32), (0, 0), 3.0) * 6
    reflectance = paper * grain * (1 - ink) + np.float32(INK_REFLECTANCE) * ink
    levels = build_pyramid(reflectance.astype(np.float32), texel_m)
    return TagSheet(board.name, T, extent, texel_m, levels)


# ----------------------------------------------------------------------------- rendering


SHEET_SUPERSAMPLE = 4  # sub-pixel samples per pixel side on the tag sheets (4 × 4 per pixel)


def board_homography(K: np.ndarray, T_CfromW: np.ndarray, T_WfromBoard: np.ndarray) -> np.ndarray:
    """3×3 map from pixel ``(u, v, 1)`` to board-plane ``(x_b, y_b, 1)`` (up to scale) of a
    sheet lying in its board's z = 0 plane, for a camera ``K``, ``T_CfromW``."""
    T = T_CfromW @ T_WfromBoard
    H_pix_from_board = K @ np.stack([T[:3, 0], T[:3, 1], T[:3, 3]], axis=1)
    return np.linalg.inv(H_pix_from_board)


def sheet_overlay(
    sheet: TagSheet, K: np.ndarray, T_CfromW: np.ndarray, reg: tuple[slice, slice], lod: F32,
    lod_bias: float, floor_texel: float, light_rgb: tuple,
) -> tuple[F32, F32]:  # fmt: skip
    """Linear colour of ``sheet`` over the pixel region ``reg`` and the fraction of each pixel
    it covers, both averaged over each pixel's footprint. ``lod`` is the floor's per-pixel
    level of detail over ``reg``, ``lod_bias`` the renderer's bias of it, ``floor_texel`` the
    floor's texel size [m].

    A camera pixel integrates the printed pattern over its area (box filter): the region is
    sampled on a grid of :data:`SHEET_SUPERSAMPLE` × :data:`SHEET_SUPERSAMPLE` sub-pixel
    points mapped exactly onto the sheet (a homography, so perspective is exact inside the
    pixel); each point reads the sheet's linear-reflectance pyramid at the level of detail of
    its own sub-pixel footprint, and the samples are averaged (``cv2.INTER_AREA``), which is
    what the sensor integrates. The previous renderer read one point per pixel from an sRGB
    pyramid at a biased, blurrier level, which turned the tags' black borders mid-grey at
    640×480.
    """
    n = SHEET_SUPERSAMPLE
    rv, ru = reg
    h, w = rv.stop - rv.start, ru.stop - ru.start
    sub = (np.arange(n, dtype=np.float64) + 0.5) / n - 0.5
    us = (ru.start + np.arange(w)[:, None] + sub[None, :]).ravel()
    vs = (rv.start + np.arange(h)[:, None] + sub[None, :]).ravel()
    H = board_homography(K, T_CfromW, sheet.T_WfromBoard)
    (sx0, sx1), (sy0, sy1) = sheet.extent_b
    inv = 1.0 / sheet.texel_m
    # pixel -> texel column / row, both linear in (u, v, 1) up to the common denominator
    A = np.array([[inv, 0.0, -sx0 * inv - 0.5], [0.0, -inv, sy1 * inv - 0.5], [0.0, 0.0, 1.0]])
    M = A @ H
    cu = (M[:, 0:1] * us[None, :]).astype(np.float32)  # (3, w n)
    cv_ = (M[:, 1:2] * vs[None, :] + M[:, 2:3]).astype(np.float32)  # (3, h n)
    den = cv_[2][:, None] + cu[2][None, :]
    front = den > 0
    with np.errstate(divide="ignore", invalid="ignore"):
        rden = np.where(front, np.float32(1.0) / den, np.float32(0.0))
    col = (cv_[0][:, None] + cu[0][None, :]) * rden
    row = (cv_[1][:, None] + cu[1][None, :]) * rden
    nx, ny = sheet.levels[0].shape[1], sheet.levels[0].shape[0]
    inside = front & (col >= -0.5) & (col <= nx - 0.5) & (row >= -0.5) & (row <= ny - 0.5)
    col[~inside] = -1.0
    row[~inside] = -1.0
    # per-pixel level of detail of the floor -> of the sheet, minus the sub-sampling
    slod = lod - np.float32(lod_bias + np.log2(n) - np.log2(floor_texel / sheet.texel_m))
    slod = cv2.resize(slod, (w * n, h * n), interpolation=cv2.INTER_NEAREST)
    refl = sample_mipmapped(sheet.levels, col, row, slod, border=cv2.BORDER_REPLICATE)
    refl *= inside
    mean = cv2.resize(refl, (w, h), interpolation=cv2.INTER_AREA)
    cover = cv2.resize(inside.astype(np.float32), (w, h), interpolation=cv2.INTER_AREA)
    mean /= np.maximum(cover, np.float32(1e-6))
    tint = np.asarray(sheet.tint, np.float32) * np.asarray(light_rgb, np.float32)
    return mean[..., None] * tint, cover
