"""Motion blur of a rendered colour frame over the sensor's exposure time.

A camera pixel integrates light over the exposure ``[t − T/2, t + T/2]``; a frame rendered at
the mid-exposure instant ``t`` is turned into that integral cheaply, from the motion between
``t`` and ``t + T/2`` (the motion is taken as linear over the exposure, whose ``T`` ≤ 33 ms is
short against a gait cycle):

* **Static scene** (floor, sheets, walls, clutter): the camera's own motion moves every point
  by the image displacement of its 3-D point between the two camera poses. The displacement
  varies smoothly down the image, so the image is cut into horizontal bands and each band is
  convolved with a line kernel along its median displacement (one ``cv2.filter2D`` per band).
* **Legs and shoes**: each pixel's 3-D point moves with its part — a shoe rigidly
  (``T_WfromShoe(t + T/2) · T_WfromShoe(t)⁻¹``), a trouser segment with the displacement of its
  axis end points interpolated along the axis — and the camera moves too; the exposure-long
  image displacement of every leg/shoe pixel is spread to the pixels around it (nearest
  leg/shoe pixel, up to the largest displacement), and the premultiplied body layer is averaged
  over sub-exposure samples taken backwards along that displacement, then laid over the
  blurred static scene. Behind the body the static scene is the environment pass (floor,
  walls), which the moving leg uncovers during the exposure.

Depth, labels and instances are not blurred: they stay the exact mid-exposure instant (a
labelling tool marks one instant; the D455's depth comes from separate global-shutter imagers
with their own, shorter exposure, and a stereo matcher does not average surfaces — motion at
depth edges shows up as the flying pixels and holes of :mod:`gaitnet.sim.sensor_depth`).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from gaitnet.sim.render_prims import T_WfromShoe
from gaitnet.sim.render_types import F32, Rays
from gaitnet.sim.scene import INSTANCE_LEFT, INSTANCE_RIGHT, LABEL_FOOT, LABEL_LEG, BodyState

BANDS = 8  # horizontal bands of the static scene's blur
STEP_PX = 2.0  # sub-exposure sample spacing along the body's displacement [px]
MAX_SAMPLES = 24
FAR_M = 1e3  # depth used for pixels that hit nothing (rotation only)
_INSTANCE = {"left": INSTANCE_LEFT, "right": INSTANCE_RIGHT}


@dataclass(frozen=True, eq=False)
class Motion:
    """The exposure's second half: camera pose and body state at ``t + T/2``, given the frame
    rendered at ``t`` (pose ``T_WfromC``, body ``body``)."""

    T_WfromC: np.ndarray
    body: BodyState
    T_WfromC_end: np.ndarray
    body_end: BodyState


def _project(K: np.ndarray, T_CfromW: np.ndarray, p_W: np.ndarray) -> np.ndarray:
    p = p_W @ T_CfromW[:3, :3].T + T_CfromW[:3, 3]
    z = np.maximum(p[:, 2], 1e-6)
    return np.stack([K[0, 0] * p[:, 0] / z + K[0, 1] * p[:, 1] / z + K[0, 2],
                     K[1, 1] * p[:, 1] / z + K[1, 2]], axis=1)  # fmt: skip


def _points_W(rays: Rays, depth: F32, T_WfromC: np.ndarray, v, u) -> np.ndarray:
    """World points of pixels (v, u) with z-depth ``depth``."""
    z = np.minimum(depth[v, u].astype(np.float64), FAR_M)
    p_C = np.stack([rays.xn[v, u] * z, rays.yn[v, u] * z, z], axis=1)
    return p_C @ T_WfromC[:3, :3].T + T_WfromC[:3, 3]


def _body_points_end(p_W: np.ndarray, label: NDArray, instance: NDArray, m: Motion) -> np.ndarray:
    """Where the body points ``p_W`` (with their label / instance) are at ``t + T/2``."""
    out = p_W.copy()
    for shoe, shoe_end in zip(m.body.shoes, m.body_end.shoes, strict=True):
        sel = (label == LABEL_FOOT) & (instance == _INSTANCE[shoe.side])
        if sel.any():
            T = T_WfromShoe(shoe_end) @ np.linalg.inv(T_WfromShoe(shoe))
            out[sel] = p_W[sel] @ T[:3, :3].T + T[:3, 3]
    for side, inst in _INSTANCE.items():
        sel = np.flatnonzero((label == LABEL_LEG) & (instance == inst))
        segs = [(a, b) for a, b in zip(m.body.legs, m.body_end.legs, strict=True) if a.side == side]
        if sel.size == 0 or not segs:
            continue
        p = p_W[sel]
        best = np.full(sel.size, np.inf)
        disp = np.zeros((sel.size, 3))
        for seg, seg_end in segs:
            a, b = np.asarray(seg.p_top_W, float), np.asarray(seg.p_bottom_W, float)
            ab = b - a
            s = np.clip((p - a) @ ab / max(float(ab @ ab), 1e-12), 0.0, 1.0)
            dist = np.linalg.norm(p - (a + s[:, None] * ab), axis=1)
            da = np.asarray(seg_end.p_top_W, float) - a
            db = np.asarray(seg_end.p_bottom_W, float) - b
            near = dist < best
            best[near] = dist[near]
            disp[near] = (1 - s[near, None]) * da + s[near, None] * db
        out[sel] = p + disp
    return out


def _line_kernel(d: np.ndarray) -> np.ndarray:
    """Normalised kernel of a uniform line of displacement ``d`` (dx, dy) [px], centred; the
    kernel is only as large as the line's bounding box (filter2D's cost is its area)."""
    rx, ry = int(np.ceil(abs(d[0]) / 2)) + 1, int(np.ceil(abs(d[1]) / 2)) + 1
    n = max(2, int(np.ceil(np.hypot(*d) / 0.5)) + 1)
    k = np.zeros((2 * ry + 1, 2 * rx + 1), np.float32)
    s = np.linspace(-0.5, 0.5, n)
    x, y = rx + s * d[0], ry + s * d[1]
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = x - x0, y - y0
    for wx, dx in ((1 - fx, 0), (fx, 1)):
        for wy, dy in ((1 - fy, 0), (fy, 1)):
            np.add.at(k, (y0 + dy, x0 + dx), (wx * wy).astype(np.float32))
    return k / k.sum()


def _blur_static(rgb: F32, depth: F32, rays: Rays, K: np.ndarray, m: Motion) -> F32:
    """Camera-motion blur of ``rgb`` by horizontal bands (module docstring)."""
    h, w = depth.shape
    edges = np.linspace(0, h, BANDS + 1).round().astype(int)
    step = max(1, min(h, w) // 40)
    v, u = np.meshgrid(np.arange(step // 2, h, step), np.arange(step // 2, w, step), indexing="ij")
    v, u = v.ravel(), u.ravel()
    p_W = _points_W(rays, depth, m.T_WfromC, v, u)
    d_all = 2.0 * (_project(K, np.linalg.inv(m.T_WfromC_end), p_W) - np.stack([u, v], axis=1))
    out = np.empty_like(rgb)
    for r0, r1 in zip(edges[:-1], edges[1:], strict=True):
        sel = (v >= r0) & (v < r1)
        d = np.median(d_all[sel], axis=0) if sel.any() else np.zeros(2)
        if np.hypot(*d) < 0.25:
            out[r0:r1] = rgb[r0:r1]
            continue
        k = _line_kernel(d)
        pad = k.shape[0] // 2
        a0, a1 = max(0, r0 - pad), min(h, r1 + pad)
        band = cv2.filter2D(rgb[a0:a1], -1, k, borderType=cv2.BORDER_REFLECT)
        out[r0:r1] = band[r0 - a0 : r1 - a0]
    return out


SEED_STEP = 3  # the body's displacement is computed on every 3rd pixel and filled in between


def motion_blur(
    rgb: F32,
    env_rgb: F32,
    depth: F32,
    label: NDArray[np.uint8],
    instance: NDArray[np.uint8],
    rays: Rays,
    K: np.ndarray,
    m: Motion,
) -> F32:
    """The frame ``rgb`` (rendered at mid-exposure) integrated over the exposure (module doc).

    ``env_rgb`` is the environment pass alone (what the legs and shoes hide), ``depth``,
    ``label``, ``instance`` the frame's maps, ``rays`` its camera's ray table.
    """
    body = label > 0
    mask = body.view(np.uint8)
    static = rgb.copy()
    cv2.copyTo(env_rgb, mask, static)
    out = _blur_static(static, depth, rays, K, m)
    if not body.any():
        return out
    vb, ub = np.nonzero(body)
    h, w = label.shape
    # displacement on a sparse set of body pixels (smooth within a part), raster order kept
    pick = (vb % SEED_STEP == 0) & (ub % SEED_STEP == 0)
    pick[:: max(1, vb.size // 64)] = True  # parts thinner than the seed grid
    v, u = vb[pick], ub[pick]
    p_W = _points_W(rays, depth, m.T_WfromC, v, u)
    p_end = _body_points_end(p_W, label[v, u], instance[v, u], m)
    d = 2.0 * (_project(K, np.linalg.inv(m.T_WfromC_end), p_end) - np.stack([u, v], axis=1))
    d = d.astype(np.float32)
    reach = float(np.abs(d).max()) / 2 + 2
    r0, r1 = max(0, int(vb[0] - reach)), min(h, int(vb[-1] + reach) + 1)
    c0, c1 = max(0, int(ub.min() - reach)), min(w, int(ub.max() + reach) + 1)
    roi = mask[r0:r1, c0:c1]
    not_seed = np.ones(roi.shape, np.uint8)
    not_seed[v - r0, u - c0] = 0
    # every pixel of the region takes the displacement of its nearest seed
    _, nearest = cv2.distanceTransformWithLabels(
        not_seed, cv2.DIST_L2, 3, labelType=cv2.DIST_LABEL_PIXEL
    )  # labels number the seeds in raster order, as np.nonzero lists them
    idx = nearest.ravel() - 1
    fx = np.take(d[:, 0], idx).reshape(nearest.shape)
    fy = np.take(d[:, 1], idx).reshape(nearest.shape)
    n = int(np.clip(np.ceil(float(np.hypot(d[:, 0], d[:, 1]).max()) / STEP_PX), 1, MAX_SAMPLES))
    alpha = roi.astype(np.float32)
    layer = cv2.merge([c * alpha for c in cv2.split(rgb[r0:r1, c0:c1])] + [alpha])
    gx = np.broadcast_to(np.arange(c1 - c0, dtype=np.float32)[None, :], fx.shape).copy()
    gy = np.broadcast_to(np.arange(r1 - r0, dtype=np.float32)[:, None], fx.shape).copy()
    acc = np.zeros_like(layer)
    mx, my = np.empty_like(fx), np.empty_like(fy)
    for i in range(n):
        s = float((i + 0.5) / n - 0.5)
        cv2.scaleAdd(fx, -s, gx, dst=mx)
        cv2.scaleAdd(fy, -s, gy, dst=my)
        sample = cv2.remap(layer, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)
        cv2.add(acc, sample, dst=acc)
    *colour, cover = cv2.split(acc * np.float32(1.0 / n))
    region = out[r0:r1, c0:c1]
    keep = 1 - cover
    region[:] = cv2.merge([b * keep + c for b, c in zip(cv2.split(region), colour, strict=True)])
    return out
