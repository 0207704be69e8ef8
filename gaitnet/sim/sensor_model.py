"""What a RealSense D455 delivers from a rendered frame: 8-bit colour and stereo depth.

Colour: optics/demosaicing blur, vignetting, exposure × white balance, black level, photon
shot noise and read noise (in electrons, added in the variance-stabilised square-root domain),
sRGB encoding and 8-bit quantisation.

Depth (docs/references.md, *Sensors*): stereo noise grows with the square of the distance,
``σ_z = z² σ_d / (f b)`` (baseline ``b`` = 95 mm, sub-pixel disparity noise ``σ_d`` ≈ 0.08 px),
partly spatially correlated (a share of the variance is drawn at a coarser grid and
upsampled); pixels are invalid (0) below the minimum range and beyond the maximum range, at
depth discontinuities (stereo matchers drop the pixels next to a jump), in the occlusion shadow
that a near object casts for the second imager (a band on the left of near objects: the depth
is referenced to the left imager and the right imager sits at +x), and at a small random
fraction of sparse holes and small blobs. Depth stays in float metres; quantisation to the
depth unit happens when frames are written.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy.special import ndtri

from gaitnet.checks import check_each, check_int_range, check_range
from gaitnet.sim.render_color import linear_to_srgb
from gaitnet.sim.render_types import F32, RenderResult

__all__ = ["SENSOR_RANGES", "SensorNoiseConfig", "apply_sensor", "auto_exposure"]


@dataclass(frozen=True)
class SensorNoiseConfig:
    """Noise and artefact settings of the simulated D455 (defaults: a typical indoor unit).

    Colour: ``full_well_e`` electrons at full scale and ``read_noise_e`` read noise (shot
    noise follows from them), ``black_level`` linear offset (flare, dark signal),
    ``vignetting`` relative irradiance loss in the image corners, ``blur_sigma_px`` Gaussian
    optics/demosaicing blur, ``white_balance`` per-channel gains.
    Depth: ``baseline_m``, ``disparity_noise_px`` (σ_d), ``correlated_fraction`` of the noise
    variance drawn on a grid ``noise_cell_px`` pixels coarse, ``min_range_m`` and
    ``max_range_m``, ``edge_jump_m`` + ``edge_jump_rel``·z (a neighbour jump larger than this
    invalidates both pixels) grown by ``edge_dilate_px``, ``occlusion_shadow`` on/off,
    ``dropout_fraction`` isolated holes and ``blob_fraction`` holes in blobs of about
    ``blob_px`` pixels. Valid ranges: :data:`SENSOR_RANGES`.
    """

    full_well_e: float = 2500.0
    read_noise_e: float = 4.0
    black_level: float = 0.003
    vignetting: float = 0.3
    blur_sigma_px: float = 0.6
    white_balance: tuple[float, float, float] = (1.0, 1.0, 1.0)
    baseline_m: float = 0.095
    disparity_noise_px: float = 0.08
    correlated_fraction: float = 0.6
    noise_cell_px: int = 3
    min_range_m: float = 0.4
    max_range_m: float = 6.0
    edge_jump_m: float = 0.02
    edge_jump_rel: float = 0.03
    edge_dilate_px: int = 1
    occlusion_shadow: bool = True
    dropout_fraction: float = 0.002
    blob_fraction: float = 0.002
    blob_px: int = 6

    def __post_init__(self) -> None:
        for name, lo, hi in SENSOR_RANGES:
            value = getattr(self, name)
            if isinstance(value, tuple):
                check_each(name, value, lo, hi)
            elif isinstance(lo, int) and isinstance(hi, int):
                check_int_range(name, value, lo, hi)
            else:
                check_range(name, value, lo, hi)


#: Valid values of :class:`SensorNoiseConfig` (key, low, high; ints for integer keys): settings
#: outside them give black, white or empty images rather than a D455-like camera's
#: (``min_range_m`` ≤ 1 m < 2 m ≤ ``max_range_m``, so the valid range is never empty).
SENSOR_RANGES: tuple[tuple[str, float, float], ...] = (
    ("full_well_e", 100.0, 1e6),
    ("read_noise_e", 0.0, 100.0),
    ("black_level", 0.0, 0.2),
    ("vignetting", 0.0, 0.9),
    ("blur_sigma_px", 0.0, 5.0),
    ("white_balance", 0.25, 4.0),
    ("baseline_m", 0.01, 0.5),
    ("disparity_noise_px", 0.0, 1.0),
    ("correlated_fraction", 0.0, 1.0),
    ("noise_cell_px", 1, 32),
    ("min_range_m", 0.1, 1.0),
    ("max_range_m", 2.0, 20.0),
    ("edge_jump_m", 0.0, 1.0),
    ("edge_jump_rel", 0.0, 1.0),
    ("edge_dilate_px", 0, 10),
    ("dropout_fraction", 0.0, 0.5),
    ("blob_fraction", 0.0, 0.5),
    ("blob_px", 1, 64),
)


def auto_exposure(rgb_linear: F32, target: float = 0.18, percentile_cap: float = 99.0) -> float:
    """Exposure that brings the mean luminance to ``target`` without clipping more than the
    top ``100 − percentile_cap`` % of pixels (a simple auto-exposure)."""
    lum = rgb_linear[::4, ::4] @ np.array([0.2126, 0.7152, 0.0722], np.float32)
    mean = float(lum.mean())
    hi = float(np.percentile(lum, percentile_cap))
    if mean <= 0 or hi <= 0:
        return 1.0
    return float(min(target / mean, 1.0 / hi))


def _gauss_table() -> np.ndarray:
    q = ndtri((np.arange(256) + 0.5) / 256.0)
    return (q / q.std()).astype(np.float32).reshape(256, 1)


# 256 equiprobable Gaussian quantiles (unit std, tails cut at ±2.9σ): one random byte per
# sample, mapped by cv2.LUT, is ~9× faster than numpy's standard_normal.
_GAUSS_LUT = _gauss_table()


def gaussian_noise(rng: np.random.Generator, shape: tuple[int, ...]) -> F32:
    """Unit-variance, zero-mean noise of ``shape`` (256-level quantised Gaussian)."""
    n = int(np.prod(shape))
    raw = np.frombuffer(rng.bytes(n), np.uint8).reshape(shape)
    return cv2.LUT(raw, _GAUSS_LUT).reshape(shape)


def _uniform16(rng: np.random.Generator, shape: tuple[int, ...]) -> NDArray[np.uint16]:
    return np.frombuffer(rng.bytes(2 * int(np.prod(shape))), np.uint16).reshape(shape)


@lru_cache(maxsize=8)
def _vignette(
    width: int, height: int, k: tuple[float, ...], strength: float, wb: tuple[float, ...]
) -> F32:
    """Irradiance falloff × white balance (H, W, 3): cos⁴-like, ``1 − strength`` in the
    corners."""
    fx, cx, fy, cy = k
    u = (np.arange(width) - cx) / fx
    v = (np.arange(height) - cy) / fy
    r2 = u[None, :] ** 2 + v[:, None] ** 2
    r2max = max(r2[0, 0], r2[0, -1], r2[-1, 0], r2[-1, -1])
    cos4 = 1.0 / (1.0 + r2) ** 2
    cos4_corner = 1.0 / (1.0 + r2max) ** 2
    fall = 1.0 - strength * (1.0 - cos4) / (1.0 - cos4_corner)
    out = fall[..., None] * np.asarray(wb)[None, None]
    out.flags.writeable = False
    return out.astype(np.float32)


@lru_cache(maxsize=8)
def _stabilised_lut(offset: float) -> np.ndarray:
    """uint8 code of ``s = sqrt(x + offset) / sqrt(1 + offset)`` -> uint8 sRGB code of x."""
    s = np.arange(256) / 255.0 * np.sqrt(1.0 + offset)
    return np.round(255.0 * linear_to_srgb(np.clip(s * s - offset, 0.0, 1.0))).astype(np.uint8)


def _colour(
    rgb_linear: F32,
    K: np.ndarray,
    rng: np.random.Generator,
    cfg: SensorNoiseConfig,
    exposure: float,
) -> NDArray[np.uint8]:
    """Photon (Poisson) + read noise through the generalised Anscombe transform: in
    ``s = sqrt(x + σ_r²/FW)`` the noise std is the constant ``1 / (2 sqrt(FW))``, so one
    scaled Gaussian image adds both, and the 8-bit sRGB code is read from a table on s."""
    h, w = rgb_linear.shape[:2]
    img = rgb_linear
    if cfg.blur_sigma_px > 0:
        img = cv2.GaussianBlur(img, (0, 0), cfg.blur_sigma_px)
    key = (float(K[0, 0]), float(K[0, 2]), float(K[1, 1]), float(K[1, 2]))
    vig = _vignette(w, h, key, cfg.vignetting, tuple(cfg.white_balance))
    img = cv2.multiply(img, vig, scale=float(exposure))
    offset = cfg.read_noise_e**2 / cfg.full_well_e
    norm = 1.0 / np.sqrt(1.0 + offset)
    cv2.add(img, cfg.black_level + offset, dst=img)
    cv2.sqrt(cv2.max(img, 0.0, dst=img), dst=img)
    noise = gaussian_noise(rng, img.shape)
    cv2.scaleAdd(noise, 0.5 / np.sqrt(cfg.full_well_e), img, dst=img)
    code = cv2.convertScaleAbs(img, alpha=255.0 * norm)
    return cv2.LUT(code, _stabilised_lut(offset)).reshape(h, w, 3)


@lru_cache(maxsize=8)
def _upsampled_std(cell: int) -> float:
    """Std of unit white noise on a ``cell``-coarse grid after bilinear upsampling."""
    g = gaussian_noise(np.random.default_rng(0), (96, 96))
    return float(cv2.resize(g, (96 * cell, 96 * cell), interpolation=cv2.INTER_LINEAR).std())


def _correlated_noise(
    rng: np.random.Generator, shape: tuple[int, int], cfg: SensorNoiseConfig
) -> F32:
    """Unit-variance noise image, ``correlated_fraction`` of its variance spatially smooth."""
    h, w = shape
    c = cfg.noise_cell_px
    white = gaussian_noise(rng, shape)
    if c == 1 or cfg.correlated_fraction == 0:
        return white
    hl, wl = -(-h // c), -(-w // c)
    coarse = gaussian_noise(rng, (hl, wl))
    smooth = cv2.resize(coarse, (wl * c, hl * c), interpolation=cv2.INTER_LINEAR)[:h, :w]
    a = np.float32(np.sqrt(cfg.correlated_fraction) / _upsampled_std(c))
    b = np.float32(np.sqrt(1.0 - cfg.correlated_fraction))
    return smooth * a + white * b


def _edges(z: F32, cfg: SensorNoiseConfig) -> NDArray[np.bool_]:
    """Pixels within ``1 + edge_dilate_px`` of a neighbour depth jump larger than
    ``edge_jump_m + edge_jump_rel · z`` (local max − min over a square window)."""
    k = 3 + 2 * cfg.edge_dilate_px
    kernel = np.ones((k, k), np.uint8)
    spread = cv2.dilate(z, kernel) - cv2.erode(z, kernel)
    thr = np.float32(cfg.edge_jump_m) + np.float32(cfg.edge_jump_rel) * cv2.erode(z, kernel)
    return spread > thr


def _occlusion_shadow(z: F32, fb: float, rows: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """Pixels the right imager (at +x) cannot see: some pixel to their right, nearer to the
    camera, lands at or left of them in the right image (``u − f b / z``). Only ``rows`` with
    a depth discontinuity can hold such pixels."""
    out = np.zeros(z.shape, bool)
    idx = np.flatnonzero(rows)
    if idx.size == 0:
        return out
    w = z.shape[1]
    s = np.arange(w, dtype=np.float32)[None, :] - np.float32(fb) / z[idx]
    rmin = np.minimum.accumulate(s[:, ::-1], axis=1)[:, ::-1]
    nxt = np.full_like(s, np.inf)
    nxt[:, :-1] = rmin[:, 1:]
    out[idx] = nxt < s - np.float32(0.5)
    return out


def _holes(
    rng: np.random.Generator, shape: tuple[int, int], cfg: SensorNoiseConfig
) -> NDArray[np.bool_]:
    """Random isolated dropouts plus small blobs."""
    holes = _uniform16(rng, shape) < round(cfg.dropout_fraction * 65536)
    if cfg.blob_fraction > 0 and cfg.blob_px > 1:
        b = cfg.blob_px
        h, w = shape
        hl, wl = -(-h // b), -(-w // b)
        p_seed = cfg.blob_fraction / 0.65  # a blob covers about 2/3 of its seed cell
        seeds = (_uniform16(rng, (hl, wl)) < round(min(p_seed, 1.0) * 65536)).astype(np.float32)
        up = cv2.resize(seeds, (wl * b, hl * b), interpolation=cv2.INTER_LINEAR)[:h, :w]
        holes |= up > 0.5
    return holes


def _depth(
    render: RenderResult, K: np.ndarray, rng: np.random.Generator, cfg: SensorNoiseConfig
) -> F32:
    z = np.where(np.isfinite(render.depth_m), render.depth_m, np.float32(1e3)).astype(np.float32)
    fb = 0.5 * (K[0, 0] + K[1, 1]) * cfg.baseline_m
    sigma = z * z * np.float32(cfg.disparity_noise_px / fb)
    noisy = z + sigma * _correlated_noise(rng, z.shape, cfg)
    edges = _edges(z, cfg)
    invalid = (z < cfg.min_range_m) | (z > cfg.max_range_m) | edges
    if cfg.occlusion_shadow:
        invalid |= _occlusion_shadow(z, fb, edges.any(axis=1))
    invalid |= _holes(rng, z.shape, cfg)
    return np.where(invalid, np.float32(0.0), noisy).astype(np.float32)


def apply_sensor(
    render: RenderResult,
    K: np.ndarray,
    rng: np.random.Generator,
    cfg: SensorNoiseConfig | None = None,
    exposure: float = 1.0,
) -> tuple[NDArray[np.uint8], F32]:
    """8-bit sRGB colour (H, W, 3) and depth in metres (H, W, 0 = invalid) of a D455.

    Deterministic for a given ``rng`` state (colour noise is drawn before depth noise).
    """
    cfg = cfg or SensorNoiseConfig()
    K = np.asarray(K, np.float64)
    rgb = _colour(render.rgb_linear, K, rng, cfg, exposure)
    depth = _depth(render, K, rng, cfg)
    return rgb, depth
