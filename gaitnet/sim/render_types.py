"""Plain data of the renderer: lighting, the render result and the per-camera ray tables."""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

F32 = NDArray[np.float32]
_ONES3 = np.ones(3, np.float32)


def rowdot(a: F32, b: F32) -> F32:
    """Row-wise dot products of (N, 3) arrays (a matrix product: ~10× faster than
    ``(a * b).sum(axis=1)`` in numpy)."""
    return (a * b) @ _ONES3


def cross3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product of two 3-vectors (np.cross costs ~10 µs of array checks per call)."""
    return np.array(
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]],
        dtype=np.result_type(a, b),
    )


def normalize_rows(a: F32) -> F32:
    """Rows of an (N, 3) array scaled to unit length."""
    return a / np.sqrt(rowdot(a, a))[:, None]


@dataclass(frozen=True)
class Lighting:
    """Indoor lighting: a key light, a hemispherical ambient term and rows of ceiling lamps.

    Linear irradiance units (an albedo-1 surface facing the key light has radiance
    ``key + ambient``); the sensor's exposure scales everything afterwards.

    * ``direction_W``: towards the key light (normalised when used); mostly overhead.
    * ``key``, ``ambient``: key-light and ambient irradiance; surfaces facing down get
      ``ambient · (1 − ambient_down_loss)``.
    * ``rgb``: colour of the light (multiplies everything lit).
    * ``lamp_spacing_m``, ``lamp_offset_m``, ``lamp_width_m``, ``lamp_length_m``: a row of
      ceiling lamps (width along x, length along y, centred on y = ``lamp_y_m``) at
      x = offset + k·spacing; ``lamp_variation`` is the relative floor irradiance swing they
      cause; ``lamp_radiance`` their brightness when seen (on the
      ceiling or mirrored in a glossy floor).
    * ``shadow_strength``, ``shadow_softness``: darkening under the soft key-light shadows of
      legs and shoes, and how fast the penumbra widens per metre of occluder height.
    * ``contact_ao``: darkening of the floor right next to a shoe (ambient occlusion).
    * ``background_rgb``: what a ray that hits nothing sees (no room, looking up).
    """

    direction_W: tuple[float, float, float] = (-0.3, 0.2, 1.0)
    key: float = 0.6
    ambient: float = 0.4
    ambient_down_loss: float = 0.65
    rgb: tuple[float, float, float] = (1.0, 0.97, 0.92)
    lamp_spacing_m: float = 2.4
    lamp_offset_m: float = 0.0
    lamp_width_m: float = 0.3
    lamp_length_m: float = 1.2
    lamp_y_m: float = 0.0
    lamp_variation: float = 0.25
    lamp_radiance: float = 3.0
    shadow_strength: float = 0.45
    shadow_softness: float = 0.35
    contact_ao: float = 0.55
    background_rgb: tuple[float, float, float] = (0.2, 0.2, 0.2)

    def light_dir(self) -> np.ndarray:
        d = np.asarray(self.direction_W, np.float64)
        n = float(np.linalg.norm(d))
        if n == 0 or d[2] <= 0:
            raise ValueError(f"Lighting.direction_W must point upwards, got {self.direction_W}")
        return d / n


@dataclass(frozen=True, eq=False)
class RenderResult:
    """One rendered frame before sensor effects (all (H, W) unless noted).

    ``rgb_linear`` (H, W, 3) float32 scene radiance; ``depth_m`` float32 z-depth along the
    camera z axis (``inf`` where nothing is hit); ``label`` uint8 (0 background, 1 foot, 2 leg);
    ``instance`` uint8 (0 none, 1 left, 2 right); ``normals`` (H, W, 3) float32 camera-frame
    unit normals (zero where nothing is hit) when asked for.
    """

    rgb_linear: F32
    depth_m: F32
    label: NDArray[np.uint8]
    instance: NDArray[np.uint8]
    normals: F32 | None = None


@dataclass(frozen=True, eq=False)
class Rays:
    """Per-pixel camera rays of one camera: ``xn``, ``yn`` with direction (xn, yn, 1), and the
    unit directions ``ux``, ``uy``, ``uz`` (all (H, W) float32).

    The ray (xn, yn, 1) is separable: ``xn[v, u] = xn_u[u] + xn_v[v]``, ``yn[v, u] = yn_v[v]``
    (float64 vectors), which makes any linear function of it one broadcast addition.
    """

    xn: F32
    yn: F32
    ux: F32
    uy: F32
    uz: F32
    xn_u: np.ndarray
    xn_v: np.ndarray
    yn_v: np.ndarray

    def linear(self, a: float, b: float, c: float) -> F32:
        """``a·xn + b·yn + c`` for every pixel (H, W) float32, in one broadcast addition."""
        col = (a * self.xn_u).astype(np.float32)
        row = (a * self.xn_v + b * self.yn_v + c).astype(np.float32)
        return col[None, :] + row[:, None]


@lru_cache(maxsize=8)
def _rays_cached(k: tuple[float, ...], width: int, height: int) -> Rays:
    K = np.array(k, np.float64).reshape(3, 3)
    Kinv = np.linalg.inv(K)
    u = np.arange(width, dtype=np.float64)[None, :]
    v = np.arange(height, dtype=np.float64)[:, None]
    xn = Kinv[0, 0] * u + Kinv[0, 1] * v + Kinv[0, 2]
    yn = np.broadcast_to(Kinv[1, 1] * v + Kinv[1, 2], (height, width))
    xn = np.broadcast_to(xn, (height, width))
    inv = 1.0 / np.sqrt(xn**2 + yn**2 + 1.0)
    arrays = [np.ascontiguousarray(a, dtype=np.float32) for a in (xn, yn, xn * inv, yn * inv, inv)]
    vectors = [
        Kinv[0, 0] * u[0] + Kinv[0, 2],
        Kinv[0, 1] * v[:, 0],
        Kinv[1, 1] * v[:, 0] + Kinv[1, 2],
    ]
    for a in arrays + vectors:
        a.flags.writeable = False
    return Rays(*arrays, *vectors)


def camera_rays(K: np.ndarray, width: int, height: int) -> Rays:
    """Cached ray tables for camera matrix ``K`` and image size (pixel centres at integers)."""
    K = np.asarray(K, np.float64)
    if K.shape != (3, 3) or K[2, 2] != 1.0 or K[2, 0] != 0 or K[2, 1] != 0 or K[1, 0] != 0:
        raise ValueError(f"K must be an upper-triangular 3x3 camera matrix, got {K.tolist()}")
    return _rays_cached(tuple(float(x) for x in K.ravel()), int(width), int(height))


def low_res_K(K: np.ndarray, factor: int) -> np.ndarray:
    """Camera matrix of the image shrunk by an integer ``factor`` (cv2.resize pixel centres)."""
    K2 = np.asarray(K, np.float64).copy()
    K2[0, :] /= factor
    K2[1, :] /= factor
    K2[0, 2] = (K[0, 2] + 0.5) / factor - 0.5
    K2[1, 2] = (K[1, 2] + 0.5) / factor - 0.5
    K2[2] = [0.0, 0.0, 1.0]
    return K2
