"""Visual odometry (gaitnet.vio.odometry): known motions on rendered RGB-D frames of a floor."""

from __future__ import annotations

import math

import cv2 as cv
import numpy as np
import pytest

from gaitnet.errors import InputError
from gaitnet.geometry.rotation import so3_exp, so3_log
from gaitnet.io.types import Frame
from gaitnet.vio.odometry import (
    FrameOdometry,
    OdometryParams,
    VoResult,
    covariance_from_information,
    motion_floor,
)
from gaitnet.vio.odometry_pose import pose_information, reprojection_residuals

W, H, F = 320, 240, 193.0
K = np.array([[F, 0.0, (W - 1) / 2], [0.0, F, (H - 1) / 2], [0.0, 0.0, 1.0]])
TEXEL_M = 0.004
TEX_N = 1000  # texture covers 4 m × 4 m, centred on the world origin


def texture(seed: int, contrast: float = 1.0) -> np.ndarray:
    """Random floor texture: noise smoothed at three scales, grey 128 ± contrast × ~60."""
    rng = np.random.default_rng(seed)
    t = np.zeros((TEX_N, TEX_N), np.float32)
    for sigma, weight in ((1.5, 1.0), (4.0, 1.5), (12.0, 2.0)):
        n = cv.GaussianBlur(rng.normal(size=(TEX_N, TEX_N)).astype(np.float32), (0, 0), sigma)
        t += weight * n / n.std()
    t = 128.0 + contrast * 60.0 * t / t.std()
    return np.clip(t, 0, 255).astype(np.float32)


def camera_pose(
    x: float, y: float, z: float, yaw: float = 0.0, pitch_deg: float = 70.0
) -> np.ndarray:
    """``T_WfromC`` of a camera at (x, y, z) facing +x (then yawed), pitched down at the floor."""
    p = math.radians(pitch_deg)
    z_C = np.array([math.cos(p), 0.0, -math.sin(p)])
    x_C = np.array([0.0, -1.0, 0.0])
    y_C = np.cross(z_C, x_C)
    T = np.eye(4)
    T[:3, :3] = so3_exp(np.array([0.0, 0.0, yaw])) @ np.stack([x_C, y_C, z_C], axis=1)
    T[:3, 3] = [x, y, z]
    return T


def render(T_WfromC: np.ndarray, tex: np.ndarray, noise_seed: int) -> Frame:
    """RGB-D frame of the floor z = 0 (``tex`` on it) seen from ``T_WfromC``; grey noise 1 level."""
    u, v = np.meshgrid(np.arange(W, dtype=np.float64), np.arange(H, dtype=np.float64))
    d_C = np.stack([(u - K[0, 2]) / F, (v - K[1, 2]) / F, np.ones_like(u)], axis=-1)
    d_W = d_C @ T_WfromC[:3, :3].T
    s = -T_WfromC[2, 3] / d_W[..., 2]  # ray parameter = depth (d_C has z = 1)
    X = T_WfromC[:3, 3] + s[..., None] * d_W
    map_x = (X[..., 0] / TEXEL_M + TEX_N / 2).astype(np.float32)
    map_y = (X[..., 1] / TEXEL_M + TEX_N / 2).astype(np.float32)
    grey = cv.remap(tex, map_x, map_y, cv.INTER_LINEAR, borderMode=cv.BORDER_REFLECT)
    grey += np.random.default_rng(noise_seed).normal(0.0, 1.0, grey.shape).astype(np.float32)
    rgb = np.repeat(np.clip(grey, 0, 255).astype(np.uint8)[..., None], 3, axis=2)
    depth = np.where((s > 0) & (s < 6), s, 0.0).astype(np.float32)
    return Frame(index=noise_seed, t_ns=noise_seed, rgb=rgb, depth_m=depth)


def pair(contrast: float = 1.0, seed: int = 0):
    """Two frames 38 mm and ~1.2° apart (walking speed at 30 Hz) and the true T_CkfromCk1."""
    tex = texture(seed, contrast)
    T1 = camera_pose(0.0, 0.0, 1.0)
    T2 = camera_pose(0.038, 0.004, 1.003, yaw=math.radians(0.8), pitch_deg=70.9)
    T_true = np.linalg.inv(T2) @ T1
    return render(T1, tex, 1), render(T2, tex, 2), T_true


def perturb(T: np.ndarray, mm: float, deg: float, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    a, b = rng.normal(size=3), rng.normal(size=3)
    G = T.copy()
    G[:3, :3] = so3_exp(math.radians(deg) * a / np.linalg.norm(a)) @ T[:3, :3]
    G[:3, 3] += 1e-3 * mm * b / np.linalg.norm(b)
    return G


def errors(res: VoResult, T_true: np.ndarray) -> tuple[float, float]:
    """Translation error [mm], rotation error [°]."""
    e_t = 1e3 * np.linalg.norm(res.t - T_true[:3, 3])
    e_r = math.degrees(np.linalg.norm(so3_log(T_true[:3, :3] @ res.R.T)))
    return float(e_t), float(e_r)


@pytest.fixture(scope="module")
def textured_pair():
    return pair()


@pytest.mark.parametrize("guess", ["imu", "identity"])
def test_known_motion_of_textured_floor(textured_pair, guess):
    prev, cur, T_true = textured_pair
    T_guess = perturb(T_true, 5.0, 0.5, 3) if guess == "imu" else np.eye(4)
    res = FrameOdometry().estimate(prev, cur, K, T_guess)
    assert res.ok, res.reason
    e_t, e_r = errors(res, T_true)
    assert e_t < 2.0 and e_r < 0.1, (e_t, e_r)
    assert res.n_inliers >= 50
    assert res.residual < 1.0
    # p_Ck = R p_Ck-1 + t convention: a floor point seen in prev lands where cur sees it.
    assert np.allclose(res.R @ res.R.T, np.eye(3), atol=1e-9)
    # Covariance: symmetric positive definite, and the actual error within ~4 sigma per axis.
    assert np.allclose(res.cov6, res.cov6.T)
    assert np.all(np.linalg.eigvalsh(res.cov6) > 0)
    e = np.concatenate([so3_log(T_true[:3, :3] @ res.R.T), T_true[:3, 3] - res.t])
    assert np.all(np.abs(e) < 4.0 * np.sqrt(np.diag(res.cov6)) + 1e-4)


def test_half_resolution_is_accurate(textured_pair):
    prev, cur, T_true = textured_pair
    res = FrameOdometry(OdometryParams(scale=0.5)).estimate(
        prev, cur, K, perturb(T_true, 5, 0.5, 4)
    )
    assert res.ok, res.reason
    e_t, e_r = errors(res, T_true)
    assert e_t < 3.0 and e_r < 0.15, (e_t, e_r)


def test_independently_moving_object_is_rejected(textured_pair):
    """A textured box (like a shoe) moving 6 cm on its own over 20 % of the image."""
    prev, cur, T_true = textured_pair
    rng = np.random.default_rng(7)
    patch = cv.GaussianBlur(rng.uniform(0, 255, (90, 120)).astype(np.float32), (0, 0), 1.5)
    patch = np.clip(128 + 3 * (patch - patch.mean()), 0, 255).astype(np.uint8)
    frames = []
    for frame, (r0, c0) in ((prev, (120, 60)), (cur, (132, 80))):
        rgb, depth = frame.rgb.copy(), frame.depth_m.copy()
        rgb[r0 : r0 + 90, c0 : c0 + 120] = patch[..., None]
        depth[r0 : r0 + 90, c0 : c0 + 120] = 0.7
        frames.append(Frame(frame.index, frame.t_ns, rgb, depth))
    res = FrameOdometry().estimate(frames[0], frames[1], K, perturb(T_true, 5, 0.5, 5))
    assert res.ok, res.reason
    e_t, e_r = errors(res, T_true)
    assert e_t < 2.0 and e_r < 0.1, (e_t, e_r)


@pytest.mark.parametrize("contrast", [0.0, 0.003])
def test_textureless_floor_fails(contrast):
    """Only sensor noise (1 grey level) on the floor: seeded tracks would stay at the guess,
    so the result must not come back as a measurement."""
    prev, cur, T_true = pair(contrast=contrast, seed=1)
    # 320×240 is already small; no motion floor: it is the same for both textures
    params = OdometryParams(scale=1.0, image_noise_grey=1.0, motion_std=0.0)
    res = FrameOdometry(params).estimate(prev, cur, K, perturb(T_true, 5, 0.5, 6))
    assert not res.ok
    assert "textured" in res.reason
    assert np.all(np.isinf(res.cov6))


def test_faint_texture_is_uncertain_but_consistent():
    """Texture barely above the noise (few corners pass the texture test): the result's
    error stays inside its covariance (3 sigma of the translation), and that covariance is
    much larger than on a well-textured floor."""
    prev, cur, T_true = pair(contrast=0.03, seed=1)
    # 320×240 is already small; no motion floor: it is the same for both textures
    params = OdometryParams(scale=1.0, image_noise_grey=1.0, motion_std=0.0)
    T_guess = perturb(T_true, 5, 0.5, 6)
    res = FrameOdometry(params).estimate(prev, cur, K, T_guess)
    assert res.ok, res.reason
    e_t, _ = errors(res, T_true)
    assert e_t < 3e3 * math.sqrt(np.trace(res.cov6[3:, 3:]))
    prev2, cur2, T_true2 = pair(contrast=1.0, seed=1)
    sharp = FrameOdometry(params).estimate(prev2, cur2, K, perturb(T_true2, 5, 0.5, 6))
    assert sharp.ok and sharp.n_inliers > 2 * res.n_inliers
    assert np.trace(res.cov6[3:, 3:]) > 3 * np.trace(sharp.cov6[3:, 3:])


def test_no_valid_depth_fails_with_reason(textured_pair):
    prev, cur, T_true = textured_pair
    blind = Frame(prev.index, prev.t_ns, prev.rgb, np.zeros_like(prev.depth_m))
    res = FrameOdometry().estimate(blind, cur, K, T_true)
    assert not res.ok
    assert "depth" in res.reason
    assert np.allclose(res.t, T_true[:3, 3])  # the guess comes back, flagged


def test_guess_far_from_truth_is_rejected(textured_pair):
    prev, cur, T_true = textured_pair
    T_bad = T_true.copy()
    T_bad[:3, 3] += [0.12, -0.08, 0.05]
    res = FrameOdometry().estimate(prev, cur, K, T_bad)
    assert not res.ok
    assert res.reason


def test_result_far_from_guess_is_implausible(textured_pair):
    """Tracking from the identity finds the true 38 mm motion; a 20 mm gate rejects it."""
    prev, cur, _ = textured_pair
    params = OdometryParams(max_guess_translation_m=0.02)
    res = FrameOdometry(params).estimate(prev, cur, K, np.eye(4))
    assert not res.ok
    assert res.reason.startswith("implausible")


def test_frames_of_different_size_raise(textured_pair):
    prev, cur, _ = textured_pair
    small = Frame(cur.index, cur.t_ns, cur.rgb[:-2], cur.depth_m[:-2])
    with pytest.raises(InputError, match="differ in size"):
        FrameOdometry().estimate(prev, small, K, np.eye(4))
    bad_depth = Frame(cur.index, cur.t_ns, cur.rgb, cur.depth_m[:-2])
    with pytest.raises(InputError, match="depth"):
        FrameOdometry().estimate(prev, bad_depth, K, np.eye(4))
    with pytest.raises(InputError, match="rigid"):
        FrameOdometry().estimate(prev, cur, K, np.diag([2.0, 1.0, 1.0, 1.0]))


def test_pose_information_matches_finite_differences():
    """JᵀJ from the analytic Jacobian equals the one from central differences of the
    reprojection residuals through R = exp([dφ]x) R̂, t = t̂ + dt."""
    rng = np.random.default_rng(0)
    p = np.column_stack([rng.uniform(-0.5, 0.5, (20, 2)), rng.uniform(0.8, 2.0, 20)])
    R = so3_exp(rng.normal(scale=0.05, size=3))
    t = rng.normal(scale=0.03, size=3)
    uv = np.zeros((20, 2))
    eps = 1e-6
    J = np.zeros((40, 6))
    for k in range(6):
        d = np.zeros(6)
        d[k] = eps
        rp = reprojection_residuals(K, so3_exp(d[:3]) @ R, t + d[3:], p, uv)
        rm = reprojection_residuals(K, so3_exp(-d[:3]) @ R, t - d[3:], p, uv)
        J[:, k] = -(rp - rm).reshape(-1) / (2 * eps)  # residual = measured − predicted
    info = pose_information(K, R, t, p)
    assert np.allclose(info, J.T @ J, rtol=1e-5, atol=1e-6 * np.abs(info).max())


def test_weak_direction_is_inflated():
    rng = np.random.default_rng(1)
    A = rng.normal(size=(6, 6))
    info = A @ A.T * 1e6
    cov, n_weak = covariance_from_information(info, 1.0, 0.05, 1.0)
    assert n_weak == 0 and np.allclose(cov, np.linalg.inv(info))
    v = np.zeros(6)
    v[3] = 1.0  # x translation unconstrained
    P = np.eye(6) - np.outer(v, v)
    cov, n_weak = covariance_from_information(P @ info @ P, 1.0, 0.05, 1.0)
    assert n_weak == 1
    assert cov[3, 3] == pytest.approx(1.0)
    assert np.all(np.delete(np.diag(cov), 3) < 1e-4)


def test_common_shift_information_matches_dense_inverse():
    """The Woodbury form equals Jᵀ Σ⁻¹ J with the full 2n×2n pixel covariance."""
    rng = np.random.default_rng(2)
    n = 12
    p = np.column_stack([rng.uniform(-0.3, 0.3, (n, 2)), rng.uniform(0.9, 1.5, n)])
    R, t = so3_exp(rng.normal(scale=0.05, size=3)), rng.normal(scale=0.03, size=3)
    A = rng.normal(size=(n, 2, 2))
    cov_i = A @ np.transpose(A, (0, 2, 1)) + 0.1 * np.eye(2)
    c = 0.3
    Sigma = np.zeros((2 * n, 2 * n))
    for i in range(n):
        Sigma[2 * i : 2 * i + 2, 2 * i : 2 * i + 2] = cov_i[i]
    U = np.tile(np.eye(2), (n, 1))
    Sigma += c**2 * U @ U.T
    J = pose_information.__globals__["reprojection_jacobian"](K, R, t, p).reshape(-1, 6)
    dense = J.T @ np.linalg.solve(Sigma, J)
    info = pose_information(K, R, t, p, np.linalg.inv(cov_i), common_px=c)
    assert np.allclose(info, dense, rtol=1e-8, atol=1e-8 * np.abs(dense).max())


def test_motion_floor_known_answer():
    """``motion_floor``: std·|t| per translation axis, std·|t|/depth per rotation axis."""
    cov = motion_floor(np.array([0.03, 0.0, -0.04]), 1.25, 0.2)  # |t| = 5 cm
    assert np.allclose(np.diag(cov), [0.008**2] * 3 + [0.01**2] * 3)
    assert np.count_nonzero(cov - np.diag(np.diag(cov))) == 0
    assert np.all(motion_floor(np.zeros(3), 1.0, 0.2) == 0.0)


def test_motion_std_adds_the_motion_floor(textured_pair):
    """``vo.motion_std`` adds the floor of the pair's own motion to the covariance and changes
    nothing else; a still camera gets no floor."""
    prev, cur, T_true = textured_pair
    guess = perturb(T_true, 5.0, 0.5, 3)
    base = FrameOdometry(OdometryParams(motion_std=0.0)).estimate(prev, cur, K, guess)
    floored = FrameOdometry(OdometryParams(motion_std=0.2)).estimate(prev, cur, K, guess)
    assert base.ok and floored.ok
    assert np.array_equal(base.R, floored.R) and np.array_equal(base.t, floored.t)
    added = floored.cov6 - base.cov6
    assert np.allclose(np.diag(added)[3:], (0.2 * np.linalg.norm(base.t)) ** 2)
    assert np.allclose(added, np.diag(np.diag(added)), atol=1e-15)
    assert np.all(np.diag(added)[:3] > 0)
    still = FrameOdometry(OdometryParams(motion_std=0.2)).estimate(prev, prev, K, np.eye(4))
    still0 = FrameOdometry(OdometryParams(motion_std=0.0)).estimate(prev, prev, K, np.eye(4))
    assert still.ok and np.linalg.norm(still.t) < 1e-3
    assert np.allclose(still.cov6, still0.cov6, rtol=1e-3, atol=(0.2e-3) ** 2)
