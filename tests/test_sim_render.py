"""Realistic renderer, procedural floors and the D455 sensor model."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from gaitnet.geometry import make_T, so3_exp
from gaitnet.io.types import AprilTagBoard, tag_corners_in_board
from gaitnet.sim.clutter import ClutterBox
from gaitnet.sim.floor import (
    FLOOR_FAMILIES,
    make_floor,
)
from gaitnet.sim.render import Lighting, render_frame
from gaitnet.sim.render_color import encode_srgb8
from gaitnet.sim.render_prims import leg_sdf, shoe_sdf
from gaitnet.sim.scene import (
    INSTANCE_LEFT,
    INSTANCE_RIGHT,
    LABEL_FOOT,
    LABEL_LEG,
    Appearance,
    BodyState,
    LegSegment,
    ShoeState,
)
from gaitnet.sim.sensor_model import SensorNoiseConfig, apply_sensor

R_PfromC_LEVEL = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
APPEARANCE = Appearance((0.05, 0.08, 0.2), (0.5, 0.05, 0.04), (0.8, 0.8, 0.78))
NO_BODY = BodyState((), ())
QUIET = SensorNoiseConfig(dropout_fraction=0.0, blob_fraction=0.0, flying_fraction=0.0)


def K_of(width: int, height: int, f: float) -> np.ndarray:
    return np.array([[f, 0.0, (width - 1) / 2], [0.0, f, (height - 1) / 2], [0.0, 0.0, 1.0]])


def camera(p, pitch_deg: float, yaw: float = 0.0) -> np.ndarray:
    """Camera looking along world +x (rotated by ``yaw``), pitched down by ``pitch_deg``."""
    R = so3_exp([0.0, 0.0, yaw]) @ so3_exp([0.0, np.deg2rad(pitch_deg), 0.0]) @ R_PfromC_LEVEL
    return make_T(R, np.asarray(p, float))


def shoe(side: str, xy, yaw: float = 0.0, toe_down: float = 0.0) -> ShoeState:
    R = so3_exp([0.0, 0.0, yaw]) @ so3_exp([0.0, toe_down, 0.0])
    c = np.array([xy[0], xy[1], 0.5 * 0.28 * abs(np.sin(toe_down))])
    return ShoeState(side, R, c, 0.28, 0.10, 0.085)


@pytest.fixture(scope="module")
def plain_floor():
    return make_floor("concrete", np.random.default_rng(0), ((-1.0, 3.0), (-1.5, 1.5)),
                      texel_m=0.005, room_height_m=None)  # fmt: skip


def points_W(res, K: np.ndarray, T_WfromC: np.ndarray, mask: np.ndarray) -> np.ndarray:
    v, u = np.nonzero(mask)
    z = res.depth_m[v, u].astype(np.float64)
    p_C = np.stack([(u - K[0, 2]) / K[0, 0] * z, (v - K[1, 2]) / K[1, 1] * z, z], axis=1)
    return p_C @ T_WfromC[:3, :3].T + T_WfromC[:3, 3]


# ----------------------------------------------------------------------------- geometry


def test_floor_only_depth_is_the_analytic_plane_depth(plain_floor):
    w, h = 160, 120
    K = K_of(w, h, 96.0)
    T = camera((0.0, 0.0, 1.0), 55.0)
    res = render_frame(K, w, h, T, plain_floor, NO_BODY, APPEARANCE)
    v, u = np.mgrid[0:h, 0:w].astype(np.float64)
    d_W = (
        np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones_like(u)], -1)
        @ T[:3, :3].T
    )
    with np.errstate(divide="ignore"):
        expected = np.where(d_W[..., 2] < 0, -1.0 / d_W[..., 2], np.inf)
    assert np.isfinite(expected).mean() > 0.9
    assert np.array_equal(np.isfinite(res.depth_m), np.isfinite(expected))
    finite = np.isfinite(expected)
    assert np.abs(res.depth_m[finite] - expected[finite]).max() < 1e-5
    assert not res.label.any() and not res.instance.any()
    assert res.rgb_linear.dtype == np.float32 and np.isfinite(res.rgb_linear).all()


def test_shoe_and_leg_pixels_lie_on_their_surfaces(plain_floor):
    w, h = 320, 240
    K = K_of(w, h, 192.0)
    T = camera((0.0, 0.0, 1.0), 55.0)
    left = shoe("left", (0.7, 0.12), yaw=0.3)
    right = shoe("right", (0.6, -0.15), yaw=-0.2, toe_down=0.35)
    leg = LegSegment("right", "shank", np.array([0.9, -0.25, 0.55]), np.array([0.85, -0.3, 0.12]),
                     0.06, 0.045)  # fmt: skip
    res = render_frame(K, w, h, T, plain_floor, BodyState((leg,), (left, right)), APPEARANCE)
    foot, legm = res.label == LABEL_FOOT, res.label == LABEL_LEG
    assert foot.sum() > 300 and legm.sum() > 300
    p = points_W(res, K, T, foot)
    d = np.minimum(shoe_sdf(left, p), shoe_sdf(right, p))
    assert np.abs(d).max() < 1e-3
    assert np.abs(leg_sdf(leg, points_W(res, K, T, legm))).max() < 1e-3
    # Pixels near each primitive's projected centre carry its label and side.
    for centre_W, label, inst in (
        (left.p_SoleCentre_W + [0.0, 0.0, 0.06], LABEL_FOOT, INSTANCE_LEFT),
        (right.R_WfromShoe @ [0.0, 0.0, 0.06] + right.p_SoleCentre_W, LABEL_FOOT, INSTANCE_RIGHT),
        ((leg.p_top_W + leg.p_bottom_W) / 2, LABEL_LEG, INSTANCE_RIGHT),
    ):
        p_C = np.linalg.inv(T)[:3] @ np.append(centre_W, 1.0)
        u, v = np.round((K @ p_C)[:2] / p_C[2]).astype(int)
        assert res.label[v, u] == label and res.instance[v, u] == inst
    # Instances exactly where labels are, and labelled pixels are in front of the floor.
    assert np.array_equal(res.label > 0, res.instance > 0)
    floor_only = render_frame(K, w, h, T, plain_floor, NO_BODY, APPEARANCE)
    assert (res.depth_m[res.label > 0] < floor_only.depth_m[res.label > 0]).all()
    assert np.array_equal(res.depth_m[res.label == 0], floor_only.depth_m[res.label == 0])


def test_leg_in_front_occludes_shoe_and_primitives_behind_camera_are_clipped(plain_floor):
    w, h = 160, 120
    K = K_of(w, h, 96.0)
    T = camera((0.0, 0.0, 1.0), 55.0)
    target = shoe("left", (0.7, 0.0))
    alone = render_frame(K, w, h, T, plain_floor, BodyState((), (target,)), APPEARANCE)
    # A thigh from behind the camera (partly at z < 0) to a knee on the line of sight.
    p_knee = T[:3, 3] + 0.5 * (np.array([0.7, 0.0, 0.05]) - T[:3, 3])
    thigh = LegSegment("right", "thigh", np.array([-0.1, 0.0, 0.95]), p_knee, 0.07, 0.06)
    both = render_frame(K, w, h, T, plain_floor, BodyState((thigh,), (target,)), APPEARANCE)
    was_shoe = alone.label == LABEL_FOOT
    hidden = was_shoe & (both.label == LABEL_LEG)
    assert hidden.sum() > 0.3 * was_shoe.sum()
    assert (both.depth_m[hidden] < alone.depth_m[hidden]).all()
    assert (both.instance[hidden] == INSTANCE_RIGHT).all()
    assert np.abs(leg_sdf(thigh, points_W(both, K, T, both.label == LABEL_LEG))).max() < 1e-3
    # A segment entirely behind the camera draws nothing.
    behind = LegSegment("left", "thigh", np.array([-0.5, 0.0, 1.0]), np.array([-0.6, 0.0, 0.5]),
                        0.07, 0.06)  # fmt: skip
    res = render_frame(K, w, h, T, plain_floor, BodyState((behind,), ()), APPEARANCE)
    assert not res.label.any()


def test_antialiasing_changes_only_edge_colours_and_normals_face_the_camera(plain_floor):
    w, h = 160, 120
    K = K_of(w, h, 96.0)
    T = camera((0.0, 0.0, 1.0), 55.0)
    leg = LegSegment("left", "shank", np.array([0.75, 0.2, 0.5]), np.array([0.7, 0.12, 0.1]),
                     0.055, 0.045)  # fmt: skip
    body = BodyState((leg,), (shoe("left", (0.7, 0.12)), shoe("right", (0.6, -0.1))))
    a = render_frame(K, w, h, T, plain_floor, body, APPEARANCE, return_normals=True)
    b = render_frame(K, w, h, T, plain_floor, body, APPEARANCE, antialias=False)
    for name in ("depth_m", "label", "instance"):
        assert np.array_equal(getattr(a, name), getattr(b, name))
    changed = np.abs(a.rgb_linear - b.rgb_linear).max(axis=-1) > 0
    assert changed.any()
    near_edge = cv2.dilate((cv2.Laplacian(a.label, cv2.CV_16S) != 0).astype(np.uint8), None)
    near_edge |= cv2.dilate((cv2.Laplacian(a.depth_m, cv2.CV_32F) > 0.02).astype(np.uint8), None)
    assert not (changed & (near_edge == 0) & (a.label != LABEL_FOOT)).any()  # shoes: sole/upper
    n = a.normals[a.label > 0]
    assert np.allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-4)
    v, u = np.nonzero(a.label > 0)
    rays = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones(u.size)], axis=1)
    assert ((n * rays).sum(axis=1) < 0).all()


def test_apriltag_sheet_is_detected_where_the_board_says():
    T_WfromBoard = make_T(so3_exp([0.0, 0.0, 0.2]), np.array([0.45, -0.12, 0.0]))
    board = AprilTagBoard("b", "tag36h11", 5, 7, 0.045, 0.013, 10, T_WfromBoard)
    floor = make_floor("wood", np.random.default_rng(1), ((-1.0, 2.0), (-1.0, 1.0)),
                       boards=(board,), room_height_m=None)  # fmt: skip
    w, h = 640, 480
    K = K_of(w, h, 385.0)
    T = camera((0.6, 0.05, 0.55), 85.0, yaw=0.1)
    res = render_frame(K, w, h, T, floor, NO_BODY, APPEARANCE, light=Lighting())
    img = encode_srgb8(res.rgb_linear * (0.4 / res.rgb_linear.mean()))
    gray = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY)
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11)
    corners, ids, _ = cv2.aruco.ArucoDetector(dictionary).detectMarkers(gray)
    assert ids is not None
    ids = ids.ravel().tolist()
    assert set(ids) <= set(range(10, 45)) and len(ids) >= 30
    T_CfromW = np.linalg.inv(T)
    for tag_id, c in zip(ids, corners, strict=True):
        p_W = tag_corners_in_board(board, tag_id) @ T_WfromBoard[:3, :3].T + T_WfromBoard[:3, 3]
        p_C = p_W @ T_CfromW[:3, :3].T + T_CfromW[:3, 3]
        uv = (p_C @ K.T)[:, :2] / p_C[:, 2:]
        assert np.abs(uv - c.reshape(4, 2)).max() < 1.5, tag_id


# ----------------------------------------------------------------------------- sensor


def test_depth_noise_grows_with_distance_squared(plain_floor):
    w, h = 200, 150
    K = K_of(w, h, 120.0)
    stds = []
    for z in (1.0, 2.0):
        res = render_frame(K, w, h, camera((1.0, 0.0, z), 89.999), plain_floor, NO_BODY, APPEARANCE)
        _, depth = apply_sensor(res, K, np.random.default_rng(5), QUIET, 1.0)
        valid = depth > 0
        assert valid.mean() > 0.98
        stds.append(float((depth[valid] - res.depth_m[valid]).std()))
    expected_1m = 1.0 * QUIET.disparity_noise_px / (120.0 * QUIET.baseline_m)
    assert stds[0] == pytest.approx(expected_1m, rel=0.2)
    assert 3.0 < stds[1] / stds[0] < 5.3


def test_depth_invalid_below_min_range_at_edges_and_in_occlusion_shadow(plain_floor):
    w, h = 160, 120
    K = K_of(w, h, 96.0)
    res = render_frame(K, w, h, camera((1.0, 0.0, 0.3), 89.999), plain_floor, NO_BODY, APPEARANCE)
    _, depth = apply_sensor(res, K, np.random.default_rng(0), QUIET, 1.0)
    assert not depth.any()
    # Looking down from 1 m at a 0.5 m tall box: its top at 0.5 m, the floor at 1 m.
    box = ClutterBox((1.0, 0.0), 0.0, (0.3, 0.3, 0.5), (0.5, 0.5, 0.5))
    res = render_frame(K, w, h, camera((1.0, 0.0, 1.0), 89.999), plain_floor, NO_BODY,
                       APPEARANCE, clutter=(box,))  # fmt: skip
    _, depth = apply_sensor(res, K, np.random.default_rng(0), QUIET, 1.0)
    top = res.depth_m < 0.75
    rows = np.flatnonzero(top.any(axis=1))[3:-3]
    assert rows.size > 20
    u_left = np.array([np.flatnonzero(top[r])[0] for r in rows])
    u_right = np.array([np.flatnonzero(top[r])[-1] for r in rows])
    assert not depth[rows, u_left].any() and not depth[rows, u_left - 1].any()  # the edge
    # Disparity step f·b·(1/0.5 − 1/1) ≈ 9 px: a band left of the box is invisible to the
    # right imager; right of the box the floor stays valid.
    band = np.stack([depth[rows, u_left - k] for k in range(3, 8)])
    beyond = np.stack([depth[rows, u_right + k] for k in range(3, 8)])
    assert (band == 0).mean() > 0.95
    assert (beyond > 0).mean() > 0.95
    assert (depth[~top & (res.depth_m > 0.9)] > 0).mean() > 0.8


def test_sensor_output_types_and_determinism(plain_floor):
    w, h = 160, 120
    K = K_of(w, h, 96.0)
    body = BodyState((), (shoe("left", (0.7, 0.1)), shoe("right", (0.6, -0.1))))
    res = render_frame(K, w, h, camera((0.0, 0.0, 1.0), 55.0), plain_floor, body, APPEARANCE)
    a = apply_sensor(res, K, np.random.default_rng(3), SensorNoiseConfig(), 2.0)
    b = apply_sensor(res, K, np.random.default_rng(3), SensorNoiseConfig(), 2.0)
    c = apply_sensor(res, K, np.random.default_rng(4), SensorNoiseConfig(), 2.0)
    assert a[0].dtype == np.uint8 and a[0].shape == (h, w, 3)
    assert a[1].dtype == np.float32 and a[1].shape == (h, w)
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
    assert not np.array_equal(a[0], c[0]) and not np.array_equal(a[1], c[1])
    assert 20 < a[0].mean() < 235


# ----------------------------------------------------------------------------- textures


def _gradient_energy(img: np.ndarray) -> float:
    g = cv2.cvtColor(img, cv2.COLOR_RGBA2GRAY).astype(np.float64)
    return float(np.mean(np.abs(np.diff(g, axis=0))) + np.mean(np.abs(np.diff(g, axis=1))))


@pytest.mark.parametrize("family", FLOOR_FAMILIES)
def test_each_floor_family_renders_and_depends_on_the_rng(family):
    extent = ((0.0, 1.5), (0.0, 1.0))
    a = make_floor(family, np.random.default_rng(1), extent, room_height_m=None)
    b = make_floor(family, np.random.default_rng(2), extent, room_height_m=None)
    assert a.levels[0].shape == (400, 600, 4) and a.levels[0].dtype == np.uint8
    assert not np.array_equal(a.levels[0], b.levels[0])
    # 400 rows are two bands of texels: generated on two threads, the same texture
    threaded = make_floor(family, np.random.default_rng(1), extent, room_height_m=None, threads=2)
    for level, same in zip(a.levels, threaded.levels, strict=True):
        np.testing.assert_array_equal(level, same)
    w, h = 160, 120
    K = K_of(w, h, 96.0)
    res = render_frame(K, w, h, camera((0.0, 0.0, 1.0), 55.0), a, NO_BODY, APPEARANCE)
    assert np.isfinite(res.rgb_linear).all() and res.rgb_linear.min() >= 0


def test_textureless_floor_has_much_less_gradient_energy_than_tiles():
    extent = ((0.0, 2.0), (0.0, 2.0))
    energies = {
        fam: _gradient_energy(make_floor(fam, np.random.default_rng(7), extent).levels[1])
        for fam in ("tiles", "textureless")
    }
    assert energies["textureless"] < 0.25 * energies["tiles"]
