"""Pinhole camera: projection, back-projection, depth images, projection Jacobian."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from gaitnet.geometry import backproject, depth_to_points, project, projection_jacobian
from gaitnet.io.types import CameraIntrinsics

INTR = CameraIntrinsics(width=64, height=48, fx=60.0, fy=62.0, cx=31.2, cy=24.7)
K = INTR.K
K_SKEW = np.array([[500.0, 1.5, 320.0], [0.0, 480.0, 240.0], [0.0, 0.0, 1.0]])


def random_points(rng: np.random.Generator, n: int) -> np.ndarray:
    return np.column_stack([rng.uniform(-2, 2, n), rng.uniform(-2, 2, n), rng.uniform(0.3, 6, n)])


def test_project_known_values_and_manual_formula() -> None:
    uv, valid = project(K, [0.0, 0.0, 2.0])
    np.testing.assert_array_equal(uv, [INTR.cx, INTR.cy])  # optical axis hits the principal point
    assert valid
    # x right, y down: a point right of and below the axis lands right of / below (cx, cy)
    uv, _ = project(K, [0.5, 0.25, 2.0])
    np.testing.assert_allclose(uv, [INTR.cx + 60.0 * 0.25, INTR.cy + 62.0 * 0.125])
    rng = np.random.default_rng(0)
    p = random_points(rng, 100)
    for Km in (K, K_SKEW):
        h = p @ Km.T
        uv, valid = project(Km, p)
        np.testing.assert_allclose(uv, h[:, :2] / h[:, 2:], atol=1e-12)
        assert valid.all()


def test_project_marks_points_behind_camera_invalid_without_warnings() -> None:
    p = np.array([[0.1, 0.2, 1.0], [0.1, 0.2, 0.0], [0.1, 0.2, -1.0], [np.nan, 0.0, 1.0]])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        uv, valid = project(K, p)
    np.testing.assert_array_equal(valid, [True, False, False, False])
    assert np.all(np.isfinite(uv[0]))
    assert np.all(np.isnan(uv[1:]))
    _, valid_min = project(K, [[0, 0, 0.05], [0, 0, 0.5]], min_depth=0.1)
    np.testing.assert_array_equal(valid_min, [False, True])


def test_project_backproject_round_trips() -> None:
    rng = np.random.default_rng(1)
    p = random_points(rng, 200).reshape(10, 20, 3)
    for Km in (K, K_SKEW):
        uv, valid = project(Km, p)
        assert uv.shape == (10, 20, 2) and valid.shape == (10, 20)
        back = backproject(Km, uv[..., 0], uv[..., 1], p[..., 2])
        np.testing.assert_allclose(back, p, atol=1e-12)
        u = rng.uniform(0, 640, 50)
        v = rng.uniform(0, 480, 50)
        z = rng.uniform(0.2, 8.0, 50)
        uv2, _ = project(Km, backproject(Km, u, v, z))
        np.testing.assert_allclose(uv2, np.column_stack([u, v]), atol=1e-10)


def test_backproject_broadcasts() -> None:
    pts = backproject(K, np.arange(4.0)[None, :], np.arange(3.0)[:, None], 2.0)
    assert pts.shape == (3, 4, 3)
    np.testing.assert_allclose(pts[..., 2], 2.0)
    np.testing.assert_allclose(
        pts[1, 3], [2.0 * (3.0 - INTR.cx) / 60.0, 2.0 * (1.0 - INTR.cy) / 62.0, 2.0]
    )


def test_depth_to_points_reconstructs_a_plane() -> None:
    # plane n·p = d seen obliquely (like the floor from a waist camera)
    n = np.array([0.0, -0.8, -0.6])
    n /= np.linalg.norm(n)
    d = -1.0
    v, u = np.mgrid[0 : INTR.height, 0 : INTR.width].astype(float)
    rays = np.stack([(u - INTR.cx) / INTR.fx, (v - INTR.cy) / INTR.fy, np.ones_like(u)], axis=-1)
    depth = d / (rays @ n)  # z of the ray/plane intersection (rays have z = 1)
    depth[depth < 0] = 0.0  # rays that miss the plane: no data
    depth[5, 7] = np.nan
    depth[6, 8] = -1.0
    assert (depth > 0).sum() > 100  # the plane fills much of the image
    pts = depth_to_points(depth, K)
    assert pts.shape == (INTR.height, INTR.width, 3)
    valid = np.isfinite(pts[..., 2])
    np.testing.assert_array_equal(valid, np.isfinite(depth) & (depth > 0))
    assert np.all(np.isnan(pts[~valid]))
    np.testing.assert_allclose(pts[valid] @ n, d, atol=1e-12)
    np.testing.assert_allclose(pts[valid][:, 2], depth[valid])
    # every valid point projects back to its own pixel
    uv, ok = project(K, pts[valid])
    assert ok.all()
    np.testing.assert_allclose(uv, np.column_stack([u[valid], v[valid]]), atol=1e-9)


def test_depth_to_points_rejects_bad_input() -> None:
    with pytest.raises(ValueError):
        depth_to_points(np.zeros((4, 4), dtype=np.uint16), K)  # must be metres, float
    with pytest.raises(ValueError):
        depth_to_points(np.zeros((4, 4, 1)), K)
    with pytest.raises(ValueError):
        project(np.eye(4), [0, 0, 1.0])
    with pytest.raises(ValueError):
        project(np.array([[1.0, 0, 0], [0, 1, 0], [0, 0, 2]]), [0, 0, 1.0])
    float32_pts = depth_to_points(np.full((2, 3), 1.5, dtype=np.float32), K)
    np.testing.assert_allclose(float32_pts[..., 2], 1.5)


@pytest.mark.parametrize("Km", [K, K_SKEW], ids=["K", "K_skew"])
def test_projection_jacobian_matches_central_differences(Km: np.ndarray) -> None:
    rng = np.random.default_rng(2)
    p = random_points(rng, 30)
    J = projection_jacobian(Km, p)
    assert J.shape == (30, 2, 3)
    h = 1e-6
    J_fd = np.empty_like(J)
    for i in range(3):
        e = np.zeros(3)
        e[i] = h
        J_fd[:, :, i] = (project(Km, p + e)[0] - project(Km, p - e)[0]) / (2 * h)
    np.testing.assert_allclose(J, J_fd, rtol=1e-7, atol=1e-6)
    # closed form for the diagonal K
    if Km is K:
        x, y, z = p.T
        np.testing.assert_allclose(J[:, 0, 0], INTR.fx / z)
        np.testing.assert_allclose(J[:, 1, 2], -INTR.fy * y / z**2)
        np.testing.assert_array_equal(J[:, 1, 0], 0.0)
    assert projection_jacobian(Km, p.reshape(5, 6, 3)).shape == (5, 6, 2, 3)
