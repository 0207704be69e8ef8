"""Stance-foot candidates from the segmenter's foot pixels where the depth image has none.

A D4xx computes depth in its left imager; what the right imager cannot see behind a nearer
surface (the stereo shadow) has no depth. Under a knee flexed 25–30° in early stance (the CMU
walkers) the near thigh and shin hide most of a waist camera's view of the planted foot, and the
toe that still shows lies in the thigh's shadow: 690–890 foot pixels in the colour image, 12–24
of them with depth (docs/benchmarks.md, *Real motion*), so
:func:`gaitnet.vio.feet.detect_foot_candidates` finds nothing. The segmenter labels that toe from
colour (and HHA), so ``gaitnet infer`` hands its foot pixels back to the filter
(``pipeline.segmented_stances``).

Each 8-connected component of the foot mask (at ``FootParams.stride``) of at least
``min_pixels`` pixels, at most ``segmented_max_depth_fraction`` of them with depth, is a
candidate when its pixels with depth (if any) lie below ``h_max_m`` (a shoe in the air is a swing
foot), when it lies at least ``segmented_apart_m`` from every depth candidate of the frame (that
foot is found already) and when its size on the floor passes the limits of the depth candidates
(``min_area_inside_m2`` … ``max_area_m2``, ``max_length_m``, ``max_width_m``). Its pixels'
rays are intersected with the floor plane (3.22); the foot point is laid from the farthest of
these points along the walking direction, as the depth candidates' is from the toe (``"toe"``:
``shoe_length_m / 2 − toe_margin_m`` back from the 98th percentile). Across it, the thigh above
the foot hides its outer part and the camera, nearer the body's middle, sees past the thigh's
inner edge: the foot point lies half ``shoe_width_m`` out from the inner edge of the points
(their 2nd or 98th percentile across), or in the middle of them where they are wider than that
or straddle the camera's line (CMU walking_06, the right foot's toe: 2.5 cm towards the middle
with the middle of the visible toe). A ray meets the floor beyond the surface it crosses, by the
surface's height over the tangent of the ray's depression: about 1 cm for a toe cap 3 cm high
seen from 1 m above and 0.3 m ahead; the foot point is that much long, the same for both feet,
so strides between two such points keep their length. The candidates are ``weak``
(:class:`gaitnet.vio.stance_tracker.StanceTracker` confirms them after ``weak_confirm_s``):
a swing foot moves ~10 cm per frame and never stays.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2 as cv
import numpy as np

from gaitnet.geometry.floor_plane import FloorPlane
from gaitnet.vio.feet import FootCandidate, FootParams

__all__ = ["FootMask", "segmented_foot_candidates"]


@dataclass(frozen=True)
class FootMask:
    """The segmenter's foot pixels of one frame: ``pixels`` (h, w) bool, the box of the frame
    (full resolution) whose top-left pixel is ``origin`` ``(row, column)``."""

    origin: tuple[int, int]
    pixels: np.ndarray

    @classmethod
    def from_labels(cls, labels: np.ndarray, foot_label: int = 1) -> FootMask | None:
        """The pixels of ``labels`` (H, W) equal to ``foot_label`` in their bounding box; None
        when there are none."""
        on = np.asarray(labels) == foot_label
        rows, cols = np.flatnonzero(on.any(axis=1)), np.flatnonzero(on.any(axis=0))
        if len(rows) == 0:
            return None
        r0, r1, c0, c1 = int(rows[0]), int(rows[-1]) + 1, int(cols[0]), int(cols[-1]) + 1
        return cls((r0, c0), on[r0:r1, c0:c1].copy())


def segmented_foot_candidates(
    mask: FootMask,
    depth_m: np.ndarray,
    K: np.ndarray,
    plane: FloorPlane,
    params: FootParams,
    found: list[FootCandidate],
) -> list[FootCandidate]:
    """Candidates of the foot pixels of ``mask`` that the depth image does not show (module
    docstring), largest first, at most ``max_candidates − len(found)``; ``found``: the frame's
    depth candidates (:func:`gaitnet.vio.feet.detect_foot_candidates`)."""
    room = params.max_candidates - len(found)
    if room <= 0:
        return []
    s = int(params.stride)
    r0, c0 = mask.origin
    # the working grid of detect_foot_candidates: full-resolution pixels (s·i, s·j)
    first_r, first_c = -(-r0 // s) * s, -(-c0 // s) * s
    sub = np.ascontiguousarray(mask.pixels[first_r - r0 :: s, first_c - c0 :: s]).astype(np.uint8)
    if not sub.any():
        return []
    n_lab, labels, stats, _ = cv.connectedComponentsWithStats(sub, connectivity=8)
    depth = np.asarray(depth_m, dtype=np.float64)
    K = np.asarray(K, dtype=np.float64)
    fwd = np.array([0.0, 0.0, 1.0]) - plane.n_C[2] * plane.n_C
    fwd /= np.linalg.norm(fwd)
    side = np.cross(plane.n_C, fwd)
    out = []
    for lab in np.argsort(-stats[1:, cv.CC_STAT_AREA]) + 1:
        if stats[lab, cv.CC_STAT_AREA] < params.min_pixels or len(out) == room:
            break
        vv, uu = np.nonzero(labels == lab)
        rows, cols = first_r + s * vv, first_c + s * uu
        cand = _candidate(rows, cols, depth, K, plane, params, fwd, side)
        if cand is None:
            continue
        if any(np.linalg.norm(cand.p_FinC - c.p_FinC) < params.segmented_apart_m for c in found):
            continue
        out.append(cand)
    return out


def _candidate(
    rows: np.ndarray,
    cols: np.ndarray,
    depth: np.ndarray,
    K: np.ndarray,
    plane: FloorPlane,
    params: FootParams,
    fwd: np.ndarray,
    side: np.ndarray,
) -> FootCandidate | None:
    """The candidate of one component's full-resolution pixels, or None (module docstring)."""
    z = depth[rows, cols]
    valid = np.isfinite(z) & (z > 0)
    if valid.mean() > params.segmented_max_depth_fraction:
        return None  # the depth shows this one: detect_foot_candidates has judged it
    rays = np.stack([(cols - K[0, 2]) / K[0, 0], (rows - K[1, 2]) / K[1, 1], np.ones(len(z))], 1)
    if valid.any():
        height = plane.height(rays[valid] * z[valid, None])
        if float(np.percentile(height, 10.0)) > params.h_max_m:
            return None  # a shoe in the air (the few pixels of a planted toe's with depth
            # are often the near thigh's edge, labelled foot: their lowest count)
    along = rays @ plane.n_C
    down = along < -1e-6  # rays that meet the floor in front of the camera
    if down.sum() < params.min_pixels:
        return None
    t = -plane.h / along[down]
    Q = rays[down] * t[:, None]
    # floor area as detect_foot_candidates measures it: z² / (fx fy) / |n·r| per pixel of the
    # working grid (s² full-resolution pixels), z = t (the rays' third component is 1)
    n_dot = np.maximum(np.abs(along[down]), 0.2 * np.linalg.norm(rays[down], axis=1))
    s = int(params.stride)
    area = float(np.sum(t**2 / n_dot) * s * s / (K[0, 0] * K[1, 1]))
    if not params.min_area_inside_m2 <= area <= params.max_area_m2:
        return None
    q2 = np.stack([Q @ fwd, Q @ side], axis=1)
    cov = np.cov((q2 - q2.mean(axis=0)).T) if len(q2) > 2 else np.eye(2) * 1e-6
    evals, evecs = np.linalg.eigh(cov)
    length = 4.0 * float(np.sqrt(max(evals[1], 0.0)))
    width = 4.0 * float(np.sqrt(max(evals[0], 0.0)))
    if length > params.max_length_m or width > params.max_width_m:
        return None
    toe_f = float(np.percentile(q2[:, 0], 98.0))
    back = 0.5 * params.shoe_length_m - params.toe_margin_m
    p_F = (toe_f - back) * fwd + _lateral(q2[:, 1], params) * side - plane.h * plane.n_C
    axis_C = evecs[0, 1] * fwd + evecs[1, 1] * side
    if axis_C @ fwd < 0:
        axis_C = -axis_C
    H, W = depth.shape
    b = params.border_px
    at_border = bool(
        rows.min() <= b or cols.min() <= b or rows.max() >= H - 1 - b or cols.max() >= W - 1 - b
    )
    return FootCandidate(
        p_FinC=p_F,
        n_pixels=len(rows),
        area_m2=area,
        ellipse=_ellipse(rows, cols),
        length_m=length,
        width_m=width,
        axis_C=axis_C,
        at_border=at_border,
        centroid_C=Q.mean(axis=0),
        weak=True,
        segmented=True,
    )


def _lateral(across: np.ndarray, params: FootParams) -> float:
    """The shoe's centre across the walking direction from its points' lateral positions
    ``across`` (0: below the camera): the middle of their 2nd–98th percentile extent, or, for
    a shoe to one side that shows less than its width, half ``shoe_width_m`` out from its inner
    edge (the near thigh hides the outer part; module docstring)."""
    lo, hi = (float(v) for v in np.percentile(across, [2.0, 98.0]))
    middle, half = 0.5 * (lo + hi), 0.5 * params.shoe_width_m
    if lo > 0.0:
        return max(middle, lo + half)
    if hi < 0.0:
        return min(middle, hi - half)
    return middle


def _ellipse(
    rows: np.ndarray, cols: np.ndarray
) -> tuple[tuple[float, float], tuple[float, float], float]:
    """``cv.fitEllipse`` of the pixels (full resolution), or their mean with unit axes when
    there are fewer than 5."""
    if len(rows) < 5:
        return (float(cols.mean()), float(rows.mean())), (1.0, 1.0), 0.0
    (cx, cy), axes, angle = cv.fitEllipse(np.stack([cols, rows], axis=1).astype(np.float32))
    return (float(cx), float(cy)), (float(axes[0]), float(axes[1])), float(angle)
