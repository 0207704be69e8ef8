"""Small real unevenness of the floor: a height field h(x, y) of a few millimetres.

A real floor is not the plane z = 0. Within the flatness tolerances of finished floors
(DIN 18202, table 3: a few mm under a 1 m straightedge, about 10 mm under 4 m) it undulates
gently, and tiles or boards stand proud of their neighbours by a fraction of a millimetre
(lippage; docs/references.md, *Simulator realism: depth*). The relief is

    h(x, y) = Σ_k A_k cos(kx_k x + ky_k y + φ_k) + L[iy, ix],
    ix = floor((x − x0) / pitch_x),  iy = floor((y − y0) / pitch_y)

(world metres, z up): a long wave (wavelength 1.5–3 m) whose steepest slope is ``slope_deg`` —
the floor's local slope, while its height stays within a few mm, so the feet (which rest on
z = 0 in the gait model) stay within a few mm of the visible floor —, two short waves
(0.6–1.2 m) of ``waviness_mm`` in all, and for tiled and wooden floors a constant offset per
tile/board of ±``lip_mm``/2 (a step of at most ``lip_mm`` at a joint; other families have
no joints). The lattice of tiles/boards is the relief's own: it does not follow the painted
joints of the floor texture.

Ray intersection (:meth:`FloorRelief.ray_t`): from the ray's hit t₀ on z = 0, two Newton steps
on ``c_z + t D_z = h(c_xy + t D_xy)``, the tile taken at the hit on z = 0 (the renderer does the
two steps on its 4× coarser grid and one at full resolution from the interpolated result). For the
smooth part the error after two steps is far below a micrometre (tests/test_sim_depth.py);
within ``|D_xy / D_z| · lip_mm`` (a few mm) of a joint, where the true ray meets the lip's
vertical face, the depth is that of the tile chosen.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property

import cv2
import numpy as np
from numpy.typing import NDArray

from gaitnet.checks import check_range

__all__ = ["FloorRelief", "FloorReliefConfig", "flat_relief", "sample_floor_relief"]

F32 = NDArray[np.float32]
LONG_WAVELENGTH_M = (1.5, 3.0)
SHORT_WAVELENGTH_M = (0.6, 1.2)
#: Tile/board lattice pitch (x, y) ranges per floor family with joints [m].
LIP_PITCH_M = {"tiles": ((0.3, 0.6), None), "wood": ((0.9, 2.0), (0.09, 0.2))}
NEWTON_STEPS = 2
BLOCK_PIXELS = 32768  # pixels per block of rows in ray_t (a few arrays of it fit in L2)


@dataclass(frozen=True)
class FloorReliefConfig:
    """The floor's unevenness (config section ``floor_relief``; module docstring).

    ``slope_deg``: steepest local slope of the long waves, 0–2° (0 = none);
    ``waviness_mm``: height amplitude of the short waves, 0–5 mm; ``lip_mm``: largest step
    between neighbouring tiles or boards, 0–3 mm (tiled and wooden floors only).
    """

    slope_deg: float = 0.2
    waviness_mm: float = 0.6
    lip_mm: float = 0.6

    def __post_init__(self) -> None:
        check_range("slope_deg", self.slope_deg, 0.0, 2.0, "°")
        check_range("waviness_mm", self.waviness_mm, 0.0, 5.0, " mm")
        check_range("lip_mm", self.lip_mm, 0.0, 3.0, " mm")


@dataclass(frozen=True, eq=False)
class FloorRelief:
    """A floor height field (module docstring). ``waves`` (n, 4): amplitude [m], kx, ky
    [rad/m], phase [rad]; ``lips`` (ny, nx) offsets [m] of the tiles whose lattice starts at
    ``origin`` with ``pitch`` (x, y) [m] (empty: no joints)."""

    waves: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))
    origin: tuple[float, float] = (0.0, 0.0)
    pitch: tuple[float, float] = (1.0, 1.0)
    lips: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))

    @cached_property
    def _table(self) -> F32:
        return np.ascontiguousarray(self.lips, np.float32)

    @property
    def is_flat(self) -> bool:
        return not np.any(self.waves[:, 0]) and not np.any(self.lips)

    # ------------------------------------------------------------------ evaluation

    def lip(self, x: np.ndarray, y: np.ndarray) -> F32:
        """Tile offsets L [m] at points (x, y) (0 where there are no joints): a nearest-
        neighbour look-up (OpenCV rounds, so the cell index is ``floor``)."""
        x = np.asarray(x, np.float32)
        if self.lips.size == 0:
            return np.zeros(x.shape, np.float32)
        mx = (x - np.float32(self.origin[0])) * np.float32(1.0 / self.pitch[0]) - np.float32(0.5)
        my = (np.asarray(y, np.float32) - np.float32(self.origin[1])) * np.float32(
            1.0 / self.pitch[1]
        ) - np.float32(0.5)
        if x.ndim == 2 and max(x.shape) < 32000:
            return cv2.remap(
                self._table, mx, my, cv2.INTER_NEAREST, borderMode=cv2.BORDER_REPLICATE
            )
        n = x.size  # cv2.remap takes 2-D maps of fewer than 32767 rows and columns
        pad = (-n) % 4096
        flat = [np.pad(m.ravel(), (0, pad)).reshape(-1, 4096) for m in (mx, my)]
        out = cv2.remap(self._table, *flat, cv2.INTER_NEAREST, borderMode=cv2.BORDER_REPLICATE)
        return out.ravel()[:n].reshape(x.shape)

    def waves_at(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """The smooth part W [m] at points (x, y) (float64)."""
        x, y = np.asarray(x, np.float64), np.asarray(y, np.float64)
        w = np.zeros(np.broadcast_shapes(x.shape, y.shape))
        for a, kx, ky, phi in self.waves:
            w += a * np.cos(kx * x + ky * y + phi)
        return w

    def height(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """h(x, y) [m] (module docstring), float64."""
        return self.waves_at(x, y) + self.lip(x, y)

    def ray_t(
        self,
        t0: F32,
        c: np.ndarray,
        D: list[F32],
        t_start: F32 | None = None,
        steps: int = NEWTON_STEPS,
    ) -> F32:
        """Ray parameter (float32) of the relief along rays ``c + t D`` (world, D float32 of
        ``t0``'s shape) from their finite hits ``t0`` on z = 0: ``steps`` Newton steps on
        ``g(t) = c_z + t D_z − W(c_xy + t D_xy) − L`` from ``t_start`` (default ``t0``), the
        tile L taken at the hit on z = 0. Along a ray a wave is ``A cos(a + t b)`` with
        ``a = k·c_xy + φ``, ``b = k·D_xy``. Images are done in blocks of rows that fit in the
        CPU cache (several times faster than whole-image passes)."""
        if t0.ndim == 2 and t0.size > 2 * BLOCK_PIXELS:
            rows = max(1, BLOCK_PIXELS // t0.shape[1])
            out = np.empty_like(t0)
            for r in range(0, t0.shape[0], rows):
                b = slice(r, r + rows)
                start = None if t_start is None else t_start[b]
                out[b] = self.ray_t(t0[b], c, [d[b] for d in D], start, steps)
            return out
        cx, cy, cz = (float(v) for v in c)
        f32 = np.float32
        lip = self.lip(cx + t0 * D[0], cy + t0 * D[1]) if self.lips.size else None
        bs = [f32(kx) * D[0] + f32(ky) * D[1] for _, kx, ky, _ in self.waves]
        t = t0 if t_start is None else t_start
        for _ in range(steps):
            g = t * D[2]
            g += f32(cz)
            if lip is not None:
                g -= lip
            dg = D[2].copy()
            for (a, kx, ky, phi), b in zip(self.waves, bs, strict=True):
                theta = t * b
                theta += f32(kx * cx + ky * cy + phi)
                cos, sin = cv2.polarToCart(None, theta)  # unit magnitudes
                cv2.scaleAdd(cos, -a, g, dst=g)
                sin *= b
                cv2.scaleAdd(sin, a, dg, dst=dg)
            g /= dg
            t = t - g
        return t

    # ------------------------------------------------------------------ ground truth

    def to_dict(self) -> dict:
        """The relief's parameters for ``groundtruth/floor_relief.json`` (docs/groundtruth.md)."""
        return {
            "formula": "h = sum_k A_k cos(kx_k x + ky_k y + phase_k) + lips[iy][ix], "
            "ix = floor((x - origin_x) / pitch_x) clipped to the table, iy likewise",
            "waves": [
                {"amplitude_m": a, "kx_rad_per_m": kx, "ky_rad_per_m": ky, "phase_rad": p}
                for a, kx, ky, p in self.waves.tolist()
            ],
            "lip_origin_m": list(self.origin),
            "lip_pitch_m": list(self.pitch),
            "lips_m": self.lips.tolist(),
        }


def flat_relief() -> FloorRelief:
    """The plane z = 0."""
    return FloorRelief()


def _waves(
    rng: np.random.Generator, n: int, wavelengths: tuple[float, float], amplitude
) -> list[list[float]]:
    out = []
    for _ in range(n):
        lam = float(rng.uniform(*wavelengths))
        heading = float(rng.uniform(0.0, 2 * math.pi))
        phase = float(rng.uniform(0.0, 2 * math.pi))
        k = 2 * math.pi / lam
        out.append([amplitude(lam), k * math.cos(heading), k * math.sin(heading), phase])
    return out


def sample_floor_relief(
    rng: np.random.Generator,
    cfg: FloorReliefConfig,
    family: str,
    extent: tuple[tuple[float, float], tuple[float, float]],
) -> FloorRelief:
    """A random relief (module docstring) covering the floor ``extent`` ((x0, x1), (y0, y1)).

    Always draws the same numbers from ``rng`` for a family, so that a magnitude set to 0
    does not change the others.
    """
    tan_s = math.tan(math.radians(cfg.slope_deg))
    # The long wave's steepest slope is A k = tan(slope_deg).
    waves = _waves(rng, 1, LONG_WAVELENGTH_M, lambda lam: tan_s * lam / (2 * math.pi))
    waves += _waves(rng, 2, SHORT_WAVELENGTH_M, lambda lam: cfg.waviness_mm * 1e-3 / 2)
    (x0, x1), (y0, y1) = extent
    origin, pitch, lips = (0.0, 0.0), (1.0, 1.0), np.zeros((0, 0))
    if family in LIP_PITCH_M:
        px_range, py_range = LIP_PITCH_M[family]
        px = float(rng.uniform(*px_range))
        py = px if py_range is None else float(rng.uniform(*py_range))
        origin = (x0 - float(rng.uniform(0, px)), y0 - float(rng.uniform(0, py)))
        nx = int(math.ceil((x1 - origin[0]) / px)) + 1
        ny = int(math.ceil((y1 - origin[1]) / py)) + 1
        offsets = rng.uniform(-0.5, 0.5, size=(ny, nx))
        lips = offsets * cfg.lip_mm * 1e-3
        pitch = (px, py)
    waves_arr = np.asarray(waves, np.float64)
    waves_arr = waves_arr[waves_arr[:, 0] != 0] if len(waves_arr) else waves_arr
    return FloorRelief(waves_arr.reshape(-1, 4), origin, pitch, lips)
