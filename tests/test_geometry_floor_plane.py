"""Floor plane fit with a gravity prior, height map (geometry.floor_plane, thesis (3.22)–(3.23))."""

import numpy as np
import pytest

from gaitnet.geometry.camera import depth_to_points, project
from gaitnet.geometry.floor_plane import (
    FloorParams,
    FloorPlane,
    fit_floor,
    fit_floor_depth,
    height_map,
)
from gaitnet.geometry.rotation import so3_exp

K = np.array([[386.0, 0.0, 319.5], [0.0, 386.0, 239.5], [0.0, 0.0, 1.0]])


def _pose(pitch_deg: float, height: float) -> np.ndarray:
    """T_WfromC of a camera at ``height`` looking forward (+x) and pitched down."""
    R0 = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])  # z fwd, x right, y down
    R = so3_exp(np.array([0.0, np.radians(pitch_deg), 0.0])) @ R0
    T = np.eye(4)
    T[:3, :3] = R
    T[2, 3] = height
    return T


def _true_plane(T_WfromC):
    return T_WfromC[:3, :3].T @ np.array([0.0, 0.0, 1.0]), T_WfromC[2, 3]


def _floor_cloud(rng, T, n, noise):
    """Points of the world floor z = 0 in front of the camera, in the camera frame."""
    P_W = np.c_[rng.uniform(0.3, 2.5, n), rng.uniform(-1.0, 1.0, n), rng.normal(0, noise, n)]
    return (P_W - T[:3, 3]) @ T[:3, :3]


def test_known_plane_with_noise_and_outliers():
    rng = np.random.default_rng(0)
    T = _pose(60.0, 1.05)
    floor = _floor_cloud(rng, T, 3000, 0.002)
    # 40 % outliers: boxes and legs above the floor, random junk
    junk_W = np.c_[
        rng.uniform(0.3, 1.5, 2000), rng.uniform(-0.5, 0.5, 2000), rng.uniform(0.03, 0.8, 2000)
    ]
    junk = (junk_W - T[:3, 3]) @ T[:3, :3]
    pts = rng.permutation(np.vstack([floor, junk]))
    n_true, h_true = _true_plane(T)
    plane = fit_floor(pts, n_true, FloorParams())
    assert plane is not None
    assert np.degrees(np.arccos(plane.n_C @ n_true)) < 0.3
    assert abs(plane.h - h_true) < 0.003
    assert plane.n_inliers > 2500
    assert plane.rms_m < 0.005


def test_height_sign_convention():
    # (3.22)–(3.23) corrected: n·p + h = 0 on the floor, h > 0, height = h + n·p
    T = _pose(70.0, 1.1)
    n, h = _true_plane(T)
    plane = FloorPlane(n_C=n, h=h)
    P_W = np.array([[1.0, 0.2, 0.0], [1.0, 0.2, 0.1], [0.5, -0.3, 0.25]])
    p_C = (P_W - T[:3, 3]) @ T[:3, :3]
    np.testing.assert_allclose(plane.height(p_C), P_W[:, 2], atol=1e-12)
    assert plane.height(np.zeros(3)) == pytest.approx(1.1)  # the camera itself
    np.testing.assert_allclose(plane.height(plane.project(p_C)), 0.0, atol=1e-12)
    hit = plane.intersect_ray(p_C[2])
    assert plane.height(hit) == pytest.approx(0.0, abs=1e-12)
    assert plane.intersect_ray(-n) is not None and plane.intersect_ray(n) is None


def test_fitted_plane_is_oriented_towards_the_camera():
    rng = np.random.default_rng(1)
    T = _pose(45.0, 0.9)
    n_true, _ = _true_plane(T)
    plane = fit_floor(_floor_cloud(rng, T, 2000, 0.001), n_true)
    assert plane.h > 0 and plane.n_C @ n_true > 0.99


def test_gravity_prior_rejects_a_wall():
    rng = np.random.default_rng(2)
    T = _pose(30.0, 1.0)
    floor = _floor_cloud(rng, T, 800, 0.002)
    # a wall x = 1.2 m in front, with more points than the floor
    wall_W = np.c_[np.full(3000, 1.2), rng.uniform(-1.5, 1.5, 3000), rng.uniform(0.0, 2.0, 3000)]
    wall = (wall_W - T[:3, 3]) @ T[:3, :3]
    pts = np.vstack([floor, wall])
    n_true, h_true = _true_plane(T)
    plane = fit_floor(pts, n_true)
    assert plane is not None
    assert np.degrees(np.arccos(plane.n_C @ n_true)) < 0.5
    assert abs(plane.h - h_true) < 0.005
    # without the prior doing its job (a prior pointing at the wall) the wall wins
    wall_normal_C = T[:3, :3].T @ np.array([-1.0, 0.0, 0.0])
    other = fit_floor(pts, wall_normal_C)
    assert other is not None and abs(other.n_C @ n_true) < 0.1
    # only walls in view: no floor
    assert fit_floor(wall, n_true) is None


def _render_floor_depth(T, shape=(480, 640)):
    """Depth image of the world floor z = 0 seen by camera T (0 where the ray misses)."""
    H, W = shape
    v, u = np.mgrid[0:H, 0:W]
    rays = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones((H, W))], -1)
    n, h = _true_plane(T)
    denom = rays @ n
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(denom < -1e-6, -h / denom, 0.0)
    return z.astype(np.float32)


def test_depth_image_fit_and_height_map():
    T = _pose(65.0, 1.0)
    depth = _render_floor_depth(T)
    rng = np.random.default_rng(3)
    depth = depth + (depth > 0) * rng.normal(0, 0.002, depth.shape).astype(np.float32)
    depth[100:140, 200:300] = 0.0  # holes
    # a box 10 cm high at (1.0, 0, 0.1): pixels that see its top
    p_box_C = (np.array([1.0, 0.0, 0.1]) - T[:3, 3]) @ T[:3, :3]
    uv, _ = project(K, p_box_C)
    u0, v0 = np.round(uv).astype(int)
    depth[v0 - 5 : v0 + 5, u0 - 5 : u0 + 5] = p_box_C[2]
    n_true, h_true = _true_plane(T)
    up_prior = so3_exp(np.radians([3.0, -4.0, 0.0])) @ n_true  # an accelerometer off by 5°
    plane = fit_floor_depth(depth, K, up_prior)
    assert plane is not None
    assert np.degrees(np.arccos(plane.n_C @ n_true)) < 0.3
    assert abs(plane.h - h_true) < 0.003
    hm = height_map(depth, K, plane)
    assert hm.dtype == np.float32 and hm.shape == depth.shape
    assert np.isnan(hm[120, 250])
    assert hm[v0, u0] == pytest.approx(0.1, abs=0.01)
    pts = depth_to_points(depth, K)
    ok = np.isfinite(pts[..., 2])
    np.testing.assert_allclose(hm[ok], plane.height(pts[ok]), atol=1e-4)
    assert np.nanmedian(np.abs(hm)) < 0.005


def test_height_map_of_a_box_is_the_whole_maps_box() -> None:
    """``origin`` places a depth box in the image: the same heights, to the bit."""
    rng = np.random.default_rng(12)
    depth = rng.uniform(0.5, 3.0, (48, 64)).astype(np.float32)
    depth[5:9, 10:20] = 0.0
    K = np.array([[60.0, 0, 31.5], [0, 61.0, 23.5], [0, 0, 1]])
    plane = FloorPlane(
        n_C=np.array([0.05, -0.94, -0.34]) / np.linalg.norm([0.05, -0.94, -0.34]), h=1.1
    )
    whole = height_map(depth, K, plane)
    rows, cols = slice(3, 40), slice(7, 50)
    box = height_map(depth[rows, cols], K, plane, origin=(7, 3))
    np.testing.assert_array_equal(box, whole[rows, cols])
