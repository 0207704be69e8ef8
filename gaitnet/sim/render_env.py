"""The environment pass of the renderer: floor (with tag sheets), walls and ceiling.

Every pixel's ray is intersected with the floor — the plane z = 0 plus its millimetre relief
(:mod:`gaitnet.sim.floor_relief`) — and, when the floor has a
room, with the room's walls and ceiling (the camera is inside an axis-aligned box; walls are
only traced in the image rows where they can be nearer than the floor). The floor texture is
sampled trilinearly with a level of detail from the pixel footprint; tag sheets are composited
from their own high-resolution pyramids. Lighting that varies smoothly over the floor —
ceiling-lamp irradiance, soft key-light shadows of the legs and shoes, contact occlusion next
to shoes and clutter, and the blurred mirror image of the lamps in a glossy floor — is
computed on a 4× smaller grid and upsampled.

Colours include the light's colour (``Lighting.rgb``).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from gaitnet.sim.floor import FloorTexture
from gaitnet.sim.floor_relief import FloorRelief
from gaitnet.sim.mipmap import sample_mipmapped
from gaitnet.sim.render_color import decode_srgb8
from gaitnet.sim.render_prims import screen_bbox
from gaitnet.sim.render_types import F32, Lighting, Rays, camera_rays, low_res_K
from gaitnet.sim.tag_sheet import sheet_overlay

LOW_RES = 4
LOD_BIAS = 0.35  # between the geometric mean and the major axis of the pixel footprint
FAR_T = np.float32(500.0)
SKIRTING_M = 0.08
NEAR_M = 0.01


@dataclass(frozen=True)
class ShadowSegment:
    """A soft key-light occluder: a segment ``a``–``b`` (world) of radius ``r``."""

    a: np.ndarray
    b: np.ndarray
    r: float


@dataclass(frozen=True)
class ContactPatch:
    """Contact occlusion around a footprint: an ellipse of half axes (``hx``, ``hy``) in the
    frame ``T_WfromP`` (z up), darkening fading with the patch's height above the floor."""

    T_WfromP: np.ndarray
    hx: float
    hy: float
    reach_m: float
    strength: float


@dataclass(frozen=True)
class Environment:
    """Environment pass output: z-depth (inf where nothing), linear colour, floor mask."""

    depth: F32
    rgb: F32
    is_floor: NDArray[np.bool_]


@dataclass(frozen=True)
class _Camera:
    """A camera (matrix, image size, pose) and its cached rays."""

    K: np.ndarray
    width: int
    height: int
    T_WfromC: np.ndarray
    T_CfromW: np.ndarray
    rays: Rays

    @classmethod
    def make(cls, K: np.ndarray, width: int, height: int, T_WfromC: np.ndarray) -> _Camera:
        return cls(
            K, width, height, T_WfromC, np.linalg.inv(T_WfromC), camera_rays(K, width, height)
        )

    def low_res(self) -> _Camera:
        Kl = low_res_K(self.K, LOW_RES)
        wl, hl = -(-self.width // LOW_RES), -(-self.height // LOW_RES)
        return _Camera.make(Kl, wl, hl, self.T_WfromC)

    @property
    def centre(self) -> np.ndarray:
        return self.T_WfromC[:3, 3]

    def world_dirs(self, scale: tuple[float, float, float] = (1.0, 1.0, 1.0)) -> list[F32]:
        """World directions (x, y, z) of the rays (xn, yn, 1), each component scaled."""
        R = self.T_WfromC[:3, :3]
        return [self.rays.linear(*(R[i] * scale[i])) for i in range(3)]

    def floor_bbox(self, p_W: np.ndarray) -> tuple[slice, slice] | None:
        """Pixel region covering a floor quadrilateral (4, 3) (near-plane clipped)."""
        p = np.concatenate([p_W, p_W + [0.0, 0.0, 1e-3]])[[0, 4, 1, 5, 3, 7, 2, 6]]
        p_C = p @ self.T_CfromW[:3, :3].T + self.T_CfromW[:3, 3]
        box = screen_bbox(self.K, p_C, self.width, self.height, near=NEAR_M)
        if box is None:
            return None
        u0, u1, v0, v1 = box
        return np.s_[v0:v1], np.s_[u0:u1]


def _floor_t(Dz: F32, cz: float) -> F32:
    """Ray parameter (= z-depth for rays (xn, yn, 1)) of the plane z = 0; inf where it is not
    hit."""
    if cz <= 0:
        return np.full_like(Dz, np.inf)
    with np.errstate(divide="ignore"):
        t = np.float32(-cz) / Dz
    return np.where(Dz < np.float32(-1e-7), t, np.float32(np.inf))


# ----------------------------------------------------------------------------- low resolution


@dataclass(frozen=True)
class _Coarse:
    """The floor seen on the low-resolution grid: hit points, directions and footprint LOD."""

    cam: _Camera
    D: list[F32]
    t: F32
    px: F32
    py: F32


def _coarse(cam: _Camera) -> _Coarse:
    low = cam.low_res()
    D = low.world_dirs()
    t = np.minimum(_floor_t(D[2], float(cam.centre[2])), FAR_T)
    c = cam.centre.astype(np.float32)
    return _Coarse(low, D, t, c[0] + t * D[0], c[1] + t * D[1])


RELIEF_RANGE_M = 10.0  # beyond this the coarse relief start is the plane (one step: < 10 µm)


def _relief_t(D: list[F32], c: np.ndarray, relief: FloorRelief | None, co: _Coarse) -> F32:
    """Ray parameter of the floor with its ``relief`` (:mod:`gaitnet.sim.floor_relief`; the
    plane z = 0 when None or flat); inf where it is not hit. Two Newton steps on the coarse
    grid ``co`` give the relative change of each hit, interpolated to full resolution as the
    start of one more Newton step there (the coarse start is off by far less than a
    millimetre, so one step brings it below 0.2 µm within the depth range)."""
    t = _floor_t(D[2], float(c[2]))
    if relief is None or relief.is_flat:
        return t
    near = co.t < np.float32(RELIEF_RANGE_M)
    t_low = np.where(near, co.t, np.float32(1.0))
    ratio = np.where(near, relief.ray_t(t_low, c, co.D) / t_low - np.float32(1.0), 0.0)
    h, w = t.shape
    up = cv2.resize(ratio.astype(np.float32), (w, h), interpolation=cv2.INTER_LINEAR)
    hit = np.isfinite(t)
    t0 = np.where(hit, t, np.float32(1.0))
    return np.where(hit, relief.ray_t(t0, c, D, t0 * (np.float32(1.0) + up), steps=1), t)


def _lod(co: _Coarse, texel: float, cz: float, size: tuple[int, int]) -> F32:
    """Floor texture level of detail per pixel, upsampled to ``size`` (w, h)."""
    rays = co.cam.rays
    n2 = rays.xn**2 + rays.yn**2 + 1.0
    f = 0.5 * (co.cam.K[0, 0] + co.cam.K[1, 1]) * LOW_RES
    with np.errstate(divide="ignore", invalid="ignore"):
        lod = np.log2(max(cz, 1e-3) / (f * texel)) + 0.75 * np.log2(n2) - 1.5 * np.log2(-co.D[2])
    lod = np.nan_to_num(lod + LOD_BIAS, nan=30.0, posinf=30.0).astype(np.float32)
    return cv2.resize(lod, size, interpolation=cv2.INTER_LINEAR)


def _lamp_profile(x: F32, y: F32, light: Lighting, sigma: F32 | float) -> F32:
    """Brightness of the ceiling lamps at ceiling point (x, y) blurred by ``sigma``: Gaussian
    across a lamp (energy-preserving), a soft-edged box along it."""
    s = np.float32(light.lamp_spacing_m)
    d = np.mod(x - np.float32(light.lamp_offset_m) + s / 2, s) - s / 2
    half = np.float32(light.lamp_width_m / 2)
    sig = np.maximum(sigma, half)
    across = np.exp(-0.5 * (d / sig) ** 2) * (half / sig)
    along = np.abs(y - np.float32(light.lamp_y_m)) - np.float32(light.lamp_length_m / 2)
    return across * np.clip(0.5 - along / (2 * sig), 0.0, 1.0)


def _shadow(px: F32, py: F32, seg: ShadowSegment, light: Lighting, l_W: np.ndarray) -> F32:
    """Soft shadow factor in [0, 1] of one segment on floor points (px, py)."""
    a = seg.a - (seg.a[2] / l_W[2]) * l_W
    b = seg.b - (seg.b[2] / l_W[2]) * l_W
    ab = (b - a)[:2].astype(np.float32)
    denom = float(ab @ ab) or 1e-12
    ax, ay = np.float32(a[0]), np.float32(a[1])
    u = np.clip(((px - ax) * ab[0] + (py - ay) * ab[1]) / np.float32(denom), 0, 1)
    ex = px - ax - u * ab[0]
    ey = py - ay - u * ab[1]
    dist = np.sqrt(ex * ex + ey * ey)
    height = np.maximum(np.float32(seg.a[2]) + u * np.float32(seg.b[2] - seg.a[2]), 0.0)
    pen = np.float32(0.01) + np.float32(light.shadow_softness) * height
    r = np.float32(seg.r)
    s = np.clip((r + pen / 2 - dist) / pen, 0.0, 1.0)
    return s * s * (3 - 2 * s) * np.minimum(np.float32(1.0), 2 * r / (2 * r + pen))


def _shadow_quad(seg: ShadowSegment, light: Lighting, l_W: np.ndarray) -> np.ndarray:
    """Floor quadrilateral (4, 3) outside which ``seg``'s shadow vanishes."""
    a = seg.a - (seg.a[2] / l_W[2]) * l_W
    b = seg.b - (seg.b[2] / l_W[2]) * l_W
    m = seg.r + 0.01 + light.shadow_softness * max(seg.a[2], seg.b[2], 0.0)
    lo = np.minimum(a, b)[:2] - m
    hi = np.maximum(a, b)[:2] + m
    return np.array([[lo[0], lo[1], 0], [hi[0], lo[1], 0], [hi[0], hi[1], 0], [lo[0], hi[1], 0]])


def _contact(px: F32, py: F32, patch: ContactPatch) -> F32:
    """Contact occlusion in [0, 1] of one patch on floor points (px, py)."""
    T = patch.T_WfromP
    dx, dy, dz = px - np.float32(T[0, 3]), py - np.float32(T[1, 3]), np.float32(-T[2, 3])
    R = T[:3, :3].astype(np.float32)
    x = R[0, 0] * dx + R[1, 0] * dy + R[2, 0] * dz
    y = R[0, 1] * dx + R[1, 1] * dy + R[2, 1] * dz
    z = R[0, 2] * dx + R[1, 2] * dy + R[2, 2] * dz
    e = np.sqrt((x / np.float32(patch.hx)) ** 2 + (y / np.float32(patch.hy)) ** 2)
    d = np.maximum((e - 1) * np.float32(min(patch.hx, patch.hy)), 0.0)
    lift = np.clip(1.0 + z / np.float32(0.06), 0.0, 1.0)
    return np.float32(patch.strength) * np.exp(-d / np.float32(patch.reach_m)) * lift * lift


def _contact_quad(patch: ContactPatch) -> np.ndarray:
    r = 5 * patch.reach_m
    hx, hy = patch.hx + r, patch.hy + r
    local = np.array([[-hx, -hy, 0.0], [hx, -hy, 0.0], [hx, hy, 0.0], [-hx, hy, 0.0]])
    p = local @ patch.T_WfromP[:3, :3].T + patch.T_WfromP[:3, 3]
    p[:, 2] = 0.0
    return p


def _floor_irradiance(
    co: _Coarse,
    light: Lighting,
    shadows: tuple[ShadowSegment, ...],
    patches: tuple[ContactPatch, ...],
) -> F32:
    """Floor irradiance on the coarse grid: lamps × soft shadows × contact occlusion."""
    l_W = light.light_dir()
    k = np.float32(2 * np.pi / light.lamp_spacing_m)
    irr = np.float32(light.ambient + light.key * l_W[2]) * (
        1 + np.float32(light.lamp_variation) * np.cos(k * (co.px - np.float32(light.lamp_offset_m)))
    )
    for seg in shadows:
        reg = co.cam.floor_bbox(_shadow_quad(seg, light, l_W))
        if reg is not None:
            irr[reg] *= 1 - np.float32(light.shadow_strength) * _shadow(
                co.px[reg], co.py[reg], seg, light, l_W
            )
    for patch in patches:
        reg = co.cam.floor_bbox(_contact_quad(patch))
        if reg is not None:
            irr[reg] *= 1 - _contact(co.px[reg], co.py[reg], patch)
    return irr


def _floor_specular(co: _Coarse, floor: FloorTexture, light: Lighting) -> F32:
    """Blurred mirror image of the ceiling lamps in the floor (Schlick Fresnel, f0 = 0.04)."""
    D = co.D
    hc = floor.room_height_m or 2.8
    norm = np.sqrt(D[0] ** 2 + D[1] ** 2 + D[2] ** 2)
    cos = np.clip(-D[2] / norm, 1e-3, 1.0)
    fresnel = 0.04 + 0.96 * (1 - cos) ** 5
    travel = np.float32(hc) / cos  # floor to ceiling along the mirrored ray
    xc = co.px + D[0] / norm * travel
    yc = co.py + D[1] / norm * travel
    sigma = np.float32(0.02) + np.float32(0.06 * (1.0 - floor.gloss)) * travel
    spec = (
        np.float32(floor.gloss * light.lamp_radiance)
        * fresnel
        * _lamp_profile(xc, yc, light, sigma)
    )
    return np.where(D[2] < 0, spec, 0.0).astype(np.float32)


# ----------------------------------------------------------------------------- tag sheets


def _composite_sheets(
    cam: _Camera, floor: FloorTexture, t: F32, lod: F32, albedo: F32, light_rgb: tuple
) -> None:
    """Blend the tag sheets into ``albedo`` in place by their pixel coverage."""
    for sheet in floor.sheets:
        (sx0, sx1), (sy0, sy1) = sheet.extent_b
        corners_b = np.array([[sx0, sy0, 0], [sx1, sy0, 0], [sx1, sy1, 0], [sx0, sy1, 0]], float)
        reg = cam.floor_bbox(corners_b @ sheet.T_WfromBoard[:3, :3].T + sheet.T_WfromBoard[:3, 3])
        if reg is None:
            continue
        colour, cover = sheet_overlay(
            sheet, cam.K, cam.T_CfromW, reg, lod[reg], LOD_BIAS, floor.texel_m, light_rgb
        )
        cover *= np.isfinite(t[reg])
        part = albedo[reg]
        part += (colour - part) * cover[..., None]


# ----------------------------------------------------------------------------- room


def _room_rows(co: _Coarse, floor: FloorTexture, height: int) -> int:
    """Number of top image rows in which a wall or the ceiling can be nearer than the floor:
    the room is a convex box around the camera, so only rays whose floor point lies outside
    the floor's extent (or that miss the floor) leave it through a wall or the ceiling."""
    (x0, x1), (y0, y1) = floor.extent_xy
    out = (co.px <= x0) | (co.px >= x1) | (co.py <= y0) | (co.py >= y1) | (co.t >= FAR_T)
    rows = np.flatnonzero(out.any(axis=1))
    return 0 if rows.size == 0 else min(height, (int(rows[-1]) + 2) * LOW_RES)


def _room_hit(D: list[F32], c: np.ndarray, floor: FloorTexture) -> tuple[F32, NDArray[np.int8]]:
    """Ray parameter to the walls/ceiling and the face hit (0: x wall, 1: y wall, 2: ceiling)."""
    (x0, x1), (y0, y1) = floor.extent_xy
    hc = float(floor.room_height_m or 0.0)
    with np.errstate(divide="ignore"):
        tx = np.where(D[0] > 0, np.float32(x1 - c[0]) / D[0], np.float32(x0 - c[0]) / D[0])
        ty = np.where(D[1] > 0, np.float32(y1 - c[1]) / D[1], np.float32(y0 - c[1]) / D[1])
        tz = np.where(D[2] > 0, np.float32(hc - c[2]) / D[2], np.float32(np.inf))
    t = np.minimum(np.minimum(tx, ty), tz)
    face = np.where(tz <= t, 2, np.where(ty <= t, 1, 0)).astype(np.int8)
    return t, face


def _shade_room(
    p: F32, D: list[F32], face: NDArray[np.int8], floor: FloorTexture, light: Lighting
) -> F32:
    """Colour (N, 3) of wall/ceiling points ``p`` (N, 3) hit by rays ``D`` on faces ``face``."""
    hc = float(floor.room_height_m or 2.8)
    l_W = light.light_dir().astype(np.float32)
    nx = np.where(face == 0, -np.sign(D[0]), 0).astype(np.float32)
    ny = np.where(face == 1, -np.sign(D[1]), 0).astype(np.float32)
    irr = np.float32(light.ambient * (1 - 0.5 * light.ambient_down_loss)) + np.float32(
        light.key
    ) * np.maximum(nx * l_W[0] + ny * l_W[1], 0)
    albedo = np.broadcast_to(np.asarray(floor.wall_rgb, np.float32), p.shape).copy()
    albedo[p[:, 2] < SKIRTING_M] = (0.05, 0.05, 0.05)
    grad = 1.0 - 0.15 * np.clip(p[:, 2] / np.float32(hc), 0, 1)
    col = albedo * (irr * grad)[:, None]
    ceil_irr = np.float32(light.ambient * (1 - light.ambient_down_loss))
    lamps = _lamp_profile(p[:, 0], p[:, 1], light, 0.0) > 0.6
    ceil_col = np.where(lamps[:, None], np.float32(light.lamp_radiance), 0.8 * ceil_irr)
    col = np.where((face == 2)[:, None], ceil_col, col)
    return (col * np.asarray(light.rgb, np.float32)).astype(np.float32)


def _paint_room(
    cam: _Camera,
    co: _Coarse,
    floor: FloorTexture,
    light: Lighting,
    out: tuple[F32, F32, NDArray[np.bool_]],
) -> bool:
    """Trace walls and ceiling in the rows where they can show; update (depth, rgb, is_floor)
    in place. False when there is no room around the camera (nothing done)."""
    depth, rgb, is_floor = out
    (x0, x1), (y0, y1) = floor.extent_xy
    c = cam.centre
    hc = floor.room_height_m
    if hc is None or not (x0 < c[0] < x1 and y0 < c[1] < y1 and 0 < c[2] < hc):
        return False
    n = _room_rows(co, floor, cam.height)
    if n == 0:
        return True
    R = cam.T_WfromC[:3, :3].astype(np.float32)
    rays = cam.rays
    D = [R[i, 0] * rays.xn[:n] + R[i, 1] * rays.yn[:n] + R[i, 2] for i in range(3)]
    t, face = _room_hit(D, c, floor)
    wall = t < depth[:n]
    if not wall.any():
        return True
    tw = t[wall]
    Dw = [d[wall] for d in D]
    p = np.stack([np.float32(c[i]) + tw * Dw[i] for i in range(3)], axis=1)
    depth[:n][wall] = tw
    rgb[:n][wall] = _shade_room(p, Dw, face[wall], floor, light)
    is_floor[:n][wall] = False
    return True


# ----------------------------------------------------------------------------- main


def render_environment(
    K: np.ndarray,
    width: int,
    height: int,
    T_WfromC: np.ndarray,
    floor: FloorTexture,
    light: Lighting,
    shadows: tuple[ShadowSegment, ...] = (),
    patches: tuple[ContactPatch, ...] = (),
    relief: FloorRelief | None = None,
) -> Environment:
    """Depth and colour (before the light colour) of floor, sheets, walls and ceiling; the
    floor has the height field ``relief`` (None: the plane z = 0). The floor's lighting
    (irradiance, mirror image, level of detail) is computed on the plane: the relief moves a
    point by millimetres there."""
    cam = _Camera.make(K, width, height, T_WfromC)
    c = cam.centre
    inv = 1.0 / floor.texel_m
    D = cam.world_dirs()
    co = _coarse(cam)
    depth = _relief_t(D, c, relief, co)
    Dx, Dy = D[0] * np.float32(inv), D[1] * np.float32(inv)
    is_floor = np.isfinite(depth)
    tm = np.minimum(depth, FAR_T)
    (fx0, _), (fy0, _) = floor.extent_xy
    mx = tm * Dx + np.float32((c[0] - fx0) * inv - 0.5)
    my = tm * Dy + np.float32((c[1] - fy0) * inv - 0.5)
    lod = _lod(co, floor.texel_m, float(c[2]), (width, height))
    rgb = decode_srgb8(sample_mipmapped(floor.levels, mx, my, lod), light.rgb)
    _composite_sheets(cam, floor, depth, lod, rgb, light.rgb)
    irr = _floor_irradiance(co, light, shadows, patches)
    irr = cv2.resize(cv2.merge([irr, irr, irr]), (width, height))
    if floor.gloss > 0:  # rgb · irradiance + the lamps' mirror image, in one pass
        spec = _floor_specular(co, floor, light)[..., None] * np.asarray(light.rgb, np.float32)
        spec = cv2.resize(spec, (width, height))
        rgb = cv2.accumulateProduct(rgb, irr, spec)
    else:
        rgb = cv2.multiply(rgb, irr, dst=rgb)
    if not _paint_room(cam, co, floor, light, (depth, rgb, is_floor)):
        sky = ~is_floor
        if sky.any():
            rgb[sky] = np.asarray(light.background_rgb, np.float32) * light.rgb
    return Environment(depth, rgb, is_floor)
