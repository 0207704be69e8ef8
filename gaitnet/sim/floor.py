"""Procedural floors for the walking simulator: textures and AprilTag sheets (the clutter standing
on them: :mod:`gaitnet.sim.clutter`).

A :class:`FloorTexture` is an 8-bit sRGB image pyramid (RGBA, alpha unused: 4 channels make
``cv2.remap`` twice as fast) mapped onto the world plane z = 0:
texel ``(row i, column j)`` of level 0 covers ``x ∈ x0 + [j, j+1]·τ``, ``y ∈ y0 + [i, i+1]·τ``
(rows run along +y, columns along +x, ``τ = texel_m``); level ``l`` is ``cv2.pyrDown`` applied
``l`` times, so a level-0 texel coordinate ``c`` is ``c / 2**l`` on level ``l``. A 20 m × 4 m
floor at 2.5 mm texels takes 51 MB (68 MB with its pyramid).

Families (:data:`FLOOR_FAMILIES`): ``tiles`` (grout lines, per-tile colour jitter, optional
checker or running bond), ``wood`` (planks with grain and seams), ``carpet`` (multi-scale noise,
fibre speckle, optional carpet tiles), ``concrete`` (low-frequency blotches, aggregate speckle,
saw-cut joints), ``textureless`` (very low contrast vinyl).

AprilTag sheets are separate high-resolution decals (:mod:`gaitnet.sim.tag_sheet`) that the
renderer composites over the floor; the mip pyramids of both are :mod:`gaitnet.sim.mipmap`'s.
The floor may also carry the walls and ceiling of a room whose footprint is the texture's
extent (``room_height_m``).
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Literal

import cv2
import numpy as np
from numpy.typing import NDArray

from gaitnet.io.types import AprilTagBoard
from gaitnet.sim.mipmap import build_pyramid
from gaitnet.sim.render_color import encode_srgb8, srgb_to_linear
from gaitnet.sim.tag_sheet import TagSheet, make_tag_sheet

FloorFamily = Literal["tiles", "wood", "carpet", "concrete", "textureless"]
FLOOR_FAMILIES: tuple[FloorFamily, ...] = ("tiles", "wood", "carpet", "concrete", "textureless")

MAX_TEXTURE_SIDE = 32000  # cv2.remap's fixed-point maps limit source images to < 32767 px

F32 = NDArray[np.float32]
Extent = tuple[tuple[float, float], tuple[float, float]]


@dataclass(frozen=True, eq=False)
class FloorTexture:
    """A textured floor plane (z = 0) with optional tag sheets and room walls.

    ``gloss`` in [0, 1] scales the floor's mirror-like reflection of the ceiling lamps;
    ``room_height_m`` None means an unbounded floor and nothing else (rays that miss it see no
    geometry), otherwise the walls stand on the extent's edges and a ceiling closes the room.
    """

    family: str
    extent_xy: Extent
    texel_m: float
    levels: tuple[NDArray[np.uint8], ...]
    gloss: float
    sheets: tuple[TagSheet, ...] = ()
    boards: tuple[AprilTagBoard, ...] = ()
    room_height_m: float | None = 2.8
    wall_rgb: tuple[float, float, float] = (0.55, 0.54, 0.50)

    @property
    def nbytes(self) -> int:
        """Memory held by the floor pyramid and the sheets."""
        total = sum(level.nbytes for level in self.levels)
        return total + sum(lv.nbytes for s in self.sheets for lv in s.levels)


# ----------------------------------------------------------------------------- noise helpers

CHUNK_ROWS = 256  # floors are generated in bands of texel rows to bound peak memory
_CUBIC_STD = 0.86  # std of cubic-interpolated unit Gaussian value noise at random positions


def _lin(srgb255: tuple[float, float, float]) -> np.ndarray:
    """Linear albedo of an sRGB colour given in 0–255."""
    return srgb_to_linear(np.asarray(srgb255, dtype=np.float64) / 255.0).astype(np.float32)


@dataclass(frozen=True)
class _Band:
    """Texel-centre coordinates of one band of rows: ``ys`` (h, 1), ``xs`` (1, W) [m]."""

    ys: F32
    xs: F32
    texel: float
    origin: tuple[float, float]
    rng: np.random.Generator

    @property
    def shape(self) -> tuple[int, int]:
        return self.ys.shape[0], self.xs.shape[1]

    def white(self) -> F32:
        """Per-texel white noise (unit std), drawn from this band's own generator."""
        return self.rng.standard_normal(self.shape, dtype=np.float32)


class _Noise:
    """Smooth value noise (≈ unit std) with feature size ``cell_m`` = (along y, along x) [m],
    defined over the whole extent and evaluated band by band (bicubic on a random grid)."""

    def __init__(self, rng: np.random.Generator, extent: Extent, cell_m: tuple[float, float]):
        (x0, x1), (y0, y1) = extent
        self.cy, self.cx = cell_m
        self.origin = (x0, y0)
        gh = int(np.ceil((y1 - y0) / self.cy)) + 4
        gw = int(np.ceil((x1 - x0) / self.cx)) + 4
        self.grid = rng.standard_normal((gh, gw)).astype(np.float32) / np.float32(_CUBIC_STD)

    def __call__(self, band: _Band) -> F32:
        gx = ((band.xs - self.origin[0]) / self.cx + 1.5).astype(np.float32)
        gy = ((band.ys - self.origin[1]) / self.cy + 1.5).astype(np.float32)
        mx, my = np.broadcast_to(gx, band.shape), np.broadcast_to(gy, band.shape)
        return cv2.remap(
            self.grid, np.ascontiguousarray(mx), np.ascontiguousarray(my), cv2.INTER_CUBIC
        )


class _Fbm:
    """Fractal sum of :class:`_Noise` octaves (≈ unit std)."""

    def __init__(
        self,
        rng: np.random.Generator,
        extent: Extent,
        cell_m: tuple[float, float],
        octaves: int = 4,
        persistence: float = 0.55,
    ):
        amps = persistence ** np.arange(octaves)
        self.amps = (amps / np.sqrt((amps**2).sum())).astype(np.float32)
        self.octaves = [
            _Noise(rng, extent, (cell_m[0] / 2**o, cell_m[1] / 2**o)) for o in range(octaves)
        ]

    def __call__(self, band: _Band) -> F32:
        total = np.zeros(band.shape, np.float32)
        for a, octave in zip(self.amps, self.octaves, strict=True):
            total += a * octave(band)
        return total


def _line_coverage(pos: F32, period: float, width: float, texel: float) -> F32:
    """Anti-aliased coverage in [0, 1] of lines of ``width`` every ``period`` (all in metres)."""
    p = np.mod(pos, np.float32(period))
    dist = np.minimum(p, np.float32(period) - p)
    return np.clip((np.float32(width / 2) - dist) / np.float32(texel) + 0.5, 0.0, 1.0)


def _pick(rng: np.random.Generator, palette: list[tuple[float, float, float]]) -> np.ndarray:
    return _lin(palette[int(rng.integers(len(palette)))])


def _index_range(lo: float, hi: float, period: float, offset: float) -> tuple[int, int]:
    """Smallest and largest ``floor((v - offset) / period)`` for v in [lo, hi], padded by 1."""
    return int(np.floor((lo - offset) / period)) - 1, int(np.floor((hi - offset) / period)) + 1


# ----------------------------------------------------------------------------- families
# Each family draws its parameters from ``rng`` once and returns (evaluate(band) -> linear
# albedo (h, W, 3) float32, gloss).

Family = tuple[Callable[[_Band], F32], float]


def _tiles(rng: np.random.Generator, extent: Extent, texel: float) -> Family:
    palette = [(205, 203, 198), (186, 176, 160), (232, 230, 226), (120, 120, 118), (175, 110, 80)]
    base, alt = _pick(rng, palette), _pick(rng, palette)
    tile_x = float(rng.uniform(0.3, 0.6))
    tile_y = tile_x * (0.5 if rng.random() < 0.3 else 1.0)
    bond = 0.5 * tile_x if tile_y < tile_x else 0.0
    grout_w = float(rng.uniform(0.003, 0.007))
    off_x, off_y = float(rng.uniform(0, tile_x)), float(rng.uniform(0, tile_y))
    checker = bool(rng.random() < 0.2)
    (x0, x1), (y0, y1) = extent
    r_lo, r_hi = _index_range(y0, y1, tile_y, off_y)
    c_lo, c_hi = _index_range(x0, x1 + bond, tile_x, off_x)
    jitter = rng.normal(
        0.0, [0.035, 0.012, 0.012, 0.012], size=(r_hi - r_lo + 1, c_hi - c_lo + 1, 4)
    )
    jitter = jitter.astype(np.float32)
    mottle = _Fbm(rng, extent, (0.08, 0.08))
    grout_rgb = _lin((110, 108, 104))

    def evaluate(b: _Band) -> F32:
        row = np.floor((b.ys - off_y) / tile_y).astype(np.int32)
        xs_row = b.xs - off_x + np.float32(bond) * (row % 2).astype(np.float32)
        col = np.floor(xs_row / tile_x).astype(np.int32)
        tr, tc = row - r_lo, col - c_lo
        j = jitter[tr, tc]
        tone = 1.0 + j[..., 0] + 0.035 * mottle(b) + 0.02 * b.white()
        colour = np.where(((tr + tc) % 2 == 1)[..., None] & checker, alt, base)
        albedo = colour * (tone[..., None] + j[..., 1:4])
        ry = b.ys - off_y
        cov = np.maximum(
            _line_coverage(xs_row, tile_x, grout_w, b.texel),
            _line_coverage(ry, tile_y, grout_w, b.texel),
        )
        bevel = np.maximum(
            _line_coverage(xs_row, tile_x, grout_w + 0.004, b.texel),
            _line_coverage(ry, tile_y, grout_w + 0.004, b.texel),
        )
        albedo *= (1.0 - 0.12 * bevel)[..., None]
        grout = grout_rgb * (0.9 + 0.05 * b.white())[..., None]
        return albedo * (1.0 - cov[..., None]) + grout * cov[..., None]

    return evaluate, float(rng.uniform(0.35, 0.7))


def _wood(rng: np.random.Generator, extent: Extent, texel: float) -> Family:
    palette = [(176, 132, 86), (110, 75, 50), (205, 170, 125), (160, 150, 140), (150, 100, 62)]
    base = _pick(rng, palette)
    along_x = bool(rng.random() < 0.5)
    plank_w = float(rng.uniform(0.09, 0.2))
    plank_len = float(rng.uniform(0.9, 2.0))
    b_off = float(rng.uniform(0, plank_w))
    (x0, x1), (y0, y1) = extent
    (a0, a1), (b0, b1) = ((x0, x1), (y0, y1)) if along_x else ((y0, y1), (x0, x1))
    j_lo, j_hi = _index_range(b0, b1, plank_w, b_off)
    shifts = rng.uniform(0, plank_len, size=j_hi - j_lo + 1).astype(np.float32)
    k_lo, k_hi = _index_range(a0, a1 + plank_len, plank_len, 0.0)
    params = rng.normal(0.0, 1.0, size=(j_hi - j_lo + 1, k_hi - k_lo + 1, 4)).astype(np.float32)
    cell = (0.01, 0.25) if along_x else (0.25, 0.01)
    warp = _Fbm(rng, extent, cell, octaves=3)
    fibre = _Noise(rng, extent, (texel, 0.03) if along_x else (0.03, texel))
    tint = np.array([1.0, 0.98, 0.96], np.float32)

    def evaluate(b: _Band) -> F32:
        a, c = (b.xs, b.ys) if along_x else (b.ys, b.xs)
        j = np.floor((c - b_off) / plank_w).astype(np.int32)
        u = a + shifts[j - j_lo]
        k = np.floor(u / plank_len).astype(np.int32)
        p = params[j - j_lo, k - k_lo]
        v = (c - b_off) - j.astype(np.float32) * plank_w
        wv = warp(b)
        freq = 1.0 / (0.006 + 0.004 * np.abs(p[..., 1]))
        ring = 0.5 + 0.5 * np.sin(np.float32(2 * np.pi) * (v * freq + 0.7 * wv + p[..., 2]))
        tone = 1.0 + 0.08 * p[..., 0] - 0.22 * ring**3 + 0.04 * fibre(b) + 0.05 * wv
        albedo = base * tone[..., None] * (1.0 + 0.03 * p[..., 3:4]) * tint
        seam = np.maximum(
            _line_coverage(c - b_off, plank_w, 0.0015, b.texel),
            _line_coverage(u, plank_len, 0.0015, b.texel),
        )
        return albedo * (1.0 - 0.65 * seam)[..., None]

    return evaluate, float(rng.uniform(0.2, 0.45))


def _carpet(rng: np.random.Generator, extent: Extent, texel: float) -> Family:
    palette = [(110, 110, 112), (80, 90, 110), (170, 155, 130), (100, 62, 58), (62, 62, 64)]
    base, fleck_rgb = _pick(rng, palette), _pick(rng, palette)
    broad = _Fbm(rng, extent, (0.2, 0.2))
    tufts = _Noise(rng, extent, (0.008, 0.008))
    carpet_tiles = bool(rng.random() < 0.5)
    size = float(rng.uniform(0.45, 0.6))

    def evaluate(b: _Band) -> F32:
        tone = 1.0 + 0.07 * broad(b) + 0.06 * tufts(b) + 0.14 * b.white()
        if carpet_tiles:
            cx = np.floor(b.xs / size).astype(np.int32)
            cy = np.floor(b.ys / size).astype(np.int32)
            tone += np.where((cx + cy) % 2 == 0, 0.04, -0.04).astype(np.float32)
            seam = np.maximum(
                _line_coverage(b.xs, size, 0.002, b.texel),
                _line_coverage(b.ys, size, 0.002, b.texel),
            )
            tone -= 0.15 * seam
        fleck = (b.white() > 2.0)[..., None]
        return np.where(fleck, fleck_rgb, base * tone[..., None])

    return evaluate, 0.0


def _concrete(rng: np.random.Generator, extent: Extent, texel: float) -> Family:
    base = _lin((150, 148, 142)) * np.float32(rng.uniform(0.8, 1.15))
    blotch = _Fbm(rng, extent, (0.6, 0.6))
    mottle = _Noise(rng, extent, (0.03, 0.03))
    stain = _Fbm(rng, extent, (0.25, 0.25), octaves=3)
    joint = float(rng.uniform(3.0, 5.0))

    def evaluate(b: _Band) -> F32:
        tone = 1.0 + 0.11 * blotch(b) + 0.05 * mottle(b) + 0.04 * b.white()
        dots = b.white()
        tone += np.where(np.abs(dots) > 2.3, 0.18 * np.sign(dots), 0.0).astype(np.float32)
        tone -= np.clip(stain(b) - 1.6, 0.0, 0.5) * 0.4
        cut = np.maximum(
            _line_coverage(b.xs - 0.3, joint, 0.004, b.texel),
            _line_coverage(b.ys - 0.2, joint, 0.004, b.texel),
        )
        return base * (tone * (1.0 - 0.55 * cut))[..., None]

    return evaluate, float(rng.uniform(0.08, 0.25))


def _textureless(rng: np.random.Generator, extent: Extent, texel: float) -> Family:
    palette = [(200, 200, 196), (225, 222, 215), (185, 192, 198), (210, 200, 185)]
    base = _pick(rng, palette)
    broad = _Noise(rng, extent, (1.5, 1.5))

    def evaluate(b: _Band) -> F32:
        tone = 1.0 + 0.012 * broad(b) + 0.004 * b.white()
        return base * tone[..., None]

    return evaluate, float(rng.uniform(0.15, 0.35))


_FAMILIES: dict[str, Callable[[np.random.Generator, Extent, float], Family]] = {
    "tiles": _tiles,
    "wood": _wood,
    "carpet": _carpet,
    "concrete": _concrete,
    "textureless": _textureless,
}


def _render_family(
    rng: np.random.Generator, family: str, extent: Extent, texel: float, threads: int = 1
) -> tuple[NDArray[np.uint8], float]:
    """Evaluate a family band by band into an sRGB uint8 image (rows along +y); ``threads``
    bands at once (each band has its own generator: the same bytes for any number)."""
    evaluate, gloss = _FAMILIES[family](rng, extent, texel)
    (x0, x1), (y0, y1) = extent
    w, h = round((x1 - x0) / texel), round((y1 - y0) / texel)
    xs = (x0 + (np.arange(w) + 0.5) * texel).astype(np.float32)[None, :]
    out = np.full((h, w, 4), 255, np.uint8)
    starts = range(0, h, CHUNK_ROWS)
    seeds = np.random.SeedSequence(int(rng.integers(2**63))).spawn(len(starts))

    def band(i: int) -> None:
        r0, r1 = starts[i], min(h, starts[i] + CHUNK_ROWS)
        ys = (y0 + (np.arange(r0, r1) + 0.5) * texel).astype(np.float32)[:, None]
        b = _Band(ys, xs, texel, (x0, y0), np.random.default_rng(seeds[i]))
        out[r0:r1, :, :3] = encode_srgb8(evaluate(b))

    if threads > 1 and len(starts) > 1:  # OpenCV and NumPy release the GIL in the bulk work
        with ThreadPoolExecutor(min(threads, len(starts))) as pool:
            list(pool.map(band, range(len(starts))))
    else:
        for i in range(len(starts)):
            band(i)
    return out, gloss


# ----------------------------------------------------------------------------- pyramids


# ----------------------------------------------------------------------------- public API


def make_floor(
    family: str,
    rng: np.random.Generator,
    extent_xy: Extent = ((-1.0, 19.0), (-2.0, 2.0)),
    texel_m: float = 0.0025,
    boards: tuple[AprilTagBoard, ...] = (),
    room_height_m: float | None = 2.8,
    threads: int = 1,
) -> FloorTexture:
    """A procedural floor of ``family`` (one of :data:`FLOOR_FAMILIES`) over ``extent_xy``.

    ``boards`` become A3 tag sheets (decals) lying on the floor; ``room_height_m`` puts walls
    on the extent's edges and a ceiling at that height (None: floor only); ``threads``: bands
    of the texture generated at once (the same texture for any number).
    """
    if family not in _FAMILIES:
        raise ValueError(f"unknown floor family {family!r}; choose one of {FLOOR_FAMILIES}")
    (x0, x1), (y0, y1) = extent_xy
    if x1 <= x0 or y1 <= y0 or texel_m <= 0:
        raise ValueError(f"empty floor extent {extent_xy} or texel size {texel_m}")
    w, h = round((x1 - x0) / texel_m), round((y1 - y0) / texel_m)
    if max(w, h) > MAX_TEXTURE_SIDE:
        raise ValueError(
            f"floor texture {w}x{h} texels exceeds {MAX_TEXTURE_SIDE} per side; "
            f"use a larger texel_m (now {texel_m}) or a smaller extent"
        )
    image, gloss = _render_family(rng, family, extent_xy, texel_m, threads)
    levels = build_pyramid(image, texel_m)
    sheets = tuple(make_tag_sheet(b, rng) for b in boards)
    wall = tuple(float(c) for c in _lin((200, 196, 188)) * rng.uniform(0.8, 1.1))
    return FloorTexture(
        family=family,
        extent_xy=((float(x0), float(x1)), (float(y0), float(y1))),
        texel_m=float(texel_m),
        levels=levels,
        gloss=gloss,
        sheets=sheets,
        boards=tuple(boards),
        room_height_m=room_height_m,
        wall_rgb=wall,  # type: ignore[arg-type]
    )
