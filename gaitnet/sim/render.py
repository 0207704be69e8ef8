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
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from gaitnet.sim.clutter import Clutter, ClutterBox, ClutterCylinder
from gaitnet.sim.floor import FloorTexture
from gaitnet.sim.floor_relief import FloorRelief
from gaitnet.sim.render_draw import Frame, draw
from gaitnet.sim.render_draw import antialias as antialias_edges
from gaitnet.sim.render_env import ContactPatch, ShadowSegment, render_environment
from gaitnet.sim.render_materials import (
    LightFrame,
    ShoeTexture,
    shade_leg,
    shade_plain,
    shade_shoe,
    shoe_texture,
)
from gaitnet.sim.render_motion import Motion, motion_blur
from gaitnet.sim.render_prims import (
    ConvexShape,
    RoundCone,
    T_WfromShoe,
    box_shape,
    geometry_of,
    upright_cylinder,
)
from gaitnet.sim.render_types import F32, Lighting, RenderResult, camera_rays
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

_INSTANCE = {"left": INSTANCE_LEFT, "right": INSTANCE_RIGHT}


# ----------------------------------------------------------------------------- primitives


@dataclass(frozen=True)
class _Clutter:
    """A clutter box or cylinder (camera frame), plain Lambertian colour, background label."""

    shape: ConvexShape
    rgb: tuple[float, float, float]
    lf: LightFrame
    label: int = LABEL_BACKGROUND
    instance: int = INSTANCE_NONE

    @classmethod
    def make(cls, item: Clutter, T_CfromW: np.ndarray, lf: LightFrame) -> _Clutter:
        if isinstance(item, ClutterBox):
            c, s = np.cos(item.yaw_rad), np.sin(item.yaw_rad)
            R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
            half = np.asarray(item.size_m, float) / 2
            shape = box_shape(np.array([*item.centre_xy, half[2]]), R, half)
        else:
            shape = upright_cylinder(item.centre_xy, item.radius_m, item.height_m)
        return cls(shape.transformed(T_CfromW), item.rgb, lf)

    def corners(self) -> np.ndarray:
        return self.shape.bound

    def trace(self, dx: F32, dy: F32, dz: F32) -> tuple[F32, NDArray[np.int8]]:
        return self.shape.intersect(dx, dy, dz)

    def edge_id(self, code: NDArray[np.int8]) -> NDArray[np.int8]:
        return code

    def shade(self, p: F32, code: NDArray[np.int8], view: F32) -> tuple[F32, F32]:
        n = self.shape.normals(p, code)
        return shade_plain(self.rgb, n, self.lf), n


@dataclass(frozen=True)
class _Leg:
    """A trouser-leg segment (round cone, camera frame)."""

    cone: RoundCone
    lf: LightFrame
    appearance: Appearance
    seed: int
    instance: int
    label: int = LABEL_LEG

    def corners(self) -> np.ndarray:
        return self.cone.corners()

    def trace(self, dx: F32, dy: F32, dz: F32) -> tuple[F32, NDArray[np.int8]]:
        return self.cone.intersect(dx, dy, dz)

    def edge_id(self, code: NDArray[np.int8]) -> NDArray[np.int8]:
        return np.zeros_like(code)

    def shade(self, p: F32, code: NDArray[np.int8], view: F32) -> tuple[F32, F32]:
        n = self.cone.normals(p, code)
        return shade_leg(self.cone, p, n, view, self.lf, self.appearance, self.seed), n


_UPPER = 16  # shoe surface codes: sole constraint k, or _UPPER + upper constraint k


@dataclass(frozen=True)
class _Shoe:
    """A shoe: union of its sole and upper (camera frame)."""

    sole: ConvexShape
    upper: ConvexShape
    T_CfromS: np.ndarray
    sole_m: float
    tex: ShoeTexture
    lf: LightFrame
    appearance: Appearance
    instance: int
    label: int = LABEL_FOOT

    @classmethod
    def make(cls, shoe: ShoeState, T_CfromW: np.ndarray, lf: LightFrame, app: Appearance) -> _Shoe:
        geo = geometry_of(shoe)
        T_CfromS = T_CfromW @ T_WfromShoe(shoe)
        tex = shoe_texture(float(shoe.length_m), float(shoe.width_m), shoe.side, app)
        sole, upper = geo.sole.transformed(T_CfromS), geo.upper.transformed(T_CfromS)
        return cls(sole, upper, T_CfromS, geo.sole_m, tex, lf, app, _INSTANCE[shoe.side])

    def corners(self) -> np.ndarray:
        return self.sole.bound

    def trace(self, dx: F32, dy: F32, dz: F32) -> tuple[F32, NDArray[np.int8]]:
        t_sole, w_sole = self.sole.intersect(dx, dy, dz)
        t_up, w_up = self.upper.intersect(dx, dy, dz)
        is_up = t_up < t_sole
        code = np.where(is_up, w_up + _UPPER, w_sole).astype(np.int8)
        return np.where(is_up, t_up, t_sole), code

    def edge_id(self, code: NDArray[np.int8]) -> NDArray[np.int8]:
        return (code >= _UPPER).astype(np.int8)

    def shade(self, p: F32, code: NDArray[np.int8], view: F32) -> tuple[F32, F32]:
        up = code >= _UPPER
        n = np.empty_like(p)
        n[up] = self.upper.normals(p[up], code[up] - _UPPER)
        n[~up] = self.sole.normals(p[~up], code[~up])
        T = self.T_CfromS
        p_S = ((p - T[:3, 3]) @ T[:3, :3]).astype(np.float32)
        rgb = shade_shoe(p_S, n, self.lf, view, self.tex, self.sole_m, self.appearance)
        return rgb, n


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
    antialias: bool = True,
    timings: dict[str, float] | None = None,
    relief: FloorRelief | None = None,
    motion: Motion | None = None,
) -> RenderResult:
    """Render one frame seen by a camera with matrix ``K`` at pose ``T_WfromC`` (module doc).

    ``antialias`` refines the colour of silhouette pixels with 4 sub-pixel rays (depth,
    labels and instances stay point-sampled). ``timings``, when given, receives the CPU
    seconds of the calling thread spent per stage (``environment``, ``clutter``, ``legs``,
    ``shoes``, ``antialias``), accumulated over calls (CPU time, so that other processes on
    the machine do not inflate them). ``relief``: the floor's height field
    (:mod:`gaitnet.sim.floor_relief`; None: the plane z = 0). ``motion``: the camera pose and
    body at the end of the exposure; the colour is then integrated over the exposure
    (:mod:`gaitnet.sim.render_motion`; depth, labels and instances stay the mid-exposure
    instant; stage ``motion_blur``).
    """
    clock = _Clock(timings)
    light = light or Lighting()
    K = np.asarray(K, np.float64)
    T_WfromC = np.asarray(T_WfromC, np.float64)
    T_CfromW = np.linalg.inv(T_WfromC)
    shadows, patches = _occluders(body, tuple(clutter), light)
    env = render_environment(
        K, width, height, T_WfromC, floor, light, shadows, patches, relief=relief
    )
    clock.lap("environment")
    lf = LightFrame.make(light, T_CfromW[:3, :3])
    env_rgb = env.rgb.copy() if antialias or motion is not None else env.rgb
    fr = Frame(
        K=K,
        rays=camera_rays(K, width, height),
        depth=env.depth,
        rgb=env.rgb,
        label=np.zeros((height, width), np.uint8),
        instance=np.zeros((height, width), np.uint8),
        normals=_env_normals(env, T_CfromW) if return_normals else None,
    )
    for item in clutter:
        draw(fr, _Clutter.make(item, T_CfromW, lf))
    clock.lap("clutter")
    seed = zlib.crc32(repr(appearance.trouser_rgb).encode())
    for leg in body.legs:
        cone = RoundCone.from_leg(leg).transformed(T_CfromW)
        draw(fr, _Leg(cone, lf, appearance, seed, _INSTANCE[leg.side]))
    clock.lap("legs")
    for shoe in body.shoes:
        draw(fr, _Shoe.make(shoe, T_CfromW, lf, appearance))
    clock.lap("shoes")
    if antialias:
        antialias_edges(fr, env_rgb)
        clock.lap("antialias")
    rgb = fr.rgb
    if motion is not None:
        rgb = motion_blur(rgb, env_rgb, fr.depth, fr.label, fr.instance, fr.rays, K, motion)
        clock.lap("motion_blur")
    return RenderResult(rgb, fr.depth, fr.label, fr.instance, fr.normals)


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
