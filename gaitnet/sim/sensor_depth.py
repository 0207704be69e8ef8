"""The depth stream of a simulated RealSense D455: active stereo, 95 mm baseline.

From the true z-depth of a rendered frame to what the camera reports (float metres, 0 =
invalid; quantisation to the depth unit happens when frames are written). Sources and the
reasons for each magnitude: docs/references.md (*Sensors*, *Simulator realism: depth*) and
docs/simulator.md (*Depth*).

The depth is computed from a disparity ``d = f b / z`` (``f`` the focal length in pixels, ``b``
the baseline), perturbed the way a stereo matcher perturbs it and turned back into depth:

* **matching noise** ``σ_d`` (``disparity_noise_px``, ≈ 0.08 px): a share
  ``correlated_fraction`` of its variance is white noise averaged over the matcher's window
  (``match_window_px``, 7 × 7 census: neighbouring pixels share most of their window, so their
  errors are correlated over several pixels), the rest white; σ_z = z² σ_d / (f b);
* **a bias** from a disparity offset fixed per camera unit (``disparity_offset_px``, its sign
  drawn per session): Δz ≈ −z² Δd / (f b), a few mm at 1 m growing with z²;
* **waviness** of a flat surface ("potato chip"): a smooth, low-order disparity error across
  the image (``waviness_px`` RMS; shape drawn per session), mm-level at 1–2 m;
* **disparity quantisation** in steps of 1 / ``subpixel_steps`` px (1/32 on the D400 series):
  depth steps z² / (32 f b), growing with z²;
* **flying pixels**: a share ``flying_fraction`` of the pixels next to a depth jump get a depth
  between the near and the far side (the matching window straddles both) instead of 0;
* **invalid pixels**: outside ``min_range_m``–``max_range_m``; the rest of the pixels at a depth
  jump; the occlusion shadow (the band the right imager cannot see); clusters of
  ``hole_cluster_px`` on dark surfaces (radiance below ``dark_radiance``: the IR pattern and
  the texture are too weak to match; at most ``dark_hole_prob`` of them) and on specular glare
  (radiance above ``glare_radiance``: a lamp mirrored in a shiny floor saturates the imagers);
  sparse random dropouts and small blobs.

Each effect has a key that turns it off (0, or false). The unit's fixed errors (offset sign
and waviness shape) are a :class:`DepthUnit`, drawn per session (:func:`sample_depth_unit`) and
written to ``groundtruth/depth_unit.json``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy.special import ndtri

from gaitnet.checks import check_each, check_int_range, check_range
from gaitnet.sim.render_types import F32, RenderResult
from gaitnet.sim.sensor_noise import gaussian_noise, uniform16

__all__ = [
    "DEPTH_RANGES",
    "DepthNoiseConfig",
    "DepthUnit",
    "check_ranges",
    "depth_image",
    "sample_depth_unit",
]


def check_ranges(obj: object, ranges: Sequence[tuple[str, float, float]]) -> None:
    """Check ``obj``'s attributes against (key, low, high) rows (ints for integer keys)."""
    for name, lo, hi in ranges:
        value = getattr(obj, name)
        if isinstance(value, tuple):
            check_each(name, value, lo, hi)
        elif isinstance(lo, int) and isinstance(hi, int):
            check_int_range(name, value, lo, hi)
        else:
            check_range(name, value, lo, hi)


@dataclass(frozen=True)
class DepthNoiseConfig:
    """The depth keys of the ``sensor`` config section (module docstring; defaults: a typical
    indoor D455). Valid ranges: :data:`DEPTH_RANGES`.

    ``baseline_m``; ``disparity_noise_px`` σ_d, ``correlated_fraction`` of its variance
    averaged over ``match_window_px``; ``disparity_offset_px`` (bias), ``waviness_px`` (RMS
    over the image), ``subpixel_steps`` (0 = no quantisation); ``min_range_m``,
    ``max_range_m``; ``edge_jump_m`` + ``edge_jump_rel``·z (a neighbour jump larger than this
    marks both pixels) grown by ``edge_dilate_px``, of which ``flying_fraction`` become
    flying pixels and the rest invalid; ``occlusion_shadow`` on/off; ``dark_radiance``,
    ``glare_radiance``, ``dark_hole_prob``, ``hole_cluster_px`` (holes on dark and glaring
    surfaces); ``dropout_fraction`` isolated holes and ``blob_fraction`` holes in blobs of
    about ``blob_px`` pixels.
    """

    baseline_m: float = 0.095
    disparity_noise_px: float = 0.08
    correlated_fraction: float = 0.7
    match_window_px: int = 7
    disparity_offset_px: float = 0.08
    waviness_px: float = 0.05
    subpixel_steps: int = 32
    min_range_m: float = 0.4
    max_range_m: float = 6.0
    edge_jump_m: float = 0.02
    edge_jump_rel: float = 0.03
    edge_dilate_px: int = 1
    flying_fraction: float = 0.3
    occlusion_shadow: bool = True
    dark_radiance: float = 0.03
    glare_radiance: float = 2.0
    dark_hole_prob: float = 0.6
    hole_cluster_px: int = 8
    dropout_fraction: float = 0.002
    blob_fraction: float = 0.002
    blob_px: int = 6

    def __post_init__(self) -> None:
        check_ranges(self, DEPTH_RANGES)


#: Valid values of :class:`DepthNoiseConfig` (key, low, high; ints for integer keys)
#: (``min_range_m`` ≤ 1 m < 2 m ≤ ``max_range_m``, so the valid range is never empty).
DEPTH_RANGES: tuple[tuple[str, float, float], ...] = (
    ("baseline_m", 0.01, 0.5),
    ("disparity_noise_px", 0.0, 1.0),
    ("correlated_fraction", 0.0, 1.0),
    ("match_window_px", 1, 31),
    ("disparity_offset_px", 0.0, 1.0),
    ("waviness_px", 0.0, 0.5),
    ("subpixel_steps", 0, 256),
    ("min_range_m", 0.1, 1.0),
    ("max_range_m", 2.0, 20.0),
    ("edge_jump_m", 0.0, 1.0),
    ("edge_jump_rel", 0.0, 1.0),
    ("edge_dilate_px", 0, 10),
    ("flying_fraction", 0.0, 1.0),
    ("dark_radiance", 0.0, 1.0),
    ("glare_radiance", 0.5, 100.0),
    ("dark_hole_prob", 0.0, 1.0),
    ("hole_cluster_px", 1, 64),
    ("dropout_fraction", 0.0, 0.5),
    ("blob_fraction", 0.0, 0.5),
    ("blob_px", 1, 64),
)


# ----------------------------------------------------------------------------- the unit


#: The waviness shape of the default unit: coefficients of (x, y, x², xy, y²) in image
#: coordinates scaled to [−1, 1] — a bowl with a slight twist.
DEFAULT_WAVINESS = (0.3, -0.2, 1.0, 0.4, 0.8)


@dataclass(frozen=True)
class DepthUnit:
    """The errors of one D455 unit that stay fixed over a session: the sign of its disparity
    offset (+1: depth reads short) and the shape of its waviness (coefficients of x, y, x²,
    xy, y² over the image scaled to [−1, 1]; scaled to ``waviness_px`` RMS when used)."""

    offset_sign: float = 1.0
    waviness: tuple[float, ...] = DEFAULT_WAVINESS

    def to_dict(self, cfg: DepthNoiseConfig) -> dict:
        """The unit's errors in ``cfg``'s magnitudes (``groundtruth/depth_unit.json``)."""
        return {
            "disparity_offset_px": self.offset_sign * cfg.disparity_offset_px,
            "waviness_rms_px": cfg.waviness_px,
            "waviness_terms": ["x", "y", "x^2", "x*y", "y^2"],
            "waviness_coefficients": list(self.waviness),
            "image_coordinates": "x = (u - (W - 1) / 2) / ((W - 1) / 2), y likewise with v, H",
            "formula": "d_obs = f b / z + disparity_offset_px + waviness_rms_px * "
            "(sum_i c_i term_i - mean) / rms + noise, quantised; z_obs = f b / d_obs",
        }


def sample_depth_unit(rng: np.random.Generator) -> DepthUnit:
    """A random unit: offset sign ±1, waviness coefficients standard normal."""
    sign = 1.0 if rng.random() < 0.5 else -1.0
    return DepthUnit(sign, tuple(float(v) for v in rng.standard_normal(5)))


@lru_cache(maxsize=8)
def _waviness_map(coeffs: tuple[float, ...], width: int, height: int) -> F32:
    """Zero-mean, unit-RMS low-order field over the image (H, W)."""
    x = np.linspace(-1.0, 1.0, width)[None, :]
    y = np.linspace(-1.0, 1.0, height)[:, None]
    terms = (x + 0 * y, y + 0 * x, x * x + 0 * y, x * y, y * y + 0 * x)
    field = sum(c * t for c, t in zip(coeffs, terms, strict=True))
    field = field - field.mean()
    rms = float(np.sqrt(np.mean(field**2)))
    out = (field / rms if rms > 0 else field).astype(np.float32)
    out.flags.writeable = False
    return out


# ----------------------------------------------------------------------------- noise


# Normal quantile of the probability coded by a byte (k / 255): the threshold for a hole.
_QUANTILE_LUT = ndtri(np.clip(np.arange(256) / 255.0, 1e-9, 1 - 1e-9)).astype(np.float32)
_QUANTILE_LUT[0] = -np.inf
_QUANTILE_LUT = _QUANTILE_LUT.reshape(256, 1)


def _window_noise(rng: np.random.Generator, shape: tuple[int, int], cfg: DepthNoiseConfig) -> F32:
    """Unit-variance noise image: ``correlated_fraction`` of its variance white noise averaged
    over the ``match_window_px`` square window (autocorrelation falling linearly to 0 at the
    window's width), the rest white."""
    white = gaussian_noise(rng, shape)
    k = cfg.match_window_px
    if k == 1 or cfg.correlated_fraction == 0:
        return white
    window = cv2.blur(gaussian_noise(rng, shape), (k, k), borderType=cv2.BORDER_REFLECT)
    a = np.float32(np.sqrt(cfg.correlated_fraction) * k)  # a k×k mean has std 1/k
    b = np.float32(np.sqrt(1.0 - cfg.correlated_fraction))
    return cv2.addWeighted(window, float(a), white, float(b), 0.0)


@lru_cache(maxsize=8)
def _upsampled_std(cell: int) -> float:
    """Std of unit white noise on a ``cell``-coarse grid after bilinear upsampling."""
    g = gaussian_noise(np.random.default_rng(0), (96, 96))
    return float(cv2.resize(g, (96 * cell, 96 * cell), interpolation=cv2.INTER_LINEAR).std())


def _smooth_gaussian(rng: np.random.Generator, shape: tuple[int, int], cell: int) -> F32:
    """About unit-variance Gaussian field, smooth over ``cell`` pixels."""
    h, w = shape
    hl, wl = -(-h // cell), -(-w // cell)
    coarse = gaussian_noise(rng, (hl, wl)) * np.float32(1.0 / _upsampled_std(cell))
    return cv2.resize(coarse, (wl * cell, hl * cell), interpolation=cv2.INTER_LINEAR)[:h, :w]


# ----------------------------------------------------------------------------- invalid pixels


def _edges(z: F32, cfg: DepthNoiseConfig) -> tuple[NDArray[np.bool_], F32, F32]:
    """Pixels within ``1 + edge_dilate_px`` of a neighbour depth jump larger than
    ``edge_jump_m + edge_jump_rel · z`` (local max − min over a square window), and the local
    min and max."""
    k = 3 + 2 * cfg.edge_dilate_px
    kernel = np.ones((k, k), np.uint8)
    zmax, zmin = cv2.dilate(z, kernel), cv2.erode(z, kernel)
    thr = np.float32(cfg.edge_jump_m) + np.float32(cfg.edge_jump_rel) * zmin
    return (zmax - zmin) > thr, zmin, zmax


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
    rng: np.random.Generator, shape: tuple[int, int], cfg: DepthNoiseConfig
) -> NDArray[np.bool_]:
    """Random isolated dropouts plus small blobs."""
    holes = uniform16(rng, shape) < round(cfg.dropout_fraction * 65536)
    if cfg.blob_fraction > 0 and cfg.blob_px > 1:
        b = cfg.blob_px
        h, w = shape
        hl, wl = -(-h // b), -(-w // b)
        p_seed = cfg.blob_fraction / 0.65  # a blob covers about 2/3 of its seed cell
        seeds = (uniform16(rng, (hl, wl)) < round(min(p_seed, 1.0) * 65536)).astype(np.float32)
        up = cv2.resize(seeds, (wl * b, hl * b), interpolation=cv2.INTER_LINEAR)[:h, :w]
        holes |= up > 0.5
    return holes


def _material_holes(
    rgb_linear: F32, rng: np.random.Generator, cfg: DepthNoiseConfig
) -> NDArray[np.bool_]:
    """Clusters of invalid pixels where the surface is too dark (radiance below
    ``dark_radiance``: probability rising linearly to ``dark_hole_prob`` at black) or glares
    (radiance above ``glare_radiance``: probability ``dark_hole_prob``). A pixel is a hole
    where a smooth Gaussian field (clusters of ``hole_cluster_px``) is below the normal
    quantile of its probability, so the share of holes follows the probability."""
    lum = cv2.cvtColor(rgb_linear, cv2.COLOR_RGB2GRAY)
    p = np.zeros(lum.shape, np.float32)
    if cfg.dark_radiance > 0:
        p = np.clip(1.0 - lum * np.float32(1.0 / cfg.dark_radiance), 0.0, 1.0)
    p[lum > np.float32(cfg.glare_radiance)] = 1.0
    code = cv2.convertScaleAbs(p, alpha=255.0 * cfg.dark_hole_prob)
    thr = cv2.LUT(code, _QUANTILE_LUT).reshape(lum.shape)
    return _smooth_gaussian(rng, lum.shape, cfg.hole_cluster_px) < thr


# ----------------------------------------------------------------------------- depth


def depth_image(
    render: RenderResult,
    K: np.ndarray,
    rng: np.random.Generator,
    cfg: DepthNoiseConfig,
    unit: DepthUnit | None = None,
) -> F32:
    """The D455's depth in metres (H, W, 0 = invalid) of a rendered frame (module docstring),
    for the camera unit ``unit`` (None: :class:`DepthUnit`'s default). Deterministic for a
    given ``rng`` state."""
    unit = unit or DepthUnit()
    z = np.where(np.isfinite(render.depth_m), render.depth_m, np.float32(1e3)).astype(np.float32)
    h, w = z.shape
    fb = np.float32(0.5 * (K[0, 0] + K[1, 1]) * cfg.baseline_m)
    disp = fb / z
    disp += np.float32(unit.offset_sign * cfg.disparity_offset_px)
    if cfg.waviness_px > 0:
        disp += _waviness_map(unit.waviness, w, h) * np.float32(cfg.waviness_px)
    if cfg.disparity_noise_px > 0:
        noise = _window_noise(rng, (h, w), cfg)
        disp += noise * np.float32(cfg.disparity_noise_px)
    if cfg.subpixel_steps > 0:
        steps = np.float32(cfg.subpixel_steps)
        disp = np.rint(disp * steps) * (np.float32(1.0) / steps)
    with np.errstate(divide="ignore"):
        noisy = np.where(disp > 0, fb / disp, np.float32(np.inf)).astype(np.float32)

    edges, zmin, zmax = _edges(z, cfg)
    jump_rows = edges.any(axis=1)
    if cfg.flying_fraction > 0:
        idx = np.flatnonzero(edges)
        fly = uniform16(rng, (idx.size,)) < round(cfg.flying_fraction * 65536)
        mix = uniform16(rng, (idx.size,)).astype(np.float32) * np.float32(1.0 / 65536)
        sel = idx[fly]
        zl, zh = zmin.ravel()[sel], zmax.ravel()[sel]
        noisy.ravel()[sel] = zl + mix[fly] * (zh - zl)
        edges.ravel()[sel] = False
    invalid = (noisy < cfg.min_range_m) | (noisy > cfg.max_range_m) | (z > cfg.max_range_m)
    invalid |= edges
    if cfg.occlusion_shadow:
        invalid |= _occlusion_shadow(z, float(fb), jump_rows)
    if cfg.dark_hole_prob > 0 and (cfg.dark_radiance > 0 or cfg.glare_radiance < 100.0):
        invalid |= _material_holes(render.rgb_linear, rng, cfg)
    invalid |= _holes(rng, (h, w), cfg)
    return np.where(invalid, np.float32(0.0), noisy).astype(np.float32)
