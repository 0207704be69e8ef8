"""Foot keypoints from a label map and depth (thesis sec. 4.1.4, eq. 4.1).

:func:`foot_keypoints` turns the segmenter's label map (0 background, 1 foot, 2 leg; 255 is
treated as background) and the aligned depth image into one :class:`FootDetection` per foot:

1. **Depth-consistent blob filtering.** Foot pixels are grouped into 8-connected blobs
   (``cv2.connectedComponentsWithStats``). With a floor plane (given, or fitted as for HHA:
   :func:`gaitnet.segmentation.hha.find_floor` with the gravity prior, or the no-IMU prior),
   foot pixels less than ``min_foot_height_m`` above the floor are floor seen as foot at the
   blob's edge and are removed (the thesis's "threshold constraint on height"), and a blob whose
   median height is above ``max_foot_height_m`` is no foot. Blobs smaller than
   ``min_area_fraction`` of the image are noise. In a blob with at least ``min_depth_pixels``
   valid depths, pixels farther than ``max_depth_dev_m`` from the blob's median depth are
   outliers (background or the other foot behind a mislabelled edge) and are removed; a blob
   where they are more than ``1 − min_consistent_fraction`` of the valid depths is not one
   surface and is dropped. Pixels without depth stay (the D455 has no depth closer than ~0.4 m
   and on dark shoes). A foot whose mid point lies farther than ``max_distance_m`` from the
   camera along the floor (about one leg length; needs gravity or a floor) is something on the
   floor ahead, not a foot, and is dropped before the sides are assigned. So is a blob whose
   area at its depth (``z² / (f_x f_y)`` per pixel; pixels without depth at the blob's median
   depth) is outside ``min_area_m2``–``max_area_m2``: not a shoe's size. With ``dropped``
   (a Counter), every blob dropped for what it is, not for its pixel count, is counted by
   reason (:data:`DROP_REASONS`).
2. **Keypoints** (eq. 4.1): with ``S_f`` the blob's pixels and ``a`` the image axis
   ``keypoint_axis`` (``"u"`` as in the thesis, whose camera had the walking direction along
   ``u``; ``"v"``, the default, for an upright camera pitched down, where forward is up in the
   image), ``top`` is the mean pixel of ``S_f`` within ``margin_top_px`` of the forward extreme
   of ``a`` (``u_max`` for ``"u"``, ``v_min`` for ``"v"``), ``bottom`` the mean within
   ``margin_bottom_px`` of the other extreme, ``mid`` the mean of all of ``S_f``. The thesis
   writes strict inequalities at both ends (``u_max − M_t < u < u_max``), which leave the set
   empty for ``M_t = 1``; here the extreme row or column is included.
3. **3-D points**: the median of the valid depths of the blob's pixels within
   ``depth_radius_px`` of a keypoint (a square window), back-projected through the keypoint's
   pixel (``K``). Fewer than ``min_depth_pixels`` valid depths there: the point is missing
   (``None`` in :attr:`FootDetection.keypoints_C`), never NaN.
4. **Left / right.** The lateral axis is ``left = up × forward`` with ``up`` from gravity (or
   the floor normal) and ``forward`` the body's forward in the camera frame
   (``forward_in_camera``, which ``gaitnet segment`` and ``gaitnet infer`` estimate from the
   standing frames at the start, :mod:`gaitnet.segmentation.midline`; until then, and by
   default, the camera's optical axis) projected on the floor (the camera's ``−y`` when that is
   nearly vertical); without ``up``, ``left`` is the camera's ``−x``. A foot's lateral position
   is its mid point's 3-D position along ``left`` (or, when the mid point has no depth, where
   the mid pixel's ray meets the floor; without a floor, the ray's direction at unit depth). Two
   feet further apart than ``min_separation_m`` laterally: the one more to the left is left.
   Otherwise, and with one foot in view, each foot on its own: the sign of its lateral position
   minus ``lateral_offset_m`` says the side. Optionally, in a band ``± min_lateral_m`` around
   zero (0 by default: measured worse, see the key), the leg blob attached to the foot (the leg
   blob with most pixels within ``attach_px`` of the foot) says it, by the lateral direction of
   the leg's pixel farthest from the foot (its hip end); with no attached leg the side is
   ``"unknown"``. Feet beyond the two largest are ``"unknown"``. A blob that spreads wider along
   ``left`` than one shoe can (``split_width_m``) is two feet merged by the segmenter's rim
   (feet side by side are a few centimetres apart): it is split in two at Otsu's threshold of
   its pixels' lateral positions before the keypoints are found. On the default simulated
   session the true label maps show two separate feet in 211 frames, the committed segmenter's
   in only 43 (a merged blob is sided as one foot by its lateral position: 79 of 265 such feet
   got the wrong side); split, 402 of 408 paired feet and all 104 lone feet get their true side.

   The rule assumes a camera worn at the middle of the waist looking forward-down; it fails
   where a foot crosses the body's midline (cross-over steps, turning on the spot), where the
   camera is worn off-centre (``lateral_offset_m``, which ``gaitnet segment`` and ``gaitnet
   infer`` estimate from the first frames: ``midline_frames``) or yawed on the body so far that
   its projected optical axis while standing misses the walking direction by more than the
   feet's half-spacing over their distance, and where a foot turned sideways spreads wider than
   ``split_width_m`` (it is split in two).
"""

from __future__ import annotations

import logging
from collections import Counter
from typing import TypeAlias

import cv2
import numpy as np

from gaitnet.errors import InputError
from gaitnet.geometry.floor_plane import FloorPlane, height_map
from gaitnet.geometry.two_groups import otsu_split
from gaitnet.segmentation.body_axes import left_axis
from gaitnet.segmentation.foot_types import KEYPOINT_NAMES, FootDetection, FootKeypointParams
from gaitnet.segmentation.hha import find_floor

log = logging.getLogger(__name__)

__all__ = [
    "DROP_REASONS",
    "KEYPOINT_NAMES",
    "FootDetection",
    "FootKeypointParams",
    "foot_keypoints",
    "kept_feet_labels",
]

FOOT, LEG = 1, 2


def _check(labels, depth_m, K) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    labels = np.asarray(labels)
    depth = np.asarray(depth_m)
    if labels.ndim != 2 or not np.issubdtype(labels.dtype, np.integer):
        raise InputError(
            f"foot keypoints: labels must be an (H, W) integer map, got "
            f"{labels.dtype} {labels.shape}"
        )
    if depth.shape != labels.shape or not np.issubdtype(depth.dtype, np.floating):
        raise InputError(
            f"foot keypoints: depth must be float metres of shape {labels.shape}, "
            f"got {depth.dtype} {depth.shape}"
        )
    K = np.asarray(K, dtype=np.float64)
    if K.shape != (3, 3) or not np.isfinite(K).all() or K[0, 0] <= 0 or K[1, 1] <= 0:
        raise InputError("foot keypoints: K must be a finite 3×3 camera matrix")
    z = np.where(np.isfinite(depth) & (depth > 0), depth, 0).astype(np.float32)
    return labels, z, K


def _ray(K: np.ndarray, u: float, v: float) -> np.ndarray:
    return np.array([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], 1.0])


def _keypoint_pixels(
    mask: np.ndarray, p: FootKeypointParams, origin: tuple[int, int] = (0, 0)
) -> dict[str, tuple[float, float]]:
    """Eq. 4.1 on the blob's pixels (module docstring); ``mask`` may be a box of the image
    whose first pixel is ``origin`` (u, v)."""
    v, u = np.nonzero(mask)
    u, v = u + origin[0], v + origin[1]
    uf, vf = u.astype(np.float64), v.astype(np.float64)
    if p.keypoint_axis == "u":
        a, hi_is_top = uf, True
    else:
        a, hi_is_top = vf, False
    lo, hi = a.min(), a.max()
    near_hi = a > hi - p.margin_top_px if hi_is_top else a > hi - p.margin_bottom_px
    near_lo = a < lo + p.margin_bottom_px if hi_is_top else a < lo + p.margin_top_px
    top, bottom = (near_hi, near_lo) if hi_is_top else (near_lo, near_hi)
    return {
        "top": (float(uf[top].mean()), float(vf[top].mean())),
        "mid": (float(uf.mean()), float(vf.mean())),
        "bottom": (float(uf[bottom].mean()), float(vf[bottom].mean())),
    }


def _point(
    z: np.ndarray, mask: np.ndarray, K: np.ndarray, uv: tuple[float, float], p: FootKeypointParams
) -> np.ndarray | None:
    H, W = z.shape
    u0, v0 = round(uv[0]), round(uv[1])
    r = p.depth_radius_px
    ys, xs = slice(max(v0 - r, 0), min(v0 + r + 1, H)), slice(max(u0 - r, 0), min(u0 + r + 1, W))
    window = z[ys, xs][mask[ys, xs]]
    window = window[window > 0]
    if window.size < p.min_depth_pixels:
        return None
    return _ray(K, *uv) * float(np.median(window))


#: Why a foot blob is dropped (the keys of ``foot_keypoints``'s ``dropped`` counter).
DROP_REASONS = ("above the floor", "not one surface", "not a shoe's size", "beyond leg reach")


def _filter_blob(
    mask: np.ndarray, z: np.ndarray, height: np.ndarray | None, p: FootKeypointParams
) -> np.ndarray | str:
    """The blob after the depth checks, or the reason it is dropped."""
    if height is not None:
        h = height[mask]
        known = np.isfinite(h)
        if known.sum() >= p.min_depth_pixels and np.median(h[known]) > p.max_foot_height_m:
            return DROP_REASONS[0]
        mask = mask & ~(np.isfinite(height) & (height < p.min_foot_height_m))
    d = z[mask]
    d = d[d > 0]
    if d.size >= p.min_depth_pixels:
        med = float(np.median(d))
        consistent = np.abs(d - med) <= p.max_depth_dev_m
        if consistent.mean() < p.min_consistent_fraction:
            return DROP_REASONS[1]
        mask = mask & ~((z > 0) & (np.abs(z - med) > p.max_depth_dev_m))
    return mask


def _area_m2(mask: np.ndarray, z: np.ndarray, K: np.ndarray) -> float | None:
    """The blob's area at its depth [m²] (module docstring); None without any depth."""
    d = z[mask]
    valid = d[d > 0]
    if valid.size == 0:
        return None
    d = np.where(d > 0, d, float(np.median(valid)))
    return float(np.sum(d.astype(np.float64) ** 2) / (K[0, 0] * K[1, 1]))


_Box: TypeAlias = tuple[slice, slice]  # rows, columns of a bounding box


def _blobs(mask: np.ndarray, min_area: float) -> list[tuple[np.ndarray, _Box]]:
    """Each 8-connected blob of ``mask`` of at least ``min_area`` pixels, largest first, as its
    mask within its bounding box and that box (the per-blob work then touches the box only).
    The components are labelled within the box around all of ``mask``, its top on an even row:
    OpenCV's 8-connected labelling scans 2×2 blocks from the first row it is given, so the
    labels, which order blobs of equal area, are then those of the whole image."""
    rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    if rows.size == 0:
        return []
    y0, x0 = int(rows[0]) & ~1, int(cols[0])
    around = np.ascontiguousarray(mask[y0 : rows[-1] + 1, x0 : cols[-1] + 1], dtype=np.uint8)
    n, comp, stats, _ = cv2.connectedComponentsWithStats(around, connectivity=8)
    keep = [i for i in range(1, n) if stats[i, cv2.CC_STAT_AREA] >= max(min_area, 1)]
    keep.sort(key=lambda i: -stats[i, cv2.CC_STAT_AREA])
    blobs = []
    for i in keep:
        x, y, w, h = (int(v) for v in stats[i, :4])
        own = comp[y : y + h, x : x + w] == i
        blobs.append((own, (slice(y0 + y, y0 + y + h), slice(x0 + x, x0 + x + w))))
    return blobs


def _lateral(
    K: np.ndarray,
    uv: tuple[float, float],
    p_C: np.ndarray | None,
    plane: FloorPlane | None,
    left: np.ndarray,
) -> float:
    if p_C is None and plane is not None:
        p_C = plane.intersect_ray(_ray(K, *uv))
    if p_C is None:
        p_C = _ray(K, *uv)
    return float(p_C @ left)


def _beyond_reach(
    K: np.ndarray,
    uv: tuple[float, float],
    p_C: np.ndarray | None,
    plane: FloorPlane | None,
    up: np.ndarray | None,
    max_distance_m: float,
) -> bool:
    """Whether the foot point (or, without its depth, where its pixel's ray meets the floor)
    lies farther than ``max_distance_m`` from the camera perpendicular to ``up``."""
    if up is None or not np.isfinite(max_distance_m):
        return False
    if p_C is None and plane is not None:
        p_C = plane.intersect_ray(_ray(K, *uv))
    if p_C is None:
        return False
    u = up / np.linalg.norm(up)
    return float(np.linalg.norm(p_C - (p_C @ u) * u)) > max_distance_m


def foot_keypoints(
    labels: np.ndarray,
    depth_m: np.ndarray,
    K: np.ndarray,
    params: FootKeypointParams | None = None,
    *,
    gravity_C: np.ndarray | None = None,
    plane: FloorPlane | None = None,
    dropped: Counter | None = None,
) -> list[FootDetection]:
    """The feet of one frame, largest first (module docstring).

    ``labels`` (H, W) integer label map, ``depth_m`` (H, W) float metres (0 / non-finite =
    invalid), ``K`` the camera matrix, ``gravity_C`` unit gravity (pointing down) in the camera
    frame if known, ``plane`` the floor if known; ``dropped`` counts the blobs dropped as no
    foot, by reason (:data:`DROP_REASONS`). Bad arrays raise
    :class:`~gaitnet.errors.InputError`.
    """
    dropped = Counter() if dropped is None else dropped
    p = params or FootKeypointParams()
    labels, z, K = _check(labels, depth_m, K)
    H, W = labels.shape
    foot_mask = labels == FOOT
    if not foot_mask.any():
        return []
    up = None if gravity_C is None else -np.asarray(gravity_C, dtype=np.float64)
    if plane is None and p.use_floor:
        plane = find_floor(z, K, None if up is None else up / np.linalg.norm(up), p.floor)
    if up is None and plane is not None:
        up = np.asarray(plane.n_C, dtype=np.float64)
    left = left_axis(up, p.forward_in_camera)
    feet: list[FootDetection] = []
    min_area = max(p.min_area_fraction * H * W, 1)
    for blob, box in _blobs(foot_mask, p.min_area_fraction * H * W):
        z_box, origin = z[box], (box[1].start, box[0].start)
        height = height_map(z_box, K, plane, origin) if plane is not None else None
        mask = _filter_blob(blob, z_box, height, p)
        if isinstance(mask, str):
            dropped[mask] += 1
            continue
        if mask.sum() < min_area:
            continue
        for piece in _split_merged(mask, z_box, K, left, p.split_width_m, min_area, origin):
            part = np.zeros((H, W), bool)
            part[box] = piece
            px = _keypoint_pixels(piece, p, origin)
            pts = {name: _point(z, part, K, px[name], p) for name in KEYPOINT_NAMES}
            area = _area_m2(piece, z_box, K)
            if area is not None and not p.min_area_m2 <= area <= p.max_area_m2:
                dropped[DROP_REASONS[2]] += 1
                continue
            if _beyond_reach(K, px["mid"], pts["mid"], plane, up, p.max_distance_m):
                dropped[DROP_REASONS[3]] += 1
                continue
            lateral = _lateral(K, px["mid"], pts["mid"], plane, left) - p.lateral_offset_m
            feet.append(FootDetection("unknown", px, pts, int(part.sum()), lateral, part))
    feet.sort(key=lambda f: -f.area_px)
    _assign_sides(feet, labels, K, left, p)
    return feet


def kept_feet_labels(labels: np.ndarray, feet: list[FootDetection]) -> np.ndarray:
    """``labels`` with foot pixels only where the post-processing kept a foot: foot pixels
    outside every detection's mask (floor seen as foot at a blob's rim, pixels off their blob's
    median depth, blobs too small, dropped by the depth checks or beyond ``max_distance_m``)
    become background; leg and background pixels are unchanged."""
    out = np.array(labels, copy=True)
    out[out == FOOT] = 0
    for foot in feet:
        out[foot.mask] = FOOT
    return out


def _split_merged(
    mask: np.ndarray,
    z: np.ndarray,
    K: np.ndarray,
    left: np.ndarray,
    width: float,
    min_area: float,
    origin: tuple[int, int] = (0, 0),
) -> list[np.ndarray]:
    """``mask`` as it is, or its two halves when it spreads wider than ``width`` along
    ``left`` (two feet merged into one blob; :attr:`FootKeypointParams.split_width_m`).
    ``mask`` and ``z`` may be a box of the image whose first pixel is ``origin`` (u, v)."""
    if width <= 0:
        return [mask]
    v, u = np.nonzero(mask)
    d = z[v, u]
    valid = d > 0
    if valid.sum() < 2:
        return [mask]
    d = np.where(valid, d, np.median(d[valid]))  # a hole lies at the blob's typical depth
    uu, vv = u + origin[0], v + origin[1]  # pixels of the image
    lateral = (
        (uu - K[0, 2]) / K[0, 0] * left[0] + (vv - K[1, 2]) / K[1, 1] * left[1] + left[2]
    ) * d
    lo, hi = np.percentile(lateral, [5, 95])
    if hi - lo <= width:
        return [mask]
    upper = otsu_split(lateral, lo, hi)
    parts = []
    for side in (upper, ~upper):
        part = np.zeros_like(mask)
        part[v[side], u[side]] = True
        parts.append(part)
    if min(int(part.sum()) for part in parts) < min_area:
        return [mask]
    return parts


def _leg_side(
    foot: FootDetection,
    legs: list[tuple[np.ndarray, _Box]],
    K: np.ndarray,
    left: np.ndarray,
    attach: int,
) -> str:
    """The side of the leg blob attached to ``foot`` (its pixel farthest from the foot)."""
    k = 2 * attach + 1
    near = cv2.dilate(foot.mask.astype(np.uint8), np.ones((k, k), np.uint8)) > 0
    contact = [int((leg & near[box]).sum()) for leg, box in legs]
    if not contact or max(contact) == 0:
        return "unknown"
    leg, box = legs[int(np.argmax(contact))]
    v, u = np.nonzero(leg)
    v, u = v + box[0].start, u + box[1].start
    mu, mv = foot.keypoints_px["mid"]
    far = int(np.argmax((u - mu) ** 2 + (v - mv) ** 2))
    lateral = float(_ray(K, u[far], v[far]) @ left)
    return "left" if lateral > 0 else "right"


def _assign_sides(
    feet: list[FootDetection],
    labels: np.ndarray,
    K: np.ndarray,
    left: np.ndarray,
    p: FootKeypointParams,
) -> None:
    if not feet:
        return
    pair = feet[:2]
    if len(pair) == 2 and abs(pair[0].lateral_m - pair[1].lateral_m) >= p.min_separation_m:
        a, b = sorted(pair, key=lambda f: -f.lateral_m)
        a.side, b.side = "left", "right"
        return
    legs: list[tuple[np.ndarray, _Box]] | None = None
    for foot in pair:
        if abs(foot.lateral_m) >= p.min_lateral_m and foot.lateral_m != 0.0:
            foot.side = "left" if foot.lateral_m > 0 else "right"
            continue
        if legs is None:
            H, W = labels.shape
            legs = _blobs(labels == LEG, p.min_leg_area_fraction * H * W)
        foot.side = _leg_side(foot, legs, K, left, p.attach_px)  # type: ignore[assignment]
