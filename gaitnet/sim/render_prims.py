"""Analytic ray casting of the renderer's primitives, and their signed distance functions.

All intersections take rays from the origin (the camera centre) with *unit* directions given as
three equally shaped float32 arrays ``(dx, dy, dz)`` and return the ray parameter ``t`` (the
distance along the ray, ``inf`` where the ray misses); the depth is ``t · dz``.

Primitives:

* round cone (a "cone-sphere": the convex hull of two spheres) for trouser legs, after
  Inigo Quilez's ray/round-cone intersection and signed distance;
* :class:`ConvexShape`: an intersection of half-spaces ``n·p ≤ h`` and quadrics
  ``|A (p − c)|² ≤ 1`` (ellipsoids, or elliptic cylinders when a row of ``A`` is zero); boxes,
  cylinders and the two parts of a shoe are such shapes.

The shoe (frame of :mod:`gaitnet.sim.scene`) is the union of a sole (its outline — the
intersection of a heel and a toe elliptic cylinder — extruded to the sole thickness) and an
upper (the outline inset by 1 mm ∩ an ellipsoid whose top passes through
``(0, 0, height_m)`` and falls to the sole at the toe), which from above is elongated with a
rounded toe, a narrower heel and a flat sole. Everything is smooth except the sole's edges and
the two shallow creases where the heel and toe cylinders meet.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from gaitnet.sim.render_types import cross3, normalize_rows
from gaitnet.sim.scene import LegSegment, ShoeState

F32 = NDArray[np.float32]
INF = np.float32(np.inf)
_BOX_EDGES = ((0, 1), (2, 3), (4, 5), (6, 7), (0, 2), (1, 3), (4, 6), (5, 7),
              (0, 4), (1, 5), (2, 6), (3, 7))  # fmt: skip


# ----------------------------------------------------------------------------- screen bounds


def box_corners(centre: np.ndarray, axes: np.ndarray, half: np.ndarray) -> np.ndarray:
    """(8, 3) corners of an oriented box; ``axes`` (3, 3) columns are its unit axes."""
    signs = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], float)
    return centre + (signs * half) @ axes.T


def screen_bbox(
    K: np.ndarray, corners_C: np.ndarray, width: int, height: int, near: float
) -> tuple[int, int, int, int] | None:
    """Pixel rectangle ``(u0, u1, v0, v1)`` (end-exclusive) covering a box's projection.

    The box (8 corners in the camera frame, :func:`box_corners` order) is clipped against the
    plane z = ``near`` first, so boxes partly behind the camera are bounded correctly; None when
    nothing of it lies in front of the camera or inside the image.
    """
    z = corners_C[:, 2]
    pts = [corners_C[z >= near]]
    for i, j in _BOX_EDGES:
        zi, zj = z[i], z[j]
        if (zi - near) * (zj - near) < 0:
            s = (near - zi) / (zj - zi)
            pts.append(corners_C[i] + s * (corners_C[j] - corners_C[i])[None])
    p = np.concatenate(pts)
    if p.shape[0] == 0:
        return None
    uvw = p @ K.T
    u, v = uvw[:, 0] / uvw[:, 2], uvw[:, 1] / uvw[:, 2]
    u0, u1 = max(0, int(np.floor(u.min()))), min(width, int(np.ceil(u.max())) + 1)
    v0, v1 = max(0, int(np.floor(v.min()))), min(height, int(np.ceil(v.max())) + 1)
    if u0 >= u1 or v0 >= v1:
        return None
    return u0, u1, v0, v1


def _basis(axis: np.ndarray) -> np.ndarray:
    """(3, 3) orthonormal columns whose first column is ``axis`` (unit)."""
    helper = np.array([0.0, 0.0, 1.0]) if abs(axis[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    e1 = cross3(axis, helper)
    e1 /= np.linalg.norm(e1)
    return np.stack([axis, e1, cross3(axis, e1)], axis=1)


# ----------------------------------------------------------------------------- round cone


@dataclass(frozen=True)
class RoundCone:
    """Convex hull of the spheres (``a``, ``ra``) and (``b``, ``rb``), in one frame."""

    a: np.ndarray
    b: np.ndarray
    ra: float
    rb: float

    @classmethod
    def from_leg(cls, leg: LegSegment) -> RoundCone:
        a = np.asarray(leg.p_top_W, np.float64)
        b = np.asarray(leg.p_bottom_W, np.float64)
        return cls(a, b, float(leg.radius_top_m), float(leg.radius_bottom_m))

    def transformed(self, T_BfromA: np.ndarray) -> RoundCone:
        R, t = T_BfromA[:3, :3], T_BfromA[:3, 3]
        return RoundCone(R @ self.a + t, R @ self.b + t, self.ra, self.rb)

    def corners(self) -> np.ndarray:
        """(8, 3) corners of an oriented bounding box."""
        ba = self.b - self.a
        length = float(np.linalg.norm(ba))
        axis = ba / length if length > 0 else np.array([0.0, 0.0, 1.0])
        r = max(self.ra, self.rb)
        centre = self.a + axis * (length + self.rb - self.ra) / 2
        half = np.array([(length + self.ra + self.rb) / 2, r, r])
        return box_corners(centre, _basis(axis), half)

    def intersect(self, dx: F32, dy: F32, dz: F32) -> tuple[F32, NDArray[np.int8]]:
        """Entry distance along unit rays from the origin (inf on a miss or from inside) and the
        part entered (0 body, 1 sphere a, 2 sphere b).

        Quilez's iRoundedCone without its early "misses the infinite cone" exit, which is wrong
        for rays that start inside the (double) cone's extension — a camera looking along a
        thigh from above the hip.
        """
        a, b = self.a.astype(np.float32), self.b.astype(np.float32)
        ra, rb = np.float32(self.ra), np.float32(self.rb)
        ba, oa = b - a, -a
        rr = ra - rb
        m0, m1 = np.float32(ba @ ba), np.float32(ba @ oa)
        m5, m7 = np.float32(oa @ oa), np.float32(b @ b)
        d2 = m0 - rr * rr
        k0 = d2 * m5 - m1 * m1 + m1 * (rr * ra * 2) - m0 * ra * ra
        m2 = ba[0] * dx + ba[1] * dy + ba[2] * dz
        m3 = oa[0] * dx + oa[1] * dy + oa[2] * dz
        m6 = m3 - m2
        k2 = d2 - m2 * m2
        k1 = d2 * m3 + m2 * (rr * ra - m1)
        with np.errstate(invalid="ignore", divide="ignore"):
            t_body = (-np.sqrt(k1 * k1 - k0 * k2) - k1) / k2
            y = t_body * m2 + (m1 - ra * rr)
            body = (y > 0) & (y < d2)
            t_a = -m3 - np.sqrt(m3 * m3 + (ra * ra - m5))
            t_b = -m6 - np.sqrt(m6 * m6 + (rb * rb - m7))
            cap_b = ~(t_a <= t_b)  # also where t_a is NaN (sphere a missed)
            t = np.where(body, t_body, np.fmin(t_a, t_b))
            part = np.where(body, 0, np.where(cap_b, 2, 1)).astype(np.int8)
            return np.where(t > 0, t, INF).astype(np.float32), part

    def normals(self, p: F32, part: NDArray[np.int8]) -> F32:
        """Outward unit normals (N, 3) at surface points ``p`` (N, 3) on ``part``."""
        a, b = self.a.astype(np.float32), self.b.astype(np.float32)
        ba = b - a
        rr = np.float32(self.ra - self.rb)
        d2 = np.float32(ba @ ba) - rr * rr
        q = p - a
        y = q @ ba - np.float32(self.ra) * rr
        n = d2 * q - y[:, None] * ba
        on_a, on_b = part == 1, part == 2
        n[on_a] = q[on_a]
        n[on_b] = p[on_b] - b
        return normalize_rows(n)

    def sdf(self, p: np.ndarray) -> np.ndarray:
        """Exact signed distance (Quilez's sdRoundCone) at points ``p`` (..., 3), float64."""
        p = np.asarray(p, np.float64)
        ba = self.b - self.a
        l2 = float(ba @ ba)
        rr = self.ra - self.rb
        a2 = l2 - rr * rr
        il2 = 1.0 / l2
        pa = p - self.a
        y = pa @ ba
        z = y - l2
        x2 = np.sum((pa * l2 - y[..., None] * ba) ** 2, axis=-1)
        y2, z2 = y * y * l2, z * z * l2
        k = np.sign(rr) * rr * rr * x2
        d_b = np.sqrt(x2 + z2) * il2 - self.rb
        d_a = np.sqrt(x2 + y2) * il2 - self.ra
        d_body = (np.sqrt(x2 * a2 * il2) + y * rr) * il2 - self.ra
        return np.where(
            np.sign(z) * a2 * z2 > k, d_b, np.where(np.sign(y) * a2 * y2 < k, d_a, d_body)
        )


# ----------------------------------------------------------------------------- convex shapes


@dataclass(frozen=True)
class Quadric:
    """``{p : |A (p − c)|² ≤ 1}``: an ellipsoid, or an elliptic cylinder when a row of ``A`` is
    zero (that direction is unbounded)."""

    A: np.ndarray
    c: np.ndarray

    def transformed(self, T_BfromA: np.ndarray) -> Quadric:
        R, t = T_BfromA[:3, :3], T_BfromA[:3, 3]
        return Quadric(self.A @ R.T, R @ self.c + t)

    def span(self, dx: F32, dy: F32, dz: F32) -> tuple[F32, F32]:
        """Entry and exit distances of unit rays from the origin (entry inf on a miss)."""
        A = self.A.astype(np.float32)
        f = -(A @ self.c.astype(np.float32))
        qa = qb = None
        for row, fi in zip(A, f, strict=True):
            if not row.any():
                continue
            e = row[0] * dx + row[1] * dy + row[2] * dz
            qa = e * e if qa is None else qa + e * e
            qb = e * fi if qb is None else qb + e * fi
        assert qa is not None and qb is not None
        qc = np.float32(f @ f - 1.0)
        disc = qb * qb - qa * qc
        with np.errstate(divide="ignore", invalid="ignore"):
            sq = np.sqrt(disc)
            inv = np.float32(1.0) / qa
            t0, t1 = (-qb - sq) * inv, (-qb + sq) * inv
        ok = disc >= 0
        if qc <= 0:  # origin inside: rays parallel to the axis never leave it
            par = qa == 0
            t0, t1 = np.where(par, -INF, t0), np.where(par, INF, t1)
            ok |= par
        return np.where(ok, t0, INF), np.where(ok, t1, -INF)

    def normals(self, p: F32) -> F32:
        A = self.A.astype(np.float32)
        g = ((p - self.c.astype(np.float32)) @ A.T) @ A
        return normalize_rows(g)

    def sdf(self, p: np.ndarray) -> np.ndarray:
        """First-order signed distance (exact sign, zero on the surface), float64."""
        q = (np.asarray(p, np.float64) - self.c) @ self.A.T
        qn = np.linalg.norm(q, axis=-1)
        grad = (q / np.maximum(qn, 1e-12)[..., None]) @ self.A
        return (qn - 1.0) / np.linalg.norm(grad, axis=-1)


@dataclass(frozen=True)
class ConvexShape:
    """``{p : n_i·p ≤ h_i for all planes} ∩ quadric_1 ∩ quadric_2 ∩ ...``.

    ``planes`` (P, 4) rows ``(n, h)`` with unit ``n``; ``bound`` (8, 3) box corners enclosing
    it. Constraint ``k`` < P is plane ``k``, ``k ≥ P`` is quadric ``k − P``.
    """

    planes: np.ndarray
    bound: np.ndarray
    quadrics: tuple[Quadric, ...] = ()

    def transformed(self, T_BfromA: np.ndarray) -> ConvexShape:
        """The same shape expressed in frame B."""
        R, t = T_BfromA[:3, :3], T_BfromA[:3, 3]
        n = self.planes[:, :3] @ R.T
        planes = np.concatenate([n, (self.planes[:, 3] + n @ t)[:, None]], axis=1)
        quads = tuple(q.transformed(T_BfromA) for q in self.quadrics)
        return ConvexShape(planes, self.bound @ R.T + t, quads)

    def _spans(self, dx: F32, dy: F32, dz: F32):
        for n0, n1, n2, h in self.planes.astype(np.float32):
            denom = n0 * dx + n1 * dy + n2 * dz
            with np.errstate(divide="ignore", invalid="ignore"):
                tt = h / denom
            outside = INF if h < 0 else -INF  # entry of rays parallel to or leaving the plane
            yield np.where(denom < 0, tt, outside), np.where(denom > 0, tt, INF)
        for q in self.quadrics:
            yield q.span(dx, dy, dz)

    def intersect(self, dx: F32, dy: F32, dz: F32) -> tuple[F32, NDArray[np.int8]]:
        """Entry distance along unit rays from the origin (inf on a miss or from inside) and
        which constraint was entered (module docstring)."""
        enter = np.full(dx.shape, -INF, np.float32)
        exit_ = np.full(dx.shape, INF, np.float32)
        which = np.zeros(dx.shape, np.int8)
        for k, (t0, t1) in enumerate(self._spans(dx, dy, dz)):
            later = t0 > enter
            np.copyto(enter, t0, where=later)
            which[later] = k
            np.minimum(exit_, t1, out=exit_)
        hit = (enter <= exit_) & (enter > 0)
        return np.where(hit, enter, INF).astype(np.float32), which

    def normals(self, p: F32, which: NDArray[np.int8]) -> F32:
        """Outward unit normals (N, 3) at surface points ``p`` entered through ``which``."""
        n_pl = self.planes[:, :3].astype(np.float32)
        P = n_pl.shape[0]
        out = n_pl[np.minimum(which, P - 1)]
        for j, q in enumerate(self.quadrics):
            sel = which == P + j
            if sel.any():
                out[sel] = q.normals(p[sel])
        return out

    def sdf(self, p: np.ndarray) -> np.ndarray:
        """Signed distance bound (exact on planes, first order on quadrics), float64."""
        p = np.asarray(p, np.float64)
        dist = (p @ self.planes[:, :3].T - self.planes[:, 3]).max(axis=-1)
        for q in self.quadrics:
            dist = np.maximum(dist, q.sdf(p))
        return dist


def _slab_planes(z0: float, z1: float) -> np.ndarray:
    return np.array([[0.0, 0.0, -1.0, -z0], [0.0, 0.0, 1.0, z1]])


def box_shape(centre: np.ndarray, R: np.ndarray, half: np.ndarray) -> ConvexShape:
    """An oriented box: centre, rotation (columns = box axes), half sizes."""
    planes = []
    for i in range(3):
        n = R[:, i]
        planes += [[*n, n @ centre + half[i]], [*(-n), -(n @ centre) + half[i]]]
    return ConvexShape(np.array(planes), box_corners(centre, R, half))


def upright_cylinder(centre_xy: tuple[float, float], radius: float, height: float) -> ConvexShape:
    """A vertical cylinder standing on z = 0."""
    c = np.array([centre_xy[0], centre_xy[1], 0.0])
    A = np.diag([1.0 / radius, 1.0 / radius, 0.0])
    bound = box_corners(c + [0, 0, height / 2], np.eye(3), np.array([radius, radius, height / 2]))
    return ConvexShape(_slab_planes(0.0, height), bound, (Quadric(A, c),))


# ----------------------------------------------------------------------------- shoes


def sole_thickness(height_m: float) -> float:
    """Sole thickness used for a shoe of total height ``height_m``."""
    return float(np.clip(0.28 * height_m, 0.012, 0.035))


def _elliptic_cylinder(cx: float, a: float, b: float, yaw: float) -> Quadric:
    """Vertical elliptic cylinder centred at (cx, 0), half axes a (along x, turned by ``yaw``)
    and b."""
    c, s = np.cos(yaw), np.sin(yaw)
    A = np.array([[c / a, s / a, 0.0], [-s / b, c / b, 0.0], [0.0, 0.0, 0.0]])
    return Quadric(A, np.array([cx, 0.0, 0.0]))


def shoe_outline_cylinders(
    length: float, width: float, medial_sign: float, inset: float = 0.0
) -> tuple[Quadric, Quadric]:
    """The sole outline as the intersection of two vertical elliptic cylinders: a heel one
    (rounded, 78 % narrower heel) and a toe one (rounded toe turned 4° to the medial side).

    ``inset`` shrinks both by that many metres (the upper sits inside the sole's rim).
    """
    L, W = length, width
    heel = _elliptic_cylinder(0.1 * L, 0.6 * L - inset, 0.55 * W - inset, 0.0)
    toe = _elliptic_cylinder(
        -0.3 * L, 0.8 * L - inset, 0.64 * W - inset, np.deg2rad(4) * medial_sign
    )
    return heel, toe


@dataclass(frozen=True)
class ShoeGeometry:
    """The two convex parts of a shoe in the shoe frame and its sole thickness."""

    sole: ConvexShape
    upper: ConvexShape
    sole_m: float


@lru_cache(maxsize=64)
def shoe_geometry(length: float, width: float, height: float, side: str) -> ShoeGeometry:
    """Shoe parts in the shoe frame (module docstring)."""
    medial = -1.0 if side == "left" else 1.0
    hs = sole_thickness(height)
    xc, ax = -0.15 * length, 0.68 * length
    az = height / np.sqrt(1.0 - (xc / ax) ** 2)
    dome = Quadric(np.diag([1.0 / ax, 1.0 / (0.7 * width), 1.0 / az]), np.array([xc, 0.0, 0.0]))
    half = np.array([0.5 * length, 0.6 * width, 0.5 * height * 1.05])
    bound = box_corners(np.array([0.0, 0.0, half[2]]), np.eye(3), half)
    sole = ConvexShape(_slab_planes(0.0, hs), bound, shoe_outline_cylinders(length, width, medial))
    rim = shoe_outline_cylinders(length, width, medial, inset=0.001)
    upper = ConvexShape(_slab_planes(0.5 * hs, 2 * height)[:1], bound, (*rim, dome))
    return ShoeGeometry(sole, upper, hs)


def geometry_of(shoe: ShoeState) -> ShoeGeometry:
    return shoe_geometry(float(shoe.length_m), float(shoe.width_m), float(shoe.height_m), shoe.side)


def T_WfromShoe(shoe: ShoeState) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = np.asarray(shoe.R_WfromShoe, np.float64)
    T[:3, 3] = np.asarray(shoe.p_SoleCentre_W, np.float64)
    return T


def shoe_sdf(shoe: ShoeState, p_W: np.ndarray) -> np.ndarray:
    """Signed distance bound of the rendered shoe at world points ``p_W`` (..., 3)."""
    T = T_WfromShoe(shoe)
    p_S = (np.asarray(p_W, np.float64) - T[:3, 3]) @ T[:3, :3]
    g = geometry_of(shoe)
    return np.minimum(g.sole.sdf(p_S), g.upper.sdf(p_S))


def leg_sdf(leg: LegSegment, p_W: np.ndarray) -> np.ndarray:
    """Exact signed distance of the rendered trouser leg at world points ``p_W`` (..., 3)."""
    return RoundCone.from_leg(leg).sdf(p_W)
