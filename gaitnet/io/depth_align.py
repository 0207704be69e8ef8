"""Re-projection of a depth image into the colour camera (:func:`align_depth_to_color`)."""

from __future__ import annotations

import numpy as np

from gaitnet.io.types import CameraIntrinsics

_SPLAT_MARGIN_PX = 0.25  # see align_depth_to_color


def align_depth_to_color(
    depth_m: np.ndarray,
    depth: CameraIntrinsics,
    color: CameraIntrinsics,
    T_CfromD: np.ndarray,
) -> np.ndarray:
    """Re-project a depth image into the colour camera (pinhole models, distortion ignored).

    Every valid depth pixel (``> 0`` and finite) is treated as a small fronto-parallel square
    at its depth: its four corners are back-projected, moved with ``T_CfromD`` (``p_C = R p_D
    + t``) and projected into colour; every colour pixel whose centre falls inside the
    projected square's bounding box, grown by ``_SPLAT_MARGIN_PX`` on each side, receives the
    colour-frame depth of the pixel's centre point. Where several depth pixels land on one
    colour pixel the nearest wins (z-buffer). Splatting the footprint rather than a single
    point leaves no holes when colour has the finer resolution; the margin closes the thin
    cracks between neighbouring footprints of a slanted surface (their depths differ, so
    parallax separates them slightly) at the cost of growing foreground edges by at most one
    colour pixel.

    Returns float32 metres of shape ``(color.height, color.width)``, 0 where nothing landed.
    """
    z = np.asarray(depth_m, dtype=np.float64)
    if z.shape != (depth.height, depth.width):
        raise ValueError(f"depth image is {z.shape}, intrinsics say {(depth.height, depth.width)}")
    W, H = color.width, color.height
    out = np.full(H * W, np.inf)
    valid = np.isfinite(z) & (z > 0)
    v, u = np.nonzero(valid)
    if u.size:
        zs = z[v, u]
        R = np.asarray(T_CfromD, dtype=np.float64)[:3, :3]
        t = np.asarray(T_CfromD, dtype=np.float64)[:3, 3]

        def to_color(du: float, dv: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            x = (u + du - depth.cx) / depth.fx * zs
            y = (v + dv - depth.cy) / depth.fy * zs
            X = R[0, 0] * x + R[0, 1] * y + R[0, 2] * zs + t[0]
            Y = R[1, 0] * x + R[1, 1] * y + R[1, 2] * zs + t[1]
            Z = R[2, 0] * x + R[2, 1] * y + R[2, 2] * zs + t[2]
            with np.errstate(divide="ignore", invalid="ignore"):
                return color.fx * X / Z + color.cx, color.fy * Y / Z + color.cy, Z

        _, _, zc = to_color(0.0, 0.0)
        corners = [to_color(du, dv) for du in (-0.5, 0.5) for dv in (-0.5, 0.5)]
        ok = zc > 0
        for _, _, zk in corners:
            ok &= zk > 0
        us = np.stack([c[0] for c in corners])
        vs = np.stack([c[1] for c in corners])
        m = _SPLAT_MARGIN_PX
        with np.errstate(invalid="ignore"):
            x0 = np.ceil(us.min(axis=0) - m)
            x1 = np.floor(us.max(axis=0) + m)
            y0 = np.ceil(vs.min(axis=0) - m)
            y1 = np.floor(vs.max(axis=0) + m)
        ok &= np.isfinite(x0) & np.isfinite(x1) & np.isfinite(y0) & np.isfinite(y1)
        ok &= (x1 >= 0) & (x0 <= W - 1) & (y1 >= 0) & (y0 <= H - 1)
        x0 = np.clip(x0[ok], 0, W - 1).astype(np.int64)
        x1 = np.clip(x1[ok], 0, W - 1).astype(np.int64)
        y0 = np.clip(y0[ok], 0, H - 1).astype(np.int64)
        y1 = np.clip(y1[ok], 0, H - 1).astype(np.int64)
        zc = zc[ok]
        span_x, span_y = x1 - x0, y1 - y0
        keep = (span_x >= 0) & (span_y >= 0)
        if keep.any():
            # A footprint spans a few pixels at most (resolution ratio); cap it so that a
            # degenerate projection (a point grazing the image plane) cannot explode.
            max_x = min(int(span_x[keep].max()), 16)
            max_y = min(int(span_y[keep].max()), 16)
            for dy in range(max_y + 1):
                for dx in range(max_x + 1):
                    m = keep & (span_x >= dx) & (span_y >= dy)
                    if m.any():
                        idx = (y0[m] + dy) * W + (x0[m] + dx)
                        np.minimum.at(out, idx, zc[m])
    out[~np.isfinite(out)] = 0.0
    return out.reshape(H, W).astype(np.float32)
