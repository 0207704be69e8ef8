"""Pinhole camera model in the OpenCV camera frame (x right, y down, z forward).

``K`` is a 3×3 camera matrix ``[[fx, s, cx], [0, fy, cy], [0, 0, 1]]`` (``s`` is normally 0),
e.g. :attr:`gaitnet.io.types.CameraIntrinsics.K`. Pixel coordinates ``(u, v)`` are (column,
row) with integer values at pixel centres, so ``depth[v, u]`` is the depth seen at pixel
``(u, v)``. Images are treated as undistorted.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

__all__ = ["backproject", "depth_to_points", "project", "projection_jacobian"]


def _as_K(K: ArrayLike) -> FloatArray:
    K = np.asarray(K, dtype=np.float64)
    if K.shape != (3, 3):
        raise ValueError(f"K must be a 3x3 camera matrix, got shape {K.shape}")
    if not np.array_equal(K[2], [0.0, 0.0, 1.0]) or K[1, 0] != 0.0:
        raise ValueError(f"K must be upper triangular with last row [0, 0, 1], got {K.tolist()}")
    if K[0, 0] == 0.0 or K[1, 1] == 0.0:
        raise ValueError("K has a zero focal length")
    return K


def _as_points(p: ArrayLike) -> FloatArray:
    p = np.asarray(p, dtype=np.float64)
    if p.shape[-1:] != (3,):
        raise ValueError(f"points need a last axis of length 3, got {p.shape}")
    return p


def project(
    K: ArrayLike, p_C: ArrayLike, *, min_depth: float = 0.0
) -> tuple[FloatArray, BoolArray]:
    """Project camera-frame points ``p_C`` (..., 3) to pixels.

    Returns ``(uv, valid)``: ``uv`` (..., 2) holds ``(u, v)``, ``valid`` (...) is
    ``z > min_depth`` (and finite). Where ``valid`` is False ``uv`` is NaN, never ``inf`` or a
    mirrored point behind the camera.
    """
    K = _as_K(K)
    p = _as_points(p_C)
    z = p[..., 2]
    valid = np.isfinite(p).all(axis=-1) & (z > min_depth)
    z_safe = np.where(valid, z, 1.0)
    xn = p[..., 0] / z_safe
    yn = p[..., 1] / z_safe
    u = K[0, 0] * xn + K[0, 1] * yn + K[0, 2]
    v = K[1, 1] * yn + K[1, 2]
    uv = np.stack([u, v], axis=-1)
    return np.where(valid[..., None], uv, np.nan), valid


def backproject(K: ArrayLike, u: ArrayLike, v: ArrayLike, z: ArrayLike) -> FloatArray:
    """Camera-frame point(s) at pixel ``(u, v)`` with depth ``z`` (the z coordinate, metres).

    ``u``, ``v`` and ``z`` broadcast; the result has shape ``(*broadcast_shape, 3)``. Inverse of
    :func:`project` for ``z > 0``.
    """
    K = _as_K(K)
    u, v, z = np.broadcast_arrays(*(np.asarray(a, dtype=np.float64) for a in (u, v, z)))
    yn = (v - K[1, 2]) / K[1, 1]
    xn = (u - K[0, 2] - K[0, 1] * yn) / K[0, 0]
    return np.stack([xn * z, yn * z, z], axis=-1)


def depth_to_points(depth_m: ArrayLike, K: ArrayLike) -> FloatArray:
    """Point image (H, W, 3) in the camera frame from a depth image ``depth_m`` (H, W) [m].

    Pixel ``(row v, column u)`` maps to ``backproject(K, u, v, depth_m[v, u])``. Pixels with no
    depth (``depth <= 0`` or non-finite, the RealSense "no data" value is 0) are NaN in all
    three coordinates; ``np.isfinite(points[..., 2])`` is the validity mask. Integer depth
    images must be converted to metres by the caller (multiply by the depth scale).
    """
    d = np.asarray(depth_m)
    if d.ndim != 2:
        raise ValueError(f"depth image must have shape (H, W), got {d.shape}")
    if not np.issubdtype(d.dtype, np.floating):
        raise ValueError(f"depth_m must be a float image in metres, got dtype {d.dtype}")
    d = d.astype(np.float64)
    H, W = d.shape
    v, u = np.mgrid[0:H, 0:W].astype(np.float64)
    valid = np.isfinite(d) & (d > 0.0)
    return backproject(K, u, v, np.where(valid, d, np.nan))


def projection_jacobian(K: ArrayLike, p_C: ArrayLike) -> FloatArray:
    """``d(u, v)/d p_C`` (..., 2, 3) of :func:`project` at camera-frame points ``p_C`` (..., 3).

    ``[[fx/z, s/z, -(fx x + s y)/z²], [0, fy/z, -fy y/z²]]``. Undefined (inf/NaN) at ``z = 0``.
    """
    K = _as_K(K)
    p = _as_points(p_C)
    x, y, z = p[..., 0], p[..., 1], p[..., 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        inv_z = 1.0 / z
        zero = np.zeros_like(z)
        # Jacobian of the normalized coordinates (x/z, y/z), then the linear part of K.
        N = np.stack(
            [
                np.stack([inv_z, zero, -x * inv_z * inv_z], axis=-1),
                np.stack([zero, inv_z, -y * inv_z * inv_z], axis=-1),
            ],
            axis=-2,
        )
        return np.matmul(K[:2, :2], N)
