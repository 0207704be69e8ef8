"""Floor plane from depth points with a gravity prior, and the height map (thesis (3.22)–(3.23)).

The plane is ``n·p + h = 0`` in the camera frame (3.22) with ``n`` a unit normal pointing from
the floor towards the camera and ``h > 0`` the camera's height above the floor. The height of a
point above the floor is ``h + n·p`` (D.-C. Dang's thesis prints ``ĥ − n̂ᵀp`` in (3.23), which
gives ``2h`` on the floor; corrected per the thesis notes). For a camera pose ``T_WfromC`` and
the world floor ``z = 0``: ``n = R_WfromCᵀ e_z`` and ``h = z`` of the camera centre.

:func:`fit_floor` is RANSAC over 3-point hypotheses (all drawn at once, vectorised), keeping
only normals within ``max_angle_from_prior_deg`` of the up direction from the IMU (the
accelerometer's specific force at rest, in the camera frame), then a total-least-squares
refinement on the inliers.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

log = logging.getLogger(__name__)

__all__ = [
    "FloorParams",
    "FloorPlane",
    "fit_floor",
    "fit_floor_depth",
    "floor_points",
    "height_map",
]


@dataclass(frozen=True)
class FloorParams:
    """RANSAC floor-fit settings (tuned on simulated sessions det_s200–s205)."""

    stride: int = 8
    """Use every ``stride``-th row and column of the depth image (640×480 → 4800 points;
    the plane's 3 parameters need far fewer, and the fit stays ~1–2 ms)."""
    max_range_m: float = 3.5
    """Ignore points farther than this [m]: D455 depth noise grows with z² (≈ 1 cm at 3 m)."""
    iterations: int = 64
    """RANSAC hypotheses. With ≥ 50 % floor inliers, P(no all-inlier triple) = 0.875^64 < 2e-4."""
    inlier_threshold_m: float = 0.015
    """Point-to-plane distance of an inlier [m]: depth noise at 1–2 m (a few mm) plus the
    simulated floor relief (waves and tile lips, ≤ 3 mm) plus the tilt of a bad hypothesis."""
    max_angle_from_prior_deg: float = 20.0
    """Reject hypotheses whose normal is farther than this from the IMU's up direction [deg]
    (the accelerometer's direction is off by the walking accelerations, ~1–2 m/s², i.e. up to
    ~10°; walls are 90° away)."""
    min_inliers: int = 150
    """Fewest inliers for a floor (3 % of the 4800 sampled points)."""
    refine_iterations: int = 2
    """Least-squares refinements, each re-selecting inliers with the refined plane."""
    seed: int = 0
    """Seed of the RANSAC sampling (deterministic results)."""


@dataclass(frozen=True)
class FloorPlane:
    """Plane ``n_C·p + h = 0`` in the camera frame; ``n_C`` unit, towards the camera, ``h > 0``.

    ``n_inliers`` and ``rms_m`` (RMS point-to-plane distance of the inliers) describe the fit.
    """

    n_C: np.ndarray
    h: float
    n_inliers: int = 0
    rms_m: float = 0.0

    def height(self, p_C: np.ndarray) -> np.ndarray:
        """Height above the floor ``h + n·p`` [m] of camera-frame points (..., 3) (3.23)."""
        return self.h + np.asarray(p_C, dtype=np.float64) @ self.n_C

    def project(self, p_C: np.ndarray) -> np.ndarray:
        """Orthogonal projection of camera-frame points (..., 3) onto the plane."""
        p = np.asarray(p_C, dtype=np.float64)
        return p - self.height(p)[..., None] * self.n_C

    def intersect_ray(self, d_C: np.ndarray) -> np.ndarray | None:
        """Where the ray ``s·d`` (s > 0) from the camera centre meets the plane, or None."""
        d = np.asarray(d_C, dtype=np.float64)
        denom = float(self.n_C @ d)
        if denom >= -1e-9:  # parallel or pointing away from the floor
            return None
        return (-self.h / denom) * d


def floor_points(depth_m: np.ndarray, K: np.ndarray, stride: int, max_range_m: float) -> np.ndarray:
    """(N, 3) camera-frame points of every ``stride``-th pixel, valid depth ≤ ``max_range_m``."""
    d = np.asarray(depth_m)[::stride, ::stride].astype(np.float64)
    v, u = np.mgrid[0 : depth_m.shape[0] : stride, 0 : depth_m.shape[1] : stride]
    ok = np.isfinite(d) & (d > 0) & (d <= max_range_m)
    z = d[ok]
    x = (u[ok] - K[0, 2]) / K[0, 0] * z
    y = (v[ok] - K[1, 2]) / K[1, 1] * z
    return np.stack([x, y, z], axis=1)


def _plane_from(p: np.ndarray, up: np.ndarray) -> tuple[np.ndarray, float]:
    """Total least squares plane through ``p`` (N, 3), normal oriented like ``up``."""
    c = p.mean(axis=0)
    _, _, Vt = np.linalg.svd(p - c, full_matrices=False)
    n = Vt[2]
    if n @ up < 0:
        n = -n
    return n, float(-n @ c)


def fit_floor(
    points_C: np.ndarray, up_C_prior: np.ndarray, params: FloorParams | None = None
) -> FloorPlane | None:
    """RANSAC floor plane (3.22) of camera-frame points (N, 3) near the prior up direction.

    ``up_C_prior`` is the up direction in the camera frame (e.g. the accelerometer's specific
    force rotated into the camera frame). Returns None (logged at debug level) if no
    hypothesis within ``max_angle_from_prior_deg`` of it has ``min_inliers`` inliers, or the
    camera would be below the plane.
    """
    params = params or FloorParams()
    p = np.asarray(points_C, dtype=np.float64)
    up = np.asarray(up_C_prior, dtype=np.float64)
    up = up / np.linalg.norm(up)
    n_pts = len(p)
    if n_pts < max(3, params.min_inliers):
        log.debug("floor: %d points, need %d", n_pts, params.min_inliers)
        return None
    rng = np.random.default_rng(params.seed)
    idx = rng.integers(0, n_pts, size=(params.iterations, 3))
    a, b, c = p[idx[:, 0]], p[idx[:, 1]], p[idx[:, 2]]
    n = np.cross(b - a, c - a)
    norm = np.linalg.norm(n, axis=1)
    good = norm > 1e-9
    n = n[good] / norm[good, None]
    a = a[good]
    n *= np.sign(n @ up)[:, None] + (n @ up == 0)[:, None]
    cos_max = math.cos(math.radians(params.max_angle_from_prior_deg))
    keep = n @ up >= cos_max
    if not keep.any():
        log.debug("floor: no hypothesis within %.0f° of the prior", params.max_angle_from_prior_deg)
        return None
    n, a = n[keep], a[keep]
    h = -np.einsum("ij,ij->i", n, a)
    dist = np.abs(p @ n.T + h)  # (N, M)
    counts = (dist < params.inlier_threshold_m).sum(axis=0)
    best = int(np.argmax(counts))
    if counts[best] < params.min_inliers:
        log.debug("floor: best plane has %d inliers, need %d", counts[best], params.min_inliers)
        return None
    n_best, h_best = n[best], float(h[best])
    inl = dist[:, best] < params.inlier_threshold_m
    for _ in range(params.refine_iterations):
        n_new, h_new = _plane_from(p[inl], up)
        if n_new @ up < cos_max:
            break
        n_best, h_best = n_new, h_new
        inl = np.abs(p @ n_best + h_best) < params.inlier_threshold_m
        if inl.sum() < 3:
            return None
    if h_best <= 0:
        log.debug("floor: camera below the fitted plane (h = %.3f)", h_best)
        return None
    r = p[inl] @ n_best + h_best
    return FloorPlane(
        n_C=n_best, h=h_best, n_inliers=int(inl.sum()), rms_m=float(np.sqrt(np.mean(r**2)))
    )


def fit_floor_depth(
    depth_m: np.ndarray, K: np.ndarray, up_C_prior: np.ndarray, params: FloorParams | None = None
) -> FloorPlane | None:
    """:func:`fit_floor` on a depth image (metres, 0 = no data) subsampled by ``params.stride``."""
    params = params or FloorParams()
    pts = floor_points(depth_m, np.asarray(K, dtype=np.float64), params.stride, params.max_range_m)
    return fit_floor(pts, up_C_prior, params)


def height_map(
    depth_m: np.ndarray, K: np.ndarray, plane: FloorPlane, origin: tuple[int, int] = (0, 0)
) -> np.ndarray:
    """Height above the floor ``h + n·p(u, v)`` (3.23, corrected sign) per pixel, float32 [m].

    NaN where the depth is invalid (≤ 0 or non-finite). Uses ``n·p = z (n_x x_n + n_y y_n + n_z)``
    with the normalised pixel coordinates, so no point image is built. ``depth_m`` may be a box
    of the image whose first pixel is ``origin`` (u, v): the same values as the whole map's there.
    """
    d = np.asarray(depth_m, dtype=np.float32)
    H, W = d.shape
    n = plane.n_C
    u0, v0 = origin
    a_u = (n[0] / K[0, 0]) * (np.arange(u0, u0 + W, dtype=np.float64) - K[0, 2])
    a_v = (n[1] / K[1, 1]) * (np.arange(v0, v0 + H, dtype=np.float64) - K[1, 2]) + n[2]
    A = (a_v[:, None] + a_u[None, :]).astype(np.float32)
    out = np.float32(plane.h) + d * A
    out[~(d > 0)] = np.nan
    return out
