"""A foot's mid point laid from its toe where the leg hides the shoe's back
(gaitnet.pipeline.toe_anchor)."""

from __future__ import annotations

import numpy as np
import pytest

from gaitnet.pipeline.toe_anchor import (
    MIN_STANDING_PAIRS,
    heading_angles,
    toe_anchored_points,
)

FPS = 30.0


def _yaw(psi: float) -> np.ndarray:
    c, s = np.cos(psi), np.sin(psi)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _camera(psi: float, pitch_deg: float) -> np.ndarray:
    """T_WfromC of a camera facing heading ``psi``, pitched ``pitch_deg`` below the horizon
    (x right, y down, z forward in the image)."""
    p = np.radians(pitch_deg)
    forward = np.array([np.cos(p), 0.0, -np.sin(p)])
    down = np.array([-np.sin(p), 0.0, -np.cos(p)])  # image down: towards the body's feet
    right = np.cross(down, forward)
    T = np.eye(4)
    T[:3, :3] = _yaw(psi) @ np.column_stack([right, down, forward])
    T[:3, 3] = [0.0, 0.0, 1.0]
    return T


@pytest.mark.parametrize("pitch_deg", [0.0, 45.0, 70.0, 89.0, 90.0])
def test_the_heading_is_the_cameras_yaw_at_every_pitch(pitch_deg: float) -> None:
    """Known answer: a camera turned to 0.3 rad and pitched down to straight down faces 0.3."""
    T = np.stack([_camera(0.3, pitch_deg)] * 4)
    np.testing.assert_allclose(heading_angles(T, np.arange(4) / FPS, 0.0), 0.3, atol=1e-12)


def test_the_heading_is_averaged_over_the_window() -> None:
    """The pelvis's swing of ±0.1 rad over one stride (1 s) cancels in a 1 s mean; a 0 s
    window keeps it; the angle unwraps across ±π."""
    t = np.arange(120) / FPS
    yaw = np.pi - 0.05 + 0.1 * np.sin(2 * np.pi * t)  # crosses +π
    T = np.stack([_camera(a, 70.0) for a in yaw])
    raw = heading_angles(T, t, 0.0)
    np.testing.assert_allclose(raw, yaw, atol=1e-9)
    mean = heading_angles(T, t, 1.0)
    np.testing.assert_allclose(mean[30:90], np.pi - 0.05, atol=0.01)


def _walk(psi_walk: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Standing 20 frames facing 0, then a walk facing ``psi_walk``; the shoe's toe → mid
    vector is (−0.09, 0, 0.035) in the heading frame for the left foot, (−0.09, 0.01, 0.035)
    for the right. Frames 30–39 show the left shoe's front only (its mid 5 cm ahead)."""
    n = 60
    psi = np.where(np.arange(n) < 20, 0.0, psi_walk)
    d0 = np.array([[-0.09, 0.0, 0.035], [-0.09, 0.01, 0.035]])
    top = np.zeros((n, 2, 3))
    top[:, :, 0] = np.linspace(0, 2, n)[:, None]
    top[:, 1, 1] = -0.2
    mid = np.empty_like(top)
    for k in range(n):
        mid[k] = top[k] + (_yaw(psi[k]) @ d0.T).T
    true_mid = mid.copy()
    along = _yaw(psi_walk) @ np.array([0.05, 0.0, 0.0])
    mid[30:40, 0] += along
    return mid, top, psi, true_mid


def test_a_hidden_back_is_laid_from_the_toe_and_whole_shoes_stay() -> None:
    """Known answer: the ten shortened left shoes get their true mid back, turned with the
    heading (0.4 rad); every other point is returned unchanged."""
    mid, top, psi, true_mid = _walk(0.4)
    out, laid = toe_anchored_points(mid, top, psi, 20, 0.02)
    assert laid == 10
    np.testing.assert_allclose(out[30:40, 0], true_mid[30:40, 0], atol=1e-12)
    keep = np.ones(60, bool)
    keep[30:40] = False
    np.testing.assert_array_equal(out[keep], mid[keep])
    np.testing.assert_array_equal(out[:, 1], mid[:, 1])


def test_the_tolerance_acts() -> None:
    """A 5 cm shortening is laid at a 2 cm tolerance but not at 6 cm."""
    mid, top, psi, _ = _walk(0.0)
    assert toe_anchored_points(mid, top, psi, 20, 0.06)[1] == 0
    assert toe_anchored_points(mid, top, psi, 20, 0.02)[1] == 10


def test_missing_keypoints_and_too_few_standing_frames_leave_points_alone() -> None:
    """A toe without depth (NaN) leaves its mid point; a NaN mid stays NaN; a foot with fewer
    than MIN_STANDING_PAIRS standing frames with both keypoints keeps all its points."""
    mid, top, psi, _ = _walk(0.0)
    top[30:35, 0] = np.nan
    mid[36, 0] = np.nan
    out, laid = toe_anchored_points(mid, top, psi, 20, 0.02)
    assert laid == 4  # 35, 37, 38, 39
    np.testing.assert_array_equal(out[30:35, 0], mid[30:35, 0])
    assert np.isnan(out[36, 0]).all()
    out, laid = toe_anchored_points(mid, top, psi, MIN_STANDING_PAIRS - 1, 0.02)
    assert laid == 0
    np.testing.assert_array_equal(out, mid)


def test_the_config_keys_act_in_infer() -> None:
    """``pipeline.toe_anchor`` lays the points, false (or another ``foot_keypoint``) keeps
    them; ``pipeline.toe_anchor_tolerance_m`` reaches the rule."""
    from types import SimpleNamespace

    from gaitnet.pipeline.config import PipelineParams
    from gaitnet.pipeline.infer import Observations, _toe_anchored

    mid, top, psi, true_mid = _walk(0.0)
    t = np.arange(60) / FPS
    vio = SimpleNamespace(t_s=t, T_WfromC=np.stack([_camera(0.0, 70.0)] * 60))
    obs = Observations(vio, (t * 1e9).astype(np.int64), mid, "x.onnx", toe_W=top)
    out = _toe_anchored(obs, PipelineParams(), 20)
    np.testing.assert_allclose(out[30:40, 0], true_mid[30:40, 0], atol=1e-9)
    for params in (
        PipelineParams(toe_anchor=False),
        PipelineParams(foot_keypoint="top"),
        PipelineParams(toe_anchor_tolerance_m=0.06),
    ):
        np.testing.assert_array_equal(_toe_anchored(obs, params, 20), mid)
