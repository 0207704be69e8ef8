"""Stance-foot candidates from the depth image and the floor plane (thesis (3.22)–(3.26)).

Pixels whose height above the floor lies in ``[h_min, h_max]`` (3.24) are grouped into
8-connected components (``cv.connectedComponentsWithStats``); components whose area, length or
width on the floor is outside the size limits are dropped and the two largest are kept. Each
gets an ellipse fitted to its outline (``cv.fitEllipse``, the "foot edge" of sec. 3.3.2) and a
foot point.

Depth holes. A dark shoe's depth is full of clustered holes (a D4xx cannot match a black
surface: up to 60 % of its pixels invalid); a band of holes across the shoe cuts it into
pieces, and the largest piece alone, without the toe, puts the foot point several cm back, a
different amount every frame. Pieces are therefore joined across invalid pixels that lie in
gaps up to ``hole_bridge_m`` wide (the morphological closing of the foot pixels, with the gap
converted to pixels at the median depth of the foot pixels); a seen floor pixel never joins
anything, so two feet stay apart unless a hole (a stereo shadow) spans the floor between them.
A joined group that fails the size limits (e.g. two feet side by side: too wide) is tried
piece by piece instead.

Feet side by side. Two shoes that touch (standing with the heels together and the toes out)
are one component. One wider across the walking direction than one shoe (``split_width_m``)
is split at Otsu's threshold of its pixels' lateral positions
(:func:`gaitnet.geometry.two_groups.otsu_split`); the halves are two candidates when both
pass the size limits and lie side by side (:func:`_split_pair`: two feet, not one shoe cut
in two), else the component is what it was.

Foot point: the measured foot position (3.26) is compared with a landmark on ``z = 0`` (3.35),
so it must lie ON the floor (thesis notes). The component's 3-D points are projected
orthogonally onto the fitted plane and described in a floor frame with the walking direction
``f`` (the optical axis projected on the floor: the camera faces forward) and the lateral
direction ``s``. The default ``point_method = "toe"`` uses the known shoe size like the
thesis's ellipse "with known major and minor axes": along ``f`` the foot point is the toe
(98th percentile of the points along ``f``) moved back by ``shoe_length_m / 2 − toe_margin_m``,
across it the middle of the 2nd–98th percentile extent of the shoe's top (the points at least
``top_height_fraction`` of the foot's height above the floor): a camera beside the foot sees
the side wall and sole edge facing it but not the far ones, and a shoe's upper is narrower than
its sole, so the extent of all points reaches the near sole edge but only the far edge of the
upper, and its middle lies a few mm towards the camera (3.4–4.1 mm medially on noise-free
simulated walks); the top is seen whole from above. Why not the centroid: the shin hides
the back of the shoe from a waist camera and the inner side walls are seen but not the outer
ones, so the visible centroid sits ~4 cm ahead of and ~8 mm inside the sole centre, by an amount
that changes as the foot moves through the image (benchmark: along-foot spread 5–7 mm for the
centroid, 1.2–1.5 mm for the toe). ``"centroid"`` (the projected centroid) and ``"ray"`` (the
ray through the image ellipse centre intersected with the plane, which lands behind the shoe
by its height times the tangent of the viewing angle) are kept for comparison
(``benchmarks/bench_detectors.py``).
"""

from __future__ import annotations

import heapq
import logging
import math
from dataclasses import dataclass

import cv2 as cv
import numpy as np

from gaitnet.checks import check_int_range, check_positive, check_range
from gaitnet.geometry.floor_plane import FloorPlane, height_map
from gaitnet.geometry.two_groups import otsu_split

log = logging.getLogger(__name__)

MIN_AXIS_COS = math.cos(math.radians(45.0))
"""Each half of a split component must have its main floor axis within 45° of the walking
direction (feet standing side by side point forward, toes out by 5–20°)."""
MIN_PAIR_APART_M = 0.08
"""The two halves of a split component are two feet only if their points lie at least this far
apart [m]: the sole centres of feet side by side are at least a shoe width (~0.1 m) apart."""

__all__ = ["FootCandidate", "FootParams", "detect_foot_candidates"]


@dataclass(frozen=True)
class FootParams:
    """Foot-candidate thresholds (tuned on simulated sessions det_s200–s205; the thesis gives
    none of ``h_foot,min/max``, ``N_foot,min``)."""

    h_min_m: float = 0.015
    """Lowest height above the floor of a foot pixel [m] (3.24): above the floor's relief and
    depth noise (a few mm at 1–2 m) with margin."""
    h_max_m: float = 0.10
    """Highest [m] (3.24): a shoe's instep is ≤ ~9 cm high; above it the shin would merge."""
    stride: int = 2
    """Work on every ``stride``-th row and column (640×480 → 320×240): a shoe still covers
    hundreds of pixels, and the per-frame time drops about 4×."""
    min_area_m2: float = 0.004
    """Smallest component area on the floor [m²] (``N_foot,min`` of the thesis, as an area so
    that it does not depend on resolution or distance): a fifth of a shoe's top view (~0.02 m²)
    — a foot half out of the image still counts, clutter crumbs do not."""
    min_area_inside_m2: float = 0.002
    """Smallest area [m²] of a component that does not touch the image border (``border_px``):
    such a foot is cut only by the leg above it, not by the frame. A waist camera sees a stance
    foot under a flexed knee by its toe alone: on real walks (CMU motion capture played by the
    simulator, knees at 25–30° in early stance) that part covers 0.002–0.006 m² for most of
    the foot flat, and ``min_area_m2`` lost most of their stances; at the border
    ``min_area_m2`` still holds (a heel leaving the image is not a stance to extend). Such a
    candidate is ``weak`` (:class:`FootCandidate`): the stance tracker confirms a stance by
    it only after ``stance.weak_confirm_s``, unless a larger one is seen (on generated walks
    the landing shoe's first partial sight would otherwise start the landmark a frame before
    the foot flat that the swing fill's timing reads it as)."""
    max_area_m2: float = 0.08
    """Largest component area [m²] (four shoes): larger low objects (a box, a step) are not feet."""
    max_length_m: float = 0.45
    """Longest extent of a component on the floor [m] (2·√λ_max of its points × 2): a shoe is
    ≤ 0.33 m; two feet merged side by side or a long object is rejected."""
    max_width_m: float = 0.2
    """Widest extent of a component across its main axis on the floor [m] (2·√λ_min × 2): one
    shoe gives 0.09–0.15 m (simulated sessions), two feet side by side ≥ 0.25 m (sole centres
    at least a shoe width apart); it matters for pieces joined across holes."""
    hole_bridge_m: float = 0.06
    """Depth holes up to this wide [m, at the foot pixels' median depth] join the pieces of
    foot pixels around them (module docstring): a black shoe's hole clusters cut it with gaps
    of 2–6 cm (simulated sessions, tuning seeds); 0 disables."""
    min_pixels: int = 20
    """Components smaller than this many pixels (working resolution) are not examined (speed;
    20 px at 320×240 is < 0.002 m² at 2 m)."""
    max_candidates: int = 2
    """Keep the largest this many components (the thesis keeps two)."""
    point_method: str = "toe"
    """``toe`` (default), ``centroid`` or ``ray`` (module docstring)."""
    shoe_length_m: float = 0.28
    """Outside length of the shoe [m] (thesis: the foot size is known). A wrong value shifts
    every foot point of the subject by the same amount along the walking direction (stride
    lengths unchanged); 0.28 m is an adult EU 42–43 shoe; set it per subject when known."""
    toe_margin_m: float = 0.0125
    """How far the 98th-percentile toe point lies behind the shoe's tip [m] (tuned on
    det_s200–s204: 11.0–13.6 mm, spread 1.4 mm)."""
    top_height_fraction: float = 0.75
    """The ``toe`` point's lateral position is the middle of the foot points at least this
    fraction of the foot's height (95th percentile of its points' heights) above the floor
    (module docstring); 0 takes all points. Tuned on det_s200–s202 with true poses and shoe
    lengths: median/90th-percentile foot-point error 3.0/5.2 mm with 0, 3.0/4.6 with 0.6,
    2.7/3.8 with 0.75, 2.7/4.2 with 0.85, 3.1/7.2 with 0.95."""
    border_px: int = 2
    """A component within this many pixels (full resolution) of the image border is flagged
    ``at_border`` (the foot is entering or leaving the image: its centroid is biased)."""
    split_width_m: float = 0.16
    """A component wider than this across the walking direction (4 standard deviations of its
    points' lateral positions, as ``max_width_m`` measures width) is tried as two feet side by
    side (module docstring); 0: never. One shoe walking straight gives about 0.12 m; two shoes
    standing with the heels together and the toes out 20° touch and gave one component, one
    stance foot between the two (a simulated session, ``gait.toe_out_deg=20
    gait.step_width_m=0.03``, seed 9110)."""

    segmented_max_depth_fraction: float = 0.5
    """A component of the segmenter's foot pixels is a candidate of its own
    (:mod:`gaitnet.vio.feet_segmented`, ``gaitnet infer`` with ``pipeline.segmented_stances``)
    only when at most this share of its pixels have depth (1: always); the others are the depth
    candidates' to find or refuse (a swing foot above ``h_max_m``)."""
    shoe_width_m: float = 0.10
    """Outside width of the shoe [m]: a candidate from the segmenter's foot pixels that shows
    less than this across lies half of it out from its inner edge
    (:mod:`gaitnet.vio.feet_segmented`)."""
    segmented_apart_m: float = 0.15
    """A candidate from the segmenter's foot pixels closer than this [m] to one from depth is
    that foot again and is dropped (half a shoe's length: the toe-based points of one shoe lie
    within a few cm)."""

    def __post_init__(self) -> None:
        check_range("h_min_m", self.h_min_m, 0.0, 1.0, " m")
        check_range("h_max_m", self.h_max_m, self.h_min_m, 2.0, " m")
        check_int_range("stride", self.stride, 1, 16)
        check_positive("min_area_m2", self.min_area_m2, " m²")
        check_range("max_area_m2", self.max_area_m2, self.min_area_m2, 100.0, " m²")
        check_range("min_area_inside_m2", self.min_area_inside_m2, 0.0, self.max_area_m2, " m²")
        for name in ("max_length_m", "max_width_m", "shoe_length_m", "shoe_width_m"):
            check_positive(name, getattr(self, name), " m")
        check_range("segmented_max_depth_fraction", self.segmented_max_depth_fraction, 0.0, 1.0)
        for name in ("hole_bridge_m", "toe_margin_m", "split_width_m", "segmented_apart_m"):
            check_range(name, getattr(self, name), 0.0, 10.0, " m")
        check_int_range("min_pixels", self.min_pixels, 1)
        check_int_range("max_candidates", self.max_candidates, 1)
        check_int_range("border_px", self.border_px, 0)
        if not 0.0 <= self.top_height_fraction < 1.0:  # also refuses NaN
            raise ValueError(
                f"top_height_fraction must be in [0, 1), got {self.top_height_fraction!r}"
            )
        if self.point_method not in ("toe", "centroid", "ray"):
            raise ValueError(
                f"point_method must be 'toe', 'centroid' or 'ray', got {self.point_method!r}"
            )


@dataclass(frozen=True)
class FootCandidate:
    """One stance-foot candidate in a frame.

    ``p_FinC`` (3,) the foot point on the floor plane (camera frame, m); ``n_pixels`` the
    component's pixels at the working resolution; ``area_m2`` its area on the floor;
    ``ellipse`` ``((u, v), (axis1, axis2), angle_deg)`` of ``cv.fitEllipse`` in full-resolution
    pixels; ``length_m``/``width_m`` the extent along/across its main floor axis (4·√λ of the
    floor-plane scatter); ``axis_C`` (3,) the main axis direction on the floor (camera frame,
    pointing forward); ``at_border`` whether it touches the image border; ``centroid_C`` the
    projected centroid; ``weak`` whether it is smaller than ``min_area_m2`` (admitted by
    ``min_area_inside_m2``; :class:`gaitnet.vio.stance_tracker.StanceTracker`); ``segmented``
    whether it was found in the segmenter's foot pixels, not in depth
    (:mod:`gaitnet.vio.feet_segmented`).
    """

    p_FinC: np.ndarray
    n_pixels: int
    area_m2: float
    ellipse: tuple[tuple[float, float], tuple[float, float], float]
    length_m: float
    width_m: float
    axis_C: np.ndarray
    at_border: bool
    centroid_C: np.ndarray
    weak: bool = False
    segmented: bool = False


def _plane_basis(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    a = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(n, a)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(n, e1)


def _groups(
    mask: np.ndarray, labels: np.ndarray, n_lab: int, d: np.ndarray, Ks: np.ndarray, bridge_m: float
) -> list[list[int]]:
    """The foot-pixel components (labels ``1 … n_lab−1``) grouped across depth holes.

    Invalid depth pixels inside the morphological closing of ``mask`` (gaps up to
    ``bridge_m`` at the median depth of the foot pixels) connect the components on both sides;
    a valid pixel never does (the floor between two feet is seen)."""
    singles = [[lab] for lab in range(1, n_lab)]
    on = mask.astype(bool)
    if bridge_m <= 0 or n_lab <= 2:
        return singles
    r = math.ceil(0.5 * bridge_m * Ks[0, 0] / float(np.median(d[on])))
    if r < 1:
        return singles
    kernel = cv.getStructuringElement(cv.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
    closed = cv.morphologyEx(mask, cv.MORPH_CLOSE, kernel).astype(bool)
    invalid = ~(d > 0)  # zero or NaN: no depth
    conn = (on | (closed & invalid)).astype(np.uint8)
    _, conn_labels = cv.connectedComponents(conn, connectivity=8)
    group_of = np.zeros(n_lab, dtype=np.int64)
    group_of[labels[on]] = conn_labels[on]
    groups: dict[int, list[int]] = {}
    for lab in range(1, n_lab):
        groups.setdefault(int(group_of[lab]), []).append(lab)
    return list(groups.values())


@dataclass(frozen=True)
class _Image:
    """What every component's candidate is computed from (working resolution)."""

    d: np.ndarray
    labels: np.ndarray
    stats: np.ndarray
    K: np.ndarray
    Ks: np.ndarray
    s: int
    shape_full: tuple[int, int]
    plane: FloorPlane
    e1: np.ndarray
    e2: np.ndarray
    fwd: np.ndarray
    side: np.ndarray


def _unit_box(img: _Image, unit: list[int]) -> tuple[int, int, int, int, np.ndarray]:
    """The bounding box ``x0, y0, x1, y1`` (working resolution) of the pixels with labels
    ``unit`` and their mask within it."""
    st = img.stats[unit]
    x0 = int(st[:, cv.CC_STAT_LEFT].min())
    y0 = int(st[:, cv.CC_STAT_TOP].min())
    x1 = int((st[:, cv.CC_STAT_LEFT] + st[:, cv.CC_STAT_WIDTH]).max())
    y1 = int((st[:, cv.CC_STAT_TOP] + st[:, cv.CC_STAT_HEIGHT]).max())
    lab_sub = img.labels[y0:y1, x0:x1]
    sub = lab_sub == unit[0] if len(unit) == 1 else np.isin(lab_sub, unit)
    return x0, y0, x1, y1, sub


def _points(img: _Image, x0: int, y0: int, sub: np.ndarray) -> tuple[np.ndarray, ...]:
    """Pixel coordinates ``vv, uu`` (in the box), rays ``(x_n, y_n, 1)`` and camera-frame
    points of the mask ``sub`` whose box starts at ``x0, y0``."""
    Ks = img.Ks
    vv, uu = np.nonzero(sub)
    z = img.d[y0 : y0 + sub.shape[0], x0 : x0 + sub.shape[1]][sub].astype(np.float64)
    x_n = (uu + x0 - Ks[0, 2]) / Ks[0, 0]
    y_n = (vv + y0 - Ks[1, 2]) / Ks[1, 1]
    rays = np.stack([x_n, y_n, np.ones_like(x_n)], axis=1)
    return vv, uu, rays, rays * z[:, None]


def _candidate(
    img: _Image, unit: list[int], params: FootParams, keep: np.ndarray | None = None
) -> FootCandidate | None:
    """The candidate of the foot pixels with labels ``unit`` (one component, or the pieces of
    one split by depth holes), only those of the box mask ``keep`` where given (one foot of
    two, :func:`_split_pair`); None when it fails the size limits (or the ray misses)."""
    x0, y0, x1, y1, sub = _unit_box(img, unit)
    if keep is not None:
        sub = sub & keep
        if not sub.any():
            return None
    area_px = int(sub.sum())
    Ks, K, s, plane = img.Ks, img.K, img.s, img.plane
    vv, uu, rays, P = _points(img, x0, y0, sub)
    z = P[:, 2]
    # Floor-projected area: a pixel at depth z on a floor-parallel surface covers
    # z² / (fx fy) / |n·r| (r = (x_n, y_n, 1)); grazing rays are clamped at |n·r̂| ≥ 0.2.
    n_dot = np.maximum(np.abs(rays @ plane.n_C), 0.2 * np.linalg.norm(rays, axis=1))
    area = float(np.sum(z**2 / n_dot) / (Ks[0, 0] * Ks[1, 1]))
    b = params.border_px
    H_full, W_full = img.shape_full
    at_border = bool(x0 * s <= b or y0 * s <= b or x1 * s >= W_full - b or y1 * s >= H_full - b)
    min_area = params.min_area_m2 if at_border else params.min_area_inside_m2
    if not min_area <= area <= params.max_area_m2:
        return None
    Q = plane.project(P)
    q2 = np.stack([Q @ img.e1, Q @ img.e2], axis=1)
    c2 = q2.mean(axis=0)
    cov = np.cov((q2 - c2).T) if len(q2) > 2 else np.eye(2) * 1e-6
    evals, evecs = np.linalg.eigh(cov)
    length = 4.0 * float(np.sqrt(max(evals[1], 0.0)))
    width = 4.0 * float(np.sqrt(max(evals[0], 0.0)))
    if length > params.max_length_m or width > params.max_width_m:
        return None
    axis_C = evecs[0, 1] * img.e1 + evecs[1, 1] * img.e2
    if axis_C @ img.fwd < 0:
        axis_C = -axis_C
    contours, _ = cv.findContours(sub.astype(np.uint8), cv.RETR_EXTERNAL, cv.CHAIN_APPROX_NONE)
    if len(unit) == 1:
        cnt = max(contours, key=len).reshape(-1, 2).astype(np.float32)
    else:  # the outline of all pieces
        cnt = cv.convexHull(np.concatenate(contours).astype(np.float32)).reshape(-1, 2)
    if len(cnt) >= 5:
        (ecx, ecy), axes, ang = cv.fitEllipse(cnt)
    else:
        ecx, ecy, axes, ang = float(uu.mean()), float(vv.mean()), (1.0, 1.0), 0.0
    # back to full-resolution pixels (pixel-centre model)
    ecx_full = (ecx + x0) * s  # sample i of the decimated image is pixel s·i
    ecy_full = (ecy + y0) * s
    ellipse = ((float(ecx_full), float(ecy_full)), (axes[0] * s, axes[1] * s), float(ang))
    if params.point_method == "toe":
        height = plane.height(P)
        top = height >= params.top_height_fraction * float(np.percentile(height, 95.0))
        lo_s, hi_s = np.percentile(Q[top] @ img.side, [2.0, 98.0])
        toe_f = float(np.percentile(Q @ img.fwd, 98.0))
        back = 0.5 * params.shoe_length_m - params.toe_margin_m
        p_F = (toe_f - back) * img.fwd + 0.5 * (lo_s + hi_s) * img.side - plane.h * plane.n_C
    elif params.point_method == "centroid":
        p_F = Q.mean(axis=0)
    else:
        ray = np.array([(ecx_full - K[0, 2]) / K[0, 0], (ecy_full - K[1, 2]) / K[1, 1], 1.0])
        p_F = plane.intersect_ray(ray)
        if p_F is None:
            return None
    return FootCandidate(
        p_FinC=p_F,
        n_pixels=area_px,
        area_m2=area,
        ellipse=ellipse,
        length_m=length,
        width_m=width,
        axis_C=axis_C,
        at_border=at_border,
        centroid_C=Q.mean(axis=0),
        weak=area < params.min_area_m2,
    )


def _split_pair(img: _Image, unit: list[int], params: FootParams) -> list[FootCandidate]:
    """The two feet of a component wider across the walking direction than one shoe
    (``split_width_m``): its pixels split at Otsu's threshold of their lateral positions, both
    halves feet whose centroids lie side by side, at least :data:`MIN_PAIR_APART_M` apart
    across and less than 0.75 of that along the walking direction, each longer along the walk
    than across (within 45°: a shoe turned across the camera's view splits into a front and a
    back half, which lie along it or across the walk); else []."""
    x0, y0, _, _, sub = _unit_box(img, unit)
    vv, uu, _, P = _points(img, x0, y0, sub)
    if len(P) < 2 * params.min_pixels:
        return []
    across = img.plane.project(P) @ img.side
    if not 4.0 * float(np.std(across)) > params.split_width_m:  # as _candidate's width
        return []
    upper = otsu_split(across, *np.percentile(across, [5.0, 95.0]))
    feet = []
    for half in (upper, ~upper):
        keep = np.zeros_like(sub)
        keep[vv[half], uu[half]] = True
        cand = _candidate(img, unit, params, keep)
        if cand is None or abs(float(cand.axis_C @ img.fwd)) < MIN_AXIS_COS:
            return []  # not a foot, or one lying across the walk: half of a turned shoe
        feet.append(cand)
    step = feet[0].centroid_C - feet[1].centroid_C
    side, ahead = abs(float(step @ img.side)), abs(float(step @ img.fwd))
    if side < MIN_PAIR_APART_M or ahead > 0.75 * side:
        return []
    return sorted(feet, key=lambda c: -c.n_pixels)


def detect_foot_candidates(
    depth_m: np.ndarray, K: np.ndarray, plane: FloorPlane, params: FootParams | None = None
) -> list[FootCandidate]:
    """Stance-foot candidates (3.24)–(3.26) of one depth image, largest first (≤ 2).

    ``depth_m`` (H, W) metres aligned to the colour camera ``K``, 0 where invalid;
    ``plane`` the frame's floor (:func:`gaitnet.geometry.floor_plane.fit_floor`).
    """
    params = params or FootParams()
    K = np.asarray(K, dtype=np.float64)
    s = int(params.stride)
    d = np.asarray(depth_m, dtype=np.float32)
    shape_full = d.shape
    if s > 1:
        d = d[::s, ::s]
        Ks = K.copy()
        Ks[0, 0] /= s
        Ks[1, 1] /= s
        Ks[0, 2] /= s
        Ks[1, 2] /= s
    else:
        Ks = K
    hmap = height_map(d, Ks, plane)
    with np.errstate(invalid="ignore"):
        mask = ((hmap >= params.h_min_m) & (hmap <= params.h_max_m)).astype(np.uint8)
    n_lab, labels, stats, _ = cv.connectedComponentsWithStats(mask, connectivity=8)
    if n_lab <= 1:
        return []
    e1, e2 = _plane_basis(plane.n_C)
    # walking direction: the optical axis projected on the floor (the camera faces forward)
    fwd = np.array([0.0, 0.0, 1.0]) - plane.n_C[2] * plane.n_C
    fwd /= np.linalg.norm(fwd)
    img = _Image(
        d, labels, stats, K, Ks, s, shape_full, plane, e1, e2, fwd, np.cross(plane.n_C, fwd)
    )
    area = stats[:, cv.CC_STAT_AREA]
    # largest first; a group of pieces that fails the size limits is tried piece by piece
    units = [
        (-int(area[g].sum()), i, g)
        for i, g in enumerate(_groups(mask, labels, n_lab, d, Ks, params.hole_bridge_m))
    ]
    heapq.heapify(units)
    tie = len(units)
    out: list[FootCandidate] = []
    while units and len(out) < params.max_candidates:
        neg_px, _, unit = heapq.heappop(units)
        if -neg_px < params.min_pixels:
            break
        cand = _candidate(img, unit, params)
        if params.split_width_m > 0:
            pair = _split_pair(img, unit, params)
            if pair:
                out.extend(pair[: params.max_candidates - len(out)])
                continue
        if cand is not None:
            out.append(cand)
        elif len(unit) > 1:
            for lab in unit:
                heapq.heappush(units, (-int(area[lab]), tie, [lab]))
                tie += 1
    return out
