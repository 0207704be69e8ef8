"""What a RealSense D455 delivers from a rendered frame: 8-bit colour and stereo depth.

Colour: optics/demosaicing blur, vignetting, exposure × white balance, black level, photon
shot noise and read noise (in electrons, added in the variance-stabilised square-root domain),
sRGB encoding and 8-bit quantisation.

Depth: :mod:`gaitnet.sim.sensor_depth` (active stereo: correlated matching noise, bias and
waviness, disparity quantisation, flying pixels, holes); its keys are the depth fields of
:class:`SensorNoiseConfig`, inherited from :class:`~gaitnet.sim.sensor_depth.DepthNoiseConfig`.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np
from numpy.typing import NDArray

from gaitnet.sim.render_color import linear_to_srgb
from gaitnet.sim.render_types import F32, RenderResult
from gaitnet.sim.sensor_depth import (
    DEPTH_RANGES,
    DepthNoiseConfig,
    DepthUnit,
    check_ranges,
    depth_image,
)
from gaitnet.sim.sensor_noise import gaussian_noise

__all__ = ["SENSOR_RANGES", "SensorNoiseConfig", "apply_sensor", "auto_exposure"]


@dataclass(frozen=True)
class SensorNoiseConfig(DepthNoiseConfig):
    """Noise and artefact settings of the simulated D455 (defaults: a typical indoor unit).

    Colour: ``full_well_e`` electrons at full scale and ``read_noise_e`` read noise (shot
    noise follows from them), ``black_level`` linear offset (flare, dark signal),
    ``vignetting`` relative irradiance loss in the image corners, ``blur_sigma_px`` Gaussian
    optics/demosaicing blur (the pixel's own area is integrated by the renderer; 0.4 px at
    640×480 is a lens + Bayer-demosaicing PSF of σ ≈ 0.67 px of the native 1280×800 sensor,
    i.e. MTF50 ≈ 0.28 cycles/pixel, scaled by the 0.6 downscaling of the 640×480 mode; docs/
    references.md, *Simulator realism: rendering*), ``white_balance`` per-channel gains.
    Depth: the fields of :class:`~gaitnet.sim.sensor_depth.DepthNoiseConfig`.
    Valid ranges: :data:`SENSOR_RANGES`.
    """

    full_well_e: float = 2500.0
    read_noise_e: float = 4.0
    black_level: float = 0.003
    vignetting: float = 0.3
    blur_sigma_px: float = 0.4
    white_balance: tuple[float, float, float] = (1.0, 1.0, 1.0)

    def __post_init__(self) -> None:
        check_ranges(self, SENSOR_RANGES)


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
    *DEPTH_RANGES,
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


def apply_sensor(
    render: RenderResult,
    K: np.ndarray,
    rng: np.random.Generator,
    cfg: SensorNoiseConfig | None = None,
    exposure: float = 1.0,
    depth_rng: np.random.Generator | None = None,
    depth_unit: DepthUnit | None = None,
) -> tuple[NDArray[np.uint8], F32]:
    """8-bit sRGB colour (H, W, 3) and depth in metres (H, W, 0 = invalid) of a D455.

    Depth noise is drawn from ``depth_rng`` (default: ``rng``, after the colour noise), for
    the camera unit ``depth_unit`` (:func:`gaitnet.sim.sensor_depth.depth_image`).
    Deterministic for given generator states.
    """
    cfg = cfg or SensorNoiseConfig()
    K = np.asarray(K, np.float64)
    rgb = _colour(render.rgb_linear, K, rng, cfg, exposure)
    depth = depth_image(render, K, rng if depth_rng is None else depth_rng, cfg, depth_unit)
    return rgb, depth
