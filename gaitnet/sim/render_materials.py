"""Materials of the subject and the clutter: albedo textures and shading of surface points.

Shading is Lambertian, ``albedo · (ambient_hemisphere(n) + key · max(0, n·l))``, with a small
Blinn-Phong sheen on shoes, all times the light's colour.
Trousers carry a periodic fabric texture (streaky weave, grain and soft creases) wrapped
around each leg segment (axial distance × angle); shoes carry an albedo texture projected from
above in the shoe frame (toe cap and seam, tongue, laces and eyelets, collar opening, optional
side stripe) plus a height-dependent sole with a groove. All textures are deterministic
functions of the sizes and :class:`Appearance`.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np

from gaitnet.sim.render_prims import RoundCone
from gaitnet.sim.render_types import F32, Lighting, cross3, normalize_rows, rowdot
from gaitnet.sim.scene import Appearance

FABRIC_N = 256
FABRIC_TEXEL_M = 0.002
SHOE_TEXEL_M = 0.001


@dataclass(frozen=True)
class LightFrame:
    """Lighting in the camera frame: ``l_C`` towards the key light, ``up`` world up,
    ``fwd`` world +x, ``rgb`` the light's colour."""

    l_C: np.ndarray
    up: np.ndarray
    fwd: np.ndarray
    rgb: np.ndarray
    light: Lighting

    @classmethod
    def make(cls, light: Lighting, R_CfromW: np.ndarray) -> LightFrame:
        l_C = (R_CfromW @ light.light_dir()).astype(np.float32)
        up, fwd = R_CfromW[:, 2].astype(np.float32), R_CfromW[:, 0].astype(np.float32)
        return cls(l_C, up, fwd, np.asarray(light.rgb, np.float32), light)


def irradiance(n: F32, lf: LightFrame) -> F32:
    """Hemispherical ambient plus key light on unit normals ``n`` (N, 3)."""
    ndl = np.maximum(n @ lf.l_C, 0.0)
    nup = n @ lf.up
    amb = np.float32(lf.light.ambient) * (
        1 - np.float32(lf.light.ambient_down_loss) * (1 - nup) / 2
    )
    return amb + np.float32(lf.light.key) * ndl


def remap_points(tex: np.ndarray, cols: F32, rows: F32, border: int) -> np.ndarray:
    """Bilinear lookup of ``tex`` at N scattered points (cv2.remap on a padded 2-D layout,
    since remap images must stay below 32767 pixels per side)."""
    n = cols.shape[0]
    width = 1024
    h = max(1, -(-n // width))
    mx = np.zeros(h * width, np.float32)
    my = np.zeros(h * width, np.float32)
    mx[:n], my[:n] = cols, rows
    out = cv2.remap(
        tex, mx.reshape(h, width), my.reshape(h, width), cv2.INTER_LINEAR, borderMode=border
    )
    return out.reshape(h * width, *tex.shape[2:])[:n]


def _seed(*values: object) -> int:
    return zlib.crc32(repr(values).encode())


def _periodic_noise(rng: np.random.Generator, n: int, cell: tuple[float, float]) -> F32:
    """Periodic (tileable) Gaussian-filtered noise (n, n), unit std; ``cell`` in texels."""
    white = rng.standard_normal((n, n))
    fy = np.fft.fftfreq(n)[:, None]
    fx = np.fft.fftfreq(n)[None, :]
    filt = np.exp(-0.5 * ((fy * cell[0] * 2.5) ** 2 + (fx * cell[1] * 2.5) ** 2))
    out = np.real(np.fft.ifft2(np.fft.fft2(white) * filt))
    return (out / (out.std() or 1.0)).astype(np.float32)


@lru_cache(maxsize=16)
def fabric_texture(seed: int) -> F32:
    """Tileable trouser-fabric multiplier (FABRIC_N², rows along the leg, columns around)."""
    rng = np.random.default_rng(seed)
    streak = _periodic_noise(rng, FABRIC_N, (10.0, 1.2))
    grain = _periodic_noise(rng, FABRIC_N, (0.7, 0.7))
    crease = _periodic_noise(rng, FABRIC_N, (5.0, 20.0))
    folds = np.tanh(1.5 * crease)
    return (1.0 + 0.025 * streak + 0.05 * grain - 0.12 * folds).astype(np.float32)


def shade_leg(
    cone: RoundCone, p: F32, n: F32, view: F32, lf: LightFrame, appearance: Appearance, seed: int
) -> F32:
    """Linear colour (N, 3) of trouser points ``p`` with normals ``n`` and unit view
    directions ``view`` (camera frame).

    The fabric wraps around the axis with the seam (angle ±π) at the back of the leg, the
    front being world +x (the walking direction at the start of a walk).
    """
    a = cone.a.astype(np.float32)
    ba = (cone.b - cone.a).astype(np.float32)
    u = ba / np.linalg.norm(ba)
    e1 = lf.fwd - (lf.fwd @ u) * u
    if np.linalg.norm(e1) < 1e-3:
        e1 = lf.up - (lf.up @ u) * u
    e1 = e1 / np.linalg.norm(e1)
    e2 = cross3(u, e1)
    q = p - a
    rows = (q @ (u / np.float32(FABRIC_TEXEL_M))).astype(np.float32)
    theta = np.arctan2(q @ e2, q @ e1)
    cols = ((theta + np.float32(np.pi)) * np.float32(FABRIC_N / (2 * np.pi))).astype(np.float32)
    mult = remap_points(fabric_texture(seed), cols, rows, cv2.BORDER_WRAP)
    irr = irradiance(n, lf)
    grazing = 1 - np.abs(rowdot(n, view))
    albedo = np.asarray(appearance.trouser_rgb, np.float32) * lf.rgb
    return albedo[None] * (mult * irr * (1 - 0.3 * grazing * grazing))[:, None]


# ----------------------------------------------------------------------------- shoes


def _lum(rgb: tuple[float, float, float]) -> float:
    return 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2]


@dataclass(frozen=True)
class ShoeTexture:
    """Albedo (linear, (h, w, 3)) of a shoe seen from above: column ``j`` ↔ x = x0 + j·τ,
    row ``i`` ↔ y = y0 − i·τ (texel centres), in the shoe frame; the shoe's (length, width);
    whether its sides carry a stripe in the sole's colour."""

    albedo: F32
    x0: float
    y0: float
    texel: float
    size: tuple[float, float]
    side_stripe: bool


def _lace_colour(appearance: Appearance, pick: float) -> np.ndarray:
    shoe = appearance.shoe_rgb
    if _lum(shoe) < 0.05:
        return np.array([0.55, 0.55, 0.55], np.float32) if pick < 0.5 else np.array(shoe) * 1.4
    if _lum(shoe) > 0.6 or pick < 0.5:
        return np.array([0.8, 0.8, 0.78], np.float32)
    return (np.array(shoe) * 0.45).astype(np.float32)


@lru_cache(maxsize=32)
def shoe_texture(length: float, width: float, side: str, appearance: Appearance) -> ShoeTexture:
    """Top-view albedo texture of a shoe (see module docstring)."""
    tau = SHOE_TEXEL_M
    x0, y0 = -0.5 * length - 0.005, 0.6 * width
    w, h = int((length + 0.01) / tau) + 1, int(1.2 * width / tau) + 1
    xs = (x0 + np.arange(w) * tau)[None, :]
    ys = (y0 - np.arange(h) * tau)[:, None]
    rng = np.random.default_rng(_seed(length, width, side, appearance))
    base = np.asarray(appearance.shoe_rgb, np.float32)
    mult = 1.0 + 0.05 * _periodic_noise(rng, max(h, w), (0.8, 0.8))[:h, :w]
    mult += 0.04 * _periodic_noise(rng, max(h, w), (12.0, 12.0))[:h, :w]
    L, W = length, width
    toe_line = 0.22 * L + 0.09 * L * (1 - (ys / (0.5 * W)) ** 2)
    mult = np.where(xs > toe_line, mult * 0.93, mult)
    mult *= 1 - 0.35 * np.exp(-0.5 * ((xs - toe_line) / 0.0012) ** 2)
    crease = (xs > 0.08 * L) & (xs < 0.22 * L)
    mult *= 1 - 0.06 * crease * (0.5 + 0.5 * np.sin(ys / 0.004 + xs / 0.01))
    albedo = base[None, None] * mult[..., None]
    stripe = bool(rng.random() < 0.5) and _lum(appearance.sole_rgb) > 1.5 * _lum(
        appearance.shoe_rgb
    )
    lace = _lace_colour(appearance, rng.random())
    _draw_laces(albedo, xs, ys, (L, W), lace, (x0, y0, tau))
    _draw_collar(albedo, xs, ys, L, W)
    return ShoeTexture(albedo.astype(np.float32), x0, y0, tau, (L, W), stripe)


def _draw_laces(
    albedo: np.ndarray,
    xs: np.ndarray,
    ys: np.ndarray,
    size: tuple[float, float],
    lace: np.ndarray,
    frame: tuple[float, float, float],
) -> None:
    """Tongue, eyelets and criss-cross laces on the instep, in place."""
    L, W = size
    x0, y0, tau = frame
    xa, xb, half = -0.2 * L, 0.17 * L, 0.17 * W
    tongue = (xs > xa - 0.01) & (xs < xb) & (np.abs(ys) < half * 0.8)
    albedo[tongue] *= 0.78

    def pt(x: float, y: float) -> tuple[int, int]:  # 1/4-texel fixed point (shift = 2)
        return round((x - x0) / tau * 4), round((y0 - y) / tau * 4)

    mask = np.zeros(albedo.shape[:2], np.float32)
    eyelets = np.zeros(albedo.shape[:2], np.float32)
    n = 6
    for i in range(n):
        xi = xa + (xb - xa) * i / (n - 1)
        for sgn in (-1, 1):
            cv2.circle(eyelets, pt(xi, sgn * half), 8, 1.0, -1, cv2.LINE_AA, 2)
        if i < n - 1:
            xj = xa + (xb - xa) * (i + 1) / (n - 1)
            for sgn in (-1, 1):
                cv2.line(mask, pt(xi, sgn * half), pt(xj, -sgn * half), 1.0, 5, cv2.LINE_AA, 2)
    albedo *= 1 - 0.9 * eyelets[..., None]
    m = mask[..., None]
    albedo[:] = albedo * (1 - m) + lace[None, None] * m * (0.9 + 0.1 * m)


def _draw_collar(albedo: np.ndarray, xs: np.ndarray, ys: np.ndarray, L: float, W: float) -> None:
    """Dark ankle opening with a padded rim near the heel, in place."""
    e = ((xs + 0.3 * L) / (0.11 * L)) ** 2 + (ys / (0.26 * W)) ** 2
    albedo[e < 1.0] = (0.035, 0.033, 0.03)
    rim = (e >= 1.0) & (e < 1.7)
    albedo[rim] *= 0.75


def _soft_band(v: F32, lo: float, hi: float, soft: float) -> F32:
    """1 inside [lo, hi], 0 outside, linear ramps of width ``soft``."""
    return np.clip(np.minimum(v - lo, hi - v) / np.float32(soft) + 0.5, 0.0, 1.0)


def _side_stripe(
    p_S: F32, albedo: F32, size: tuple[float, float], sole_m: float, colour: np.ndarray
) -> F32:
    """A band in the sole's colour along both sides of the upper, above the sole."""
    L, W = size
    band = _soft_band(p_S[:, 0], -0.3 * L, 0.12 * L, 0.01)
    band *= _soft_band(p_S[:, 2], sole_m + 0.008, sole_m + 0.026, 0.003)
    band *= np.clip((np.abs(p_S[:, 1]) - 0.25 * W) / 0.01, 0.0, 1.0)
    return albedo + band[:, None] * (colour * np.float32(0.9) - albedo)


def shade_shoe(
    p_S: F32,
    n: F32,
    lf: LightFrame,
    view: F32,
    tex: ShoeTexture,
    sole_m: float,
    appearance: Appearance,
) -> F32:
    """Linear colour (N, 3) of shoe points ``p_S`` (shoe frame) with camera-frame normals
    ``n`` and unit view directions ``view`` (from the point towards the camera)."""
    cols = ((p_S[:, 0] - np.float32(tex.x0)) / np.float32(tex.texel)).astype(np.float32)
    rows = ((np.float32(tex.y0) - p_S[:, 1]) / np.float32(tex.texel)).astype(np.float32)
    albedo = remap_points(tex.albedo, cols, rows, cv2.BORDER_REPLICATE)
    z = p_S[:, 2]
    sole = np.asarray(appearance.sole_rgb, np.float32)
    groove = 1 - 0.35 * np.exp(-0.5 * ((z - 0.55 * sole_m) / 0.0012) ** 2)
    if tex.side_stripe:
        albedo = _side_stripe(p_S, albedo, tex.size, sole_m, sole)
    in_sole = (z < np.float32(sole_m))[:, None]
    albedo = np.where(in_sole, sole[None] * groove[:, None], albedo)
    irr = irradiance(n, lf)
    half = normalize_rows(view + lf.l_C[None])
    gloss = np.where(in_sole[:, 0], 0.02, 0.07).astype(np.float32)
    spec = gloss * np.maximum(rowdot(n, half), 0) ** 40 * np.float32(lf.light.key)
    return (albedo * irr[:, None] + spec[:, None]) * lf.rgb


def shade_plain(rgb: tuple[float, float, float], n: F32, lf: LightFrame) -> F32:
    """Lambertian colour (N, 3) of a uniformly coloured object (clutter)."""
    return (np.asarray(rgb, np.float32) * lf.rgb)[None] * irradiance(n, lf)[:, None]
