"""HHA: known answers on a ray-cast floor with a box seen by a pitched camera."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gaitnet.errors import InputError
from gaitnet.geometry.floor_plane import FloorPlane
from gaitnet.segmentation.hha import (
    HhaParams,
    hha_decode,
    hha_encode,
    hha_stride,
    surface_normals,
)

W, H, F = 320, 240, 200.0
K = np.array([[F, 0.0, (W - 1) / 2], [0.0, F, (H - 1) / 2], [0.0, 0.0, 1.0]])
HEIGHT_STEP = (1.2 + 0.05) / 254  # one height code [m] (default params)
ANGLE_STEP = 180.0 / 254


def camera(pitch_deg: float, roll_deg: float = 0.0) -> np.ndarray:
    """R_WfromC of a camera pitched down and rolled about its optical axis (world z up)."""
    t, r = math.radians(pitch_deg), math.radians(roll_deg)
    x = np.array([0.0, -1.0, 0.0])
    y = np.array([-math.sin(t), 0.0, -math.cos(t)])
    z = np.array([math.cos(t), 0.0, -math.sin(t)])
    x, y = math.cos(r) * x + math.sin(r) * y, -math.sin(r) * x + math.cos(r) * y
    return np.stack([x, y, z], axis=1)


def scene(
    pitch_deg: float = 60.0,
    roll_deg: float = 0.0,
    cam_h: float = 1.0,
    box: bool = True,
    box_x: float = 1.0,
):
    """Ray-cast depth of the floor z = 0 and a box x ∈ [box_x, box_x + 0.5], |y| ≤ 0.3,
    z ∈ [0, 0.4].

    Depth beyond 6 m is invalid (a sensor's range). Returns depth (float32), R_WfromC, the
    hit's world height and a face id per pixel (0 floor, 1 the box's vertical front face, 2 its
    top, -1 nothing)."""
    R = camera(pitch_deg, roll_deg)
    v, u = np.mgrid[0:H, 0:W].astype(np.float64)
    r = np.stack([(u - K[0, 2]) / F, (v - K[1, 2]) / F, np.ones_like(u)], axis=-1)
    d = r @ R.T  # ray directions in the world; the camera-frame z of a hit is the ray multiple
    best = np.full((H, W), np.inf)
    face = np.full((H, W), -1)
    with np.errstate(divide="ignore", invalid="ignore"):
        candidates = [(0, -cam_h / d[..., 2])]
        if box:
            candidates += [(1, box_x / d[..., 0]), (2, (0.4 - cam_h) / d[..., 2])]
        for fid, s in candidates:
            p = s[..., None] * d + np.array([0.0, 0.0, cam_h])
            ok = np.isfinite(s) & (s > 0)
            if fid == 1:
                ok &= (np.abs(p[..., 1]) <= 0.3) & (p[..., 2] >= 0) & (p[..., 2] <= 0.4)
            if fid == 2:
                ok &= (np.abs(p[..., 1]) <= 0.3) & (p[..., 0] >= box_x) & (p[..., 0] <= box_x + 0.5)
            take = ok & (s < best)
            best[take], face[take] = s[take], fid
    depth = np.where(np.isfinite(best) & (best <= 6.0), best, 0.0).astype(np.float32)
    face[depth == 0] = -1
    world_z = cam_h + depth[..., None] * d
    return depth, R, world_z[..., 2], face


def gravity_C(R: np.ndarray) -> np.ndarray:
    return R.T @ np.array([0.0, 0.0, -1.0])


def interior(mask: np.ndarray, margin: int) -> np.ndarray:
    """``mask`` eroded by ``margin`` pixels (and away from the image border)."""
    import cv2

    k = 2 * margin + 1
    out = cv2.erode(mask.astype(np.uint8), np.ones((k, k), np.uint8)) > 0
    out[:margin], out[-margin:], out[:, :margin], out[:, -margin:] = False, False, False, False
    return out


def test_floor_and_box_known_heights_and_angles() -> None:
    depth, R, height_true, face = scene(60.0)
    assert (face == 1).sum() > 2000 and (face == 0).sum() > 20000  # the scene is as designed
    hha = hha_encode(depth, K, gravity_C(R))
    _, height, angle = hha_decode(hha)
    valid = depth > 0
    # height: the fitted floor is the true one (heights exact to half a code, 0..0.4 m on the box)
    assert np.abs(height - height_true)[valid].max() <= 0.5 * HEIGHT_STEP + 1e-3
    assert np.abs(height[face == 0]).max() <= 0.5 * HEIGHT_STEP + 1e-3
    # angle: floor 0°, the vertical face 90°, away from silhouettes (the normal window)
    floor = interior(face == 0, 8)
    front = interior(face == 1, 8)
    assert np.abs(angle[floor]).max() <= 1.0
    assert np.abs(angle[front] - 90.0).max() <= 1.0
    assert hha[..., 2][front].min() >= 127 and hha[..., 2][front].max() <= 129


@pytest.mark.parametrize(
    ("pitch", "roll", "box_x"), [(40.0, 0.0, 1.0), (75.0, 8.0, 0.5), (20.0, -5.0, 1.0)]
)
def test_without_gravity_the_floor_normal_is_up(pitch: float, roll: float, box_x: float) -> None:
    depth, R, height_true, face = scene(pitch, roll, box_x=box_x)
    with_imu = hha_encode(depth, K, gravity_C(R)).astype(int)
    no_imu = hha_encode(depth, K, None).astype(int)
    assert np.abs(no_imu - with_imu).max() <= 1  # the same up to rounding
    _, height, angle = hha_decode(no_imu.astype(np.uint8))
    assert np.abs(height[face == 0]).max() <= HEIGHT_STEP
    front = interior(face == 1, 8)
    assert front.sum() > 500 and np.abs(angle[front] - 90.0).max() <= 1.0


def test_without_gravity_and_floor_height_and_angle_are_unknown() -> None:
    # a camera pitched 0° (looking at the horizon) sees the floor 60° from the no-IMU prior
    depth, _, _, _ = scene(pitch_deg=5.0, box=False)
    assert (depth > 0).mean() > 0.3
    hha = hha_encode(depth, K, None)
    assert (hha[..., 0][depth > 0] > 0).all()
    assert not hha[..., 1].any() and not hha[..., 2].any()


def test_gravity_without_floor_measures_height_from_the_lowest_points() -> None:
    depth, R, height_true, face = scene(60.0)
    wall = np.where(face == 1, depth, 0.0).astype(np.float32)  # only the vertical face
    params = HhaParams(lowest_point_percentile=0.0)
    _, height, angle = hha_decode(hha_encode(wall, K, gravity_C(R), params), params)
    ok = face == 1
    expected = height_true[ok] - height_true[ok].min()
    assert np.abs(height[ok] - expected).max() <= 0.5 * HEIGHT_STEP + 1e-3
    assert np.abs(angle[interior(ok, 8)] - 90.0).max() <= 1.0


def test_given_plane_is_used_as_it_is() -> None:
    depth, R, height_true, face = scene(60.0)
    g = gravity_C(R)
    plane = FloorPlane(n_C=-g, h=1.0 + 0.1)  # a floor 10 cm lower than the real one
    _, height, _ = hha_decode(hha_encode(depth, K, g, plane=plane))
    valid = depth > 0
    assert np.abs(height - (height_true + 0.1))[valid].max() <= 0.5 * HEIGHT_STEP + 1e-3


def test_disparity_monotone_and_unsaturated_over_the_working_range() -> None:
    z = np.linspace(0.3, 3.0, 1000, dtype=np.float32)
    depth = np.tile(z, (4, 1))
    code = hha_encode(depth, np.eye(3), None)[0, :, 0].astype(int)
    assert code[0] == 255 and code[-1] == 1
    assert (np.diff(code) <= 0).all()  # monotone (farther → smaller)
    near = z <= 1.2  # where the published 31000/z (z ≥ 1 m clamp) is 255 everywhere
    assert len(np.unique(code[near])) > 150
    assert (code[(z > 0.31) & (z < 2.9)] < 255).all() and (code[(z > 0.31) & (z < 2.9)] > 1).all()
    back, _, _ = hha_decode(hha_encode(depth, np.eye(3), None))
    step = (1 / 0.3 - 1 / 3.0) / 254
    assert np.abs(1 / back[0] - 1 / z).max() <= 0.5 * step + 1e-5
    # outside the range: saturated, still valid (never 0)
    far = hha_encode(np.full((3, 3), 10.0, np.float32), np.eye(3), None)[..., 0]
    close = hha_encode(np.full((3, 3), 0.1, np.float32), np.eye(3), None)[..., 0]
    assert (far == 1).all() and (close == 255).all()


def test_invalid_depth_is_zero_in_every_channel() -> None:
    depth, R, _, _ = scene(60.0)
    rng = np.random.default_rng(0)
    holes = rng.random(depth.shape) < 0.05
    depth[holes] = 0.0
    depth[rng.random(depth.shape) < 0.01] = np.nan
    depth[5, 5] = -1.0
    bad = ~(np.isfinite(depth) & (depth > 0))
    hha = hha_encode(depth, K, gravity_C(R))
    assert not hha[bad].any()
    assert (hha[~bad][:, :2] > 0).all()  # valid pixels keep disparity and height
    assert (hha[~bad][:, 2] > 0).mean() > 0.99  # and nearly all an angle
    assert not hha_encode(np.zeros((8, 8), np.float32), K, None).any()


def test_normals_point_towards_the_camera() -> None:
    depth, R, _, face = scene(60.0)
    n = surface_normals(depth, K)
    up_C = -gravity_C(R)
    floor = interior(face == 0, 8)
    assert np.allclose(n[floor], up_C, atol=0.01)
    back_C = R.T @ np.array([-1.0, 0.0, 0.0])  # the box's front face looks back at the camera
    assert np.allclose(n[interior(face == 1, 8)], back_C, atol=0.01)


def test_bad_inputs_and_params() -> None:
    with pytest.raises(InputError, match="depth"):
        hha_encode(np.zeros((4, 4, 3), np.float32), K)
    with pytest.raises(InputError, match="float metres"):
        hha_encode(np.zeros((4, 4), np.uint16), K)
    with pytest.raises(InputError, match="gravity"):
        hha_encode(np.ones((4, 4), np.float32), K, np.array([0.0, np.nan, 1.0]))
    with pytest.raises(InputError, match="K must"):
        hha_encode(np.ones((4, 4), np.float32), np.zeros((3, 3)))
    with pytest.raises(ValueError, match="normal_window_px"):
        HhaParams(normal_window_px=4)
    with pytest.raises(ValueError, match="max_depth_m"):
        HhaParams(min_depth_m=2.0, max_depth_m=1.0)
    assert HhaParams().fingerprint() != HhaParams(max_depth_m=4.0).fingerprint()
    assert HhaParams().fingerprint() == HhaParams().fingerprint()


def test_every_setting_acts() -> None:
    depth, R, _, face = scene(60.0)
    g = gravity_C(R)
    noisy = depth * (1 + np.random.default_rng(1).normal(0, 0.004, depth.shape)).astype(np.float32)
    base = hha_encode(noisy, K, g)

    def changed(**kw) -> np.ndarray:
        return hha_encode(noisy, K, g, HhaParams(**kw)) != base

    assert changed(min_depth_m=0.5)[..., 0].any() and changed(max_depth_m=5.0)[..., 0].any()
    assert changed(min_height_m=-0.2)[..., 1].any() and changed(max_height_m=2.0)[..., 1].any()
    floor = interior(face == 0, 12)

    def floor_angle_spread(**kw) -> float:
        _, _, angle = hha_decode(hha_encode(noisy, K, g, HhaParams(**kw)))
        return float(np.nanstd(angle[floor]))

    # wider windows and baselines average the depth noise away
    assert floor_angle_spread(normal_window_px=15) < floor_angle_spread(normal_window_px=3)
    assert floor_angle_spread(normal_step_px=5) < floor_angle_spread(normal_step_px=1)
    # differences across the box's silhouette are kept with a loose jump limit
    assert changed(max_depth_jump=1.0)[..., 2][face == 1].any()
    # the floor fit's settings reach the fit (an impossible inlier count: no floor found)
    from gaitnet.geometry.floor_plane import FloorParams

    assert changed(floor=FloorParams(min_inliers=10**6))[..., 1].any()
    # without gravity: the prior's pitch and cone decide whether a level camera finds its floor
    level, _, _, _ = scene(pitch_deg=5.0, box=False)
    assert not hha_encode(level, K, None)[..., 1].any()
    assert hha_encode(level, K, None, HhaParams(no_imu_pitch_deg=10.0))[..., 1].any()
    assert hha_encode(level, K, None, HhaParams(no_imu_max_angle_deg=80.0))[..., 1].any()
    # the lowest-point percentile (gravity but no floor)
    wall = np.where(face == 1, depth, 0.0).astype(np.float32)
    a = hha_encode(wall, K, g, HhaParams(lowest_point_percentile=0.0))
    b = hha_encode(wall, K, g, HhaParams(lowest_point_percentile=20.0))
    assert (a[..., 1] != b[..., 1]).any()


def test_stride_encodes_the_sampled_grid_and_repeats_it() -> None:
    """Stride 2 is the encoding of every other pixel (with K and the normal window scaled),
    each code repeated over its 2 × 2 block; on the ray-cast scene its heights and angles are
    still the true ones."""
    depth, R, height_true, face = scene(60.0)
    g = gravity_C(R)
    params = HhaParams()
    strided = hha_encode(depth, K, g, params, stride=2)
    assert strided.shape == (H, W, 3) and strided.dtype == np.uint8
    K_half = K.copy()
    K_half[:2] /= 2
    half_params = HhaParams(normal_step_px=2, normal_window_px=5)  # 3 / 2 → 2, 9 / 2 → 5
    direct = hha_encode(depth[::2, ::2], K_half, g, half_params)
    for dv in (0, 1):
        for du in (0, 1):
            assert np.array_equal(strided[dv::2, du::2], direct)
    _, height, angle = hha_decode(strided[::2, ::2])  # at the pixels sampled
    valid = depth[::2, ::2] > 0
    assert np.abs(height - height_true[::2, ::2])[valid].max() <= 0.5 * HEIGHT_STEP + 1e-3
    assert np.abs(angle[interior(face[::2, ::2] == 0, 6)]).max() <= 1.0
    assert np.abs(angle[interior(face[::2, ::2] == 1, 6)] - 90.0).max() <= 1.0
    # an odd size keeps its shape (the last row and column are their block's first)
    odd = hha_encode(depth[:-1, :-1], K, g, params, stride=2)
    assert odd.shape == (H - 1, W - 1, 3)
    assert np.array_equal(odd, strided[:-1, :-1])
    assert np.array_equal(hha_encode(depth, K, g, params, stride=1), hha_encode(depth, K, g))


def test_hha_stride_follows_the_model_input_scale() -> None:
    assert [hha_stride(s) for s in (1.0, 0.75, 0.5, 0.4, 1 / 3, 0.25)] == [1, 1, 2, 2, 3, 4]
    for bad in (0.0, 1.5, float("nan"), "0.5"):
        with pytest.raises(InputError, match="input_scale"):
            hha_stride(bad)  # type: ignore[arg-type]
    depth, R, _, _ = scene(60.0)
    for bad_stride in (0, -1, 1.5, True):
        with pytest.raises(InputError, match="stride"):
            hha_encode(depth, K, gravity_C(R), stride=bad_stride)  # type: ignore[arg-type]
