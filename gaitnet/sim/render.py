"""Realistic ray-cast renderer of the waist-camera view: floor, tag sheets, room, clutter, legs
and shoes, with exact depth, labels and instances.

Each pixel casts one ray through its centre (``(u, v)`` integer, as in
:mod:`gaitnet.geometry.camera`). The environment (floor plane, walls, ceiling) is hit
analytically for all pixels (:mod:`gaitnet.sim.render_env`); then every primitive — clutter
boxes and cylinders, each trouser-leg segment (a round cone), each shoe (union of two convex
parts, :mod:`gaitnet.sim.render_prims`) — is intersected only with the rays inside its
projected bounding box (clipped at the near plane, so parts behind the camera are fine) and
written where it is nearer than what the z-buffer holds. Depth, colour, label, instance and
normal of a pixel are written by the same comparison, so the maps agree pixel for pixel.

Returned depth is the z coordinate in the camera frame (``inf`` where nothing is hit).
Colours are linear scene radiance; :func:`gaitnet.sim.sensor_model.apply_sensor` turns a
:class:`RenderResult` into 8-bit RGB and D455-like depth.
"""

from __future__ import annotations

import time
import zlib
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from gaitnet.sim.floor import Clutter, ClutterBox, ClutterCylinder, FloorTexture
from gaitnet.sim.render_env import ContactPatch, ShadowSegment, render_environment
from gaitnet.sim.render_materials import (
    LightFrame,
    shade_leg,
    shade_plain,
    shade_shoe,
    shoe_texture,
)
from gaitnet.sim.render_prims import (
    ConvexShape,
    RoundCone,
    T_WfromShoe,
    box_shape,
    geometry_of,
    screen_bbox,
    upright_cylinder,
)
from gaitnet.sim.render_types import F32, Lighting, Rays, RenderResult, camera_rays
from gaitnet.sim.scene import (
    INSTANCE_LEFT,
    INSTANCE_NONE,
    INSTANCE_RIGHT,
    LABEL_BACKGROUND,
    LABEL_FOOT,
    LABEL_LEG,
    Appearance,
    BodyState,
    ShoeState,
)

__all__ = ["Lighting", "RenderResult", "render_frame"]

NEAR_M = 0.01
_INSTANCE = {"left": INSTANCE_LEFT, "right": INSTANCE_RIGHT}


@dataclass
class _Frame:
    """Mutable per-frame state: z-buffer and output maps, camera and lighting."""

    K: np.ndarray
    T_CfromW: np.ndarray
    rays: Rays
    lf: LightFrame
    depth: F32
    rgb: F32
    label: NDArray[np.uint8]
    instance: NDArray[np.uint8]
    normals: F32 | None

    @property
    def size(self) -> tuple[int, int]:
        return self.depth.shape[1], self.depth.shape[0]

    def region(self, corners_C: np.ndarray) -> tuple[slice, slice] | None:
        box = screen_bbox(self.K, corners_C, *self.size, near=NEAR_M)
        if box is None:
            return None
        u0, u1, v0, v1 = box
        return np.s_[v0:v1], np.s_[u0:u1]


@dataclass(frozen=True)
class _Hits:
    """The winning hits of one primitive inside its region: mask, points, normals."""

    region: tuple[slice, slice]
    win: NDArray[np.bool_]
    p: F32
    view: F32


def _resolve(fr: _Frame, region: tuple[slice, slice], t: F32) -> _Hits | None:
    """Z-test ray distances ``t`` of a region against the buffer."""
    dz = fr.rays.uz[region]
    z = t * dz
    win = (z < fr.depth[region]) & (z > NEAR_M)
    if not win.any():
        return None
    d = np.stack([fr.rays.ux[region][win], fr.rays.uy[region][win], dz[win]], axis=1)
    return _Hits(region, win, d * t[win][:, None], -d)


def _write(fr: _Frame, hits: _Hits, rgb: F32, n: F32, label: int, instance: int) -> None:
    """Write the winners' depth, colour, label, instance and normal (same mask for all)."""
    r, w = hits.region, hits.win
    fr.depth[r][w] = hits.p[:, 2]
    fr.rgb[r][w] = rgb
    fr.label[r][w] = label
    fr.instance[r][w] = instance
    if fr.normals is not None:
        fr.normals[r][w] = n


def _rays_of(fr: _Frame, region: tuple[slice, slice]) -> tuple[F32, F32, F32]:
    return fr.rays.ux[region], fr.rays.uy[region], fr.rays.uz[region]


# ----------------------------------------------------------------------------- primitives


def _draw_convex(
    fr: _Frame, shape_C: ConvexShape, shade: Callable[[F32, F32, F32], F32], label: int, inst: int
) -> None:
    region = fr.region(shape_C.bound)
    if region is None:
        return
    t, which = shape_C.intersect(*_rays_of(fr, region))
    hits = _resolve(fr, region, t)
    if hits is None:
        return
    n = shape_C.normals(hits.p, which[hits.win])
    _write(fr, hits, shade(hits.p, n, hits.view), n, label, inst)


def _draw_clutter(fr: _Frame, item: Clutter) -> None:
    if isinstance(item, ClutterBox):
        c, s = np.cos(item.yaw_rad), np.sin(item.yaw_rad)
        R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        half = np.asarray(item.size_m, float) / 2
        shape = box_shape(np.array([*item.centre_xy, half[2]]), R, half)
    else:
        shape = upright_cylinder(item.centre_xy, item.radius_m, item.height_m)
    rgb = item.rgb
    _draw_convex(
        fr,
        shape.transformed(fr.T_CfromW),
        lambda p, n, v: shade_plain(rgb, n, fr.lf),
        LABEL_BACKGROUND,
        INSTANCE_NONE,
    )


def _draw_leg(fr: _Frame, cone_W: RoundCone, side: str, appearance: Appearance, seed: int) -> None:
    cone = cone_W.transformed(fr.T_CfromW)
    region = fr.region(cone.corners())
    if region is None:
        return
    t, part = cone.intersect(*_rays_of(fr, region))
    hits = _resolve(fr, region, t)
    if hits is None:
        return
    n = cone.normals(hits.p, part[hits.win])
    rgb = shade_leg(cone, hits.p, n, fr.lf, appearance, seed)
    _write(fr, hits, rgb, n, LABEL_LEG, _INSTANCE[side])


def _draw_shoe(fr: _Frame, shoe: ShoeState, appearance: Appearance) -> None:
    geo = geometry_of(shoe)
    T_CfromS = fr.T_CfromW @ T_WfromShoe(shoe)
    sole, upper = geo.sole.transformed(T_CfromS), geo.upper.transformed(T_CfromS)
    region = fr.region(sole.bound)
    if region is None:
        return
    rays = _rays_of(fr, region)
    t_sole, w_sole = sole.intersect(*rays)
    t_up, w_up = upper.intersect(*rays)
    is_up = t_up < t_sole
    hits = _resolve(fr, region, np.where(is_up, t_up, t_sole))
    if hits is None:
        return
    up = is_up[hits.win]
    n = np.empty_like(hits.p)
    n[up] = upper.normals(hits.p[up], w_up[hits.win][up])
    n[~up] = sole.normals(hits.p[~up], w_sole[hits.win][~up])
    p_S = ((hits.p - T_CfromS[:3, 3]) @ T_CfromS[:3, :3]).astype(np.float32)
    tex = shoe_texture(float(shoe.length_m), float(shoe.width_m), shoe.side, appearance)
    rgb = shade_shoe(p_S, n, fr.lf, hits.view, tex, geo.sole_m, appearance)
    _write(fr, hits, rgb, n, LABEL_FOOT, _INSTANCE[shoe.side])


# ----------------------------------------------------------------------------- shadows


def _occluders(
    body: BodyState, clutter: tuple[Clutter, ...], light: Lighting
) -> tuple[tuple[ShadowSegment, ...], tuple[ContactPatch, ...]]:
    """Soft-shadow segments (legs, shoes) and contact patches (shoes, clutter)."""
    segs = [
        ShadowSegment(
            np.asarray(leg.p_top_W, float),
            np.asarray(leg.p_bottom_W, float),
            0.9 * max(leg.radius_top_m, leg.radius_bottom_m),
        )
        for leg in body.legs
    ]
    patches = []
    for shoe in body.shoes:
        T = T_WfromShoe(shoe)
        L, W, H = shoe.length_m, shoe.width_m, shoe.height_m
        heel = T[:3, :3] @ [-0.38 * L, 0.0, 0.45 * H] + T[:3, 3]
        toe = T[:3, :3] @ [0.36 * L, 0.0, 0.3 * H] + T[:3, 3]
        segs.append(ShadowSegment(heel, toe, 0.42 * W))
        patches.append(ContactPatch(T, 0.5 * L, 0.5 * W, 0.02, light.contact_ao))
    for item in clutter:
        T = np.eye(4)
        T[:2, 3] = item.centre_xy
        if isinstance(item, ClutterCylinder):
            hx = hy = item.radius_m
        else:
            c, s = np.cos(item.yaw_rad), np.sin(item.yaw_rad)
            T[:2, :2] = [[c, -s], [s, c]]
            hx, hy = item.size_m[0] / 2, item.size_m[1] / 2
        patches.append(ContactPatch(T, hx, hy, 0.04, 0.8 * light.contact_ao))
    return tuple(segs), tuple(patches)


# ----------------------------------------------------------------------------- main


def render_frame(
    K: np.ndarray,
    width: int,
    height: int,
    T_WfromC: np.ndarray,
    floor: FloorTexture,
    body: BodyState,
    appearance: Appearance,
    clutter: tuple[Clutter, ...] = (),
    light: Lighting | None = None,
    *,
    return_normals: bool = False,
    timings: dict[str, float] | None = None,
) -> RenderResult:
    """Render one frame seen by a camera with matrix ``K`` at pose ``T_WfromC`` (module doc).

    ``timings``, when given, receives the CPU seconds of the calling thread spent per stage
    (``environment``, ``clutter``, ``legs``, ``shoes``), accumulated over calls (CPU time, so
    that other processes on the machine do not inflate them).
    """
    clock = _Clock(timings)
    light = light or Lighting()
    K = np.asarray(K, np.float64)
    T_WfromC = np.asarray(T_WfromC, np.float64)
    T_CfromW = np.linalg.inv(T_WfromC)
    shadows, patches = _occluders(body, tuple(clutter), light)
    env = render_environment(K, width, height, T_WfromC, floor, light, shadows, patches)
    clock.lap("environment")
    fr = _Frame(
        K=K,
        T_CfromW=T_CfromW,
        rays=camera_rays(K, width, height),
        lf=LightFrame.make(light, T_CfromW[:3, :3]),
        depth=env.depth,
        rgb=env.rgb,
        label=np.zeros((height, width), np.uint8),
        instance=np.zeros((height, width), np.uint8),
        normals=_env_normals(env, T_CfromW) if return_normals else None,
    )
    for item in clutter:
        _draw_clutter(fr, item)
    clock.lap("clutter")
    seed = zlib.crc32(repr(appearance.trouser_rgb).encode())
    for leg in body.legs:
        _draw_leg(fr, RoundCone.from_leg(leg), leg.side, appearance, seed)
    clock.lap("legs")
    for shoe in body.shoes:
        _draw_shoe(fr, shoe, appearance)
    clock.lap("shoes")
    return RenderResult(fr.rgb, fr.depth, fr.label, fr.instance, fr.normals)


class _Clock:
    """Accumulates stage durations into a caller's dict (no-op without one)."""

    def __init__(self, timings: dict[str, float] | None) -> None:
        self.timings = timings
        self.t = time.thread_time()

    def lap(self, name: str) -> None:
        if self.timings is None:
            return
        now = time.thread_time()
        self.timings[name] = self.timings.get(name, 0.0) + now - self.t
        self.t = now


def _env_normals(env, T_CfromW: np.ndarray) -> F32:
    """Camera-frame normals of the environment: the floor's up vector (walls left at zero)."""
    h, w = env.depth.shape
    normals = np.zeros((h, w, 3), np.float32)
    normals[env.is_floor] = T_CfromW[:3, 2].astype(np.float32)
    return normals
