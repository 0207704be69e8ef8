"""Z-buffered drawing of ray-cast primitives with anti-aliased silhouettes.

A :class:`Drawable` traces unit rays from the camera centre (camera frame) and shades its hit
points. :func:`draw` intersects it with the rays of the pixels inside its projected bounding
box and writes depth, label, instance, normal and colour wherever it is nearer than the buffer
(one comparison decides all of them: labels and depth agree pixel for pixel), plus an id of the
visible surface. After all primitives, :func:`antialias` refines the *colour only* of edge
pixels — where the visible primitive or surface part changes between 4-neighbours — with 4
sub-pixel rays each, traced against all primitives (those whose box covers the pixel); a
sub-ray that hits none takes the environment's colour of the pixel. Depth, labels and
instances stay point-sampled at the pixel centre, as a depth camera and a labelling tool give
them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from gaitnet.sim.render_prims import screen_bbox
from gaitnet.sim.render_types import F32, Rays

NEAR_M = 0.01
SUBPIXEL = np.array([[-0.25, -0.25], [0.25, -0.25], [-0.25, 0.25], [0.25, 0.25]])

I8 = NDArray[np.int8]


class Drawable(Protocol):
    """A primitive in the camera frame."""

    label: int
    instance: int

    def corners(self) -> np.ndarray:
        """(8, 3) corners of a box enclosing it (camera frame)."""
        ...

    def trace(self, dx: F32, dy: F32, dz: F32) -> tuple[F32, I8]:
        """Entry distance along unit rays (inf on a miss) and a per-ray surface code."""
        ...

    def edge_id(self, code: I8) -> I8:
        """Codes whose changes between neighbour pixels deserve anti-aliasing."""
        ...

    def shade(self, p: F32, code: I8, view: F32) -> tuple[F32, F32]:
        """Linear colour (N, 3) and unit normals (N, 3) at hit points ``p`` (N, 3)."""
        ...


@dataclass
class Frame:
    """Mutable per-frame state: camera, z-buffer, output maps and what was drawn."""

    K: np.ndarray
    rays: Rays
    depth: F32
    rgb: F32
    label: NDArray[np.uint8]
    instance: NDArray[np.uint8]
    normals: F32 | None
    surface: NDArray[np.uint16] = field(init=False)
    drawn: list[tuple[Drawable, tuple[slice, slice]]] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.surface = np.zeros(self.depth.shape, np.uint16)

    def region(self, corners_C: np.ndarray) -> tuple[slice, slice] | None:
        h, w = self.depth.shape
        box = screen_bbox(self.K, corners_C, w, h, near=NEAR_M)
        if box is None:
            return None
        u0, u1, v0, v1 = box
        return np.s_[v0:v1], np.s_[u0:u1]


def _edges(ids: NDArray) -> NDArray[np.bool_]:
    """Pixels whose id differs from a 4-neighbour's."""
    e = np.zeros(ids.shape, bool)
    dx = ids[:, 1:] != ids[:, :-1]
    dy = ids[1:] != ids[:-1]
    e[:, 1:] |= dx
    e[:, :-1] |= dx
    e[1:] |= dy
    e[:-1] |= dy
    return e


def _sub_rays(K: np.ndarray, u: np.ndarray, v: np.ndarray) -> tuple[F32, F32, F32]:
    """Unit directions of 4 sub-pixel rays per pixel (rays ordered pixel-major)."""
    uu = (u[:, None] + SUBPIXEL[None, :, 0]).ravel()
    vv = (v[:, None] + SUBPIXEL[None, :, 1]).ravel()
    Kinv = np.linalg.inv(K)
    xn = Kinv[0, 0] * uu + Kinv[0, 1] * vv + Kinv[0, 2]
    yn = Kinv[1, 1] * vv + Kinv[1, 2]
    inv = 1.0 / np.sqrt(xn * xn + yn * yn + 1.0)
    return (xn * inv).astype(np.float32), (yn * inv).astype(np.float32), inv.astype(np.float32)


def draw(fr: Frame, prim: Drawable) -> None:
    """Z-buffer ``prim`` into the frame (module docstring)."""
    region = fr.region(prim.corners())
    if region is None:
        return
    ux, uy, uz = fr.rays.ux[region], fr.rays.uy[region], fr.rays.uz[region]
    t, code = prim.trace(ux, uy, uz)
    z = t * uz
    win = np.isfinite(t) & (z > NEAR_M) & (z < fr.depth[region])
    fr.drawn.append((prim, region))
    local = np.flatnonzero(win)
    if local.size == 0:
        return
    width = fr.depth.shape[1]
    rw = region[1].stop - region[1].start
    flat = (local // rw + region[0].start) * width + (local % rw + region[1].start)
    d = np.stack([fr.rays.ux.ravel()[flat], fr.rays.uy.ravel()[flat], fr.rays.uz.ravel()[flat]], 1)
    t_w, code_w = t.ravel()[local], code.ravel()[local]
    rgb, n = prim.shade(d * t_w[:, None], code_w, -d)
    fr.depth.ravel()[flat] = t_w * d[:, 2]
    fr.rgb.reshape(-1, 3)[flat] = rgb
    fr.label.ravel()[flat] = prim.label
    fr.instance.ravel()[flat] = prim.instance
    fr.surface.ravel()[flat] = len(fr.drawn) * 64 + prim.edge_id(code_w).astype(np.uint16)
    if fr.normals is not None:
        fr.normals.reshape(-1, 3)[flat] = n


def _union(regions: list[tuple[slice, slice]]) -> tuple[slice, slice]:
    v0 = min(r[0].start for r in regions)
    v1 = max(r[0].stop for r in regions)
    u0 = min(r[1].start for r in regions)
    u1 = max(r[1].stop for r in regions)
    return np.s_[v0:v1], np.s_[u0:u1]


def antialias(fr: Frame, env_rgb: F32) -> None:
    """Refine the colour of the edge pixels of everything drawn (module docstring)."""
    if not fr.drawn:
        return
    box = _union([r for _, r in fr.drawn])
    edge = _edges(fr.surface[box])
    if not edge.any():
        return
    vi, ui = np.nonzero(edge)
    v, u = vi + box[0].start, ui + box[1].start
    dx, dy, dz = _sub_rays(fr.K, u.astype(np.float64), v.astype(np.float64))
    best = np.full(dx.shape, np.inf, np.float32)
    who = np.full(dx.shape, -1, np.int16)
    codes = np.zeros(dx.shape, np.int8)
    pu, pv = np.repeat(u, 4), np.repeat(v, 4)
    for k, (prim, (rv, ru)) in enumerate(fr.drawn):
        idx = np.flatnonzero((pv >= rv.start) & (pv < rv.stop) & (pu >= ru.start) & (pu < ru.stop))
        if idx.size == 0:
            continue
        t, code = prim.trace(dx[idx], dy[idx], dz[idx])
        z = t * dz[idx]
        near = np.isfinite(t) & (z > NEAR_M) & (t < best[idx])
        sel = idx[near]
        best[sel], who[sel], codes[sel] = t[near], k, code[near]
    colours = np.repeat(env_rgb[v, u], 4, axis=0)
    for k, (prim, _) in enumerate(fr.drawn):
        sel = np.flatnonzero(who == k)
        if sel.size:
            d = np.stack([dx[sel], dy[sel], dz[sel]], axis=1)
            colours[sel] = prim.shade(d * best[sel][:, None], codes[sel], -d)[0]
    fr.rgb[v, u] = colours.reshape(-1, 4, 3).mean(axis=1)
