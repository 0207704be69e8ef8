"""AprilTag board pose and covariance (gaitnet.vio.apriltags, thesis (3.27)–(3.34))."""

import sys

import cv2 as cv
import numpy as np
import pytest

from gaitnet.config import load_config
from gaitnet.errors import ConfigError
from gaitnet.geometry.camera import project
from gaitnet.geometry.rotation import so3_exp, so3_log
from gaitnet.io.types import (
    APRILTAG_FAMILIES,
    AprilTagBoard,
    CameraIntrinsics,
    Frame,
    SessionCalibration,
    tag_corners_in_board,
)
from gaitnet.vio import tag_detectors
from gaitnet.vio.apriltags import (
    AprilTagParams,
    camera_pose_jacobian,
    detect_board_pose,
    imu_pose_from_camera,
    pose_covariance,
)
from gaitnet.vio.config import VioConfig
from gaitnet.vio.tag_detectors import detect_tags

CAM = CameraIntrinsics(width=640, height=480, fx=386.0, fy=386.0, cx=319.5, cy=239.5)
K = CAM.K


def _board(name="start", first_id=0, x=0.3, yaw=np.pi / 2):
    T = np.eye(4)
    T[:3, :3] = so3_exp(np.array([0.0, 0.0, yaw]))
    T[:2, 3] = [x, 0.12]
    return AprilTagBoard(name, "tag36h11", 7, 5, 0.04, 0.012, first_id, T)


def _calib(boards):
    T_CfromI = np.eye(4)
    T_CfromI[:3, 3] = [-0.03, 0.007, 0.016]
    return SessionCalibration(CAM, CAM, 0.001, True, T_CfromI, apriltag_boards=tuple(boards))


def _camera(height=0.7, x=0.1, pitch_deg=75.0):
    R0 = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    T = np.eye(4)
    T[:3, :3] = so3_exp(np.array([0.0, np.radians(pitch_deg), 0.0])) @ R0
    T[:3, 3] = [x, 0.0, height]
    return T


def _render(board, T_WfromC, ppm=4000.0):
    """Grey image of the board (white sheet, tags drawn with cv.aruco) seen from T_WfromC,
    on a mid-grey floor: a top-view canvas (``ppm`` px per metre) warped by the homography."""
    d = cv.aruco.getPredefinedDictionary(cv.aruco.DICT_APRILTAG_36h11)
    s, g = board.tag_size_m, board.gap_m
    W = board.cols * (s + g) + g
    H = board.rows * (s + g) + g
    canvas = np.full((int(H * ppm), int(W * ppm)), 255, np.uint8)
    tag_px = int(round(s * ppm))
    for tag_id in board.tag_ids:
        c = board.tag_centre_in_board(tag_id)
        img = cv.aruco.generateImageMarker(d, tag_id, tag_px, borderBits=1)
        # canvas row grows with -y (tag read with board +y up), column with +x; margin g/2
        col0 = int(round((c[0] - s / 2 + g / 2) * ppm))
        row0 = int(round((H - (c[1] + s / 2 + g / 2)) * ppm))
        canvas[row0 : row0 + tag_px, col0 : col0 + tag_px] = img
    # canvas pixel centre (col, row) -> board (x, y) = ((col + .5) / ppm - g / 2,
    #                                               H - g / 2 - (row + .5) / ppm)
    A = np.array([[1 / ppm, 0, 0.5 / ppm - g / 2], [0, -1 / ppm, H - g / 2 - 0.5 / ppm], [0, 0, 1]])
    T_CfromB = np.linalg.inv(T_WfromC) @ board.T_WfromBoard
    Hb = K @ T_CfromB[:3, [0, 1, 3]]
    Hc = Hb @ A
    out = cv.warpPerspective(canvas, Hc, (640, 480), flags=cv.INTER_AREA, borderValue=110)
    return out


def _frame(gray):
    return Frame(
        index=0,
        t_ns=0,
        rgb=np.repeat(gray[..., None], 3, axis=2),
        depth_m=np.zeros(gray.shape, np.float32),
    )


DETECTORS = ["apriltag3", "aruco"]


@pytest.mark.parametrize("detector", DETECTORS)
def test_synthetic_board_pose_and_corner_convention(detector):
    board = _board()
    T_true = _camera()
    params = AprilTagParams(detector=detector)
    obs = detect_board_pose(_frame(_render(board, T_true)), _calib([board]), params)
    assert obs is not None and obs.board == "start"
    assert obs.n_tags >= 30
    assert np.linalg.norm(obs.T_WfromC[:3, 3] - T_true[:3, 3]) < 0.005
    assert np.degrees(np.linalg.norm(so3_log(T_true[:3, :3].T @ obs.T_WfromC[:3, :3]))) < 0.3
    assert obs.rms_px < 0.6
    # known answer: the detected corners are the true projections of tag_corners_in_board
    # (aruco order, pixel centres at integers): a corner out of order is a tag side (~14 px)
    # away, a pixel-centre slip is a 0.5 px mean offset
    p_C = (obs.corners_W.reshape(-1, 3) - T_true[:3, 3]) @ T_true[:3, :3]
    uv, _ = project(K, p_C)
    d = obs.corners_px.reshape(-1, 2) - uv
    assert np.abs(d).max() < 1.0
    assert np.abs(d.mean(axis=0)).max() < 0.2
    np.testing.assert_allclose(obs.cov6, obs.cov6.T)
    assert np.all(np.linalg.eigvalsh(obs.cov6) > 0)


def test_the_detector_key_selects_the_corner_detector():
    board = _board()
    img = _render(board, _camera())
    ids, corners = {}, {}
    for detector in DETECTORS:
        i, c = detect_tags(img, AprilTagParams(detector=detector))
        order = np.argsort(i)
        ids[detector], corners[detector] = i[order], c[order]
    np.testing.assert_array_equal(ids["apriltag3"], ids["aruco"])
    # the same tags, corners within a pixel, from two different detectors
    diff = np.abs(corners["apriltag3"] - corners["aruco"])
    assert diff.max() < 1.0 and np.median(diff) > 1e-3


def test_a_wrong_detector_is_a_one_line_config_error():
    with pytest.raises(ConfigError, match="tags.detector") as info:
        load_config(VioConfig, None, ["tags.detector=opencv"])
    assert "\n" not in str(info.value)
    with pytest.raises(ValueError, match="detector"):
        AprilTagParams(detector="opencv")


def test_apriltag3_without_its_package_is_a_one_line_error(monkeypatch):
    monkeypatch.setitem(sys.modules, "pupil_apriltags", None)  # import fails
    monkeypatch.setattr(tag_detectors, "_DETECTORS", {})
    img = _render(_board(), _camera())
    with pytest.raises(ConfigError, match="pupil_apriltags==") as info:
        detect_tags(img, AprilTagParams(detector="apriltag3"))
    assert "\n" not in str(info.value) and "tags.detector=aruco" in str(info.value)
    assert len(detect_tags(img, AprilTagParams(detector="aruco"))[0]) >= 30


def test_sessions_accept_exactly_the_families_the_detectors_decode():
    """A session's board families are checked where session.yaml is read (gaitnet check
    refuses the others), against the families the filter's detectors know."""
    assert set(APRILTAG_FAMILIES) == set(tag_detectors._FAMILIES)
    with pytest.raises(ValueError, match="family 'tag25h9' cannot be decoded"):
        AprilTagBoard("start", "tag25h9", 7, 5, 0.04, 0.012, 0, np.eye(4))


@pytest.mark.parametrize("detector", DETECTORS)
def test_picks_the_board_in_view_and_ignores_others(detector):
    start, end = _board("start", 0, x=0.3), _board("end", 35, x=5.0)
    T_true = _camera()
    img = _render(start, T_true)
    params = AprilTagParams(detector=detector)
    obs = detect_board_pose(_frame(img), _calib([end, start]), params)
    assert obs is not None and obs.board == "start"
    assert set(obs.tag_ids.tolist()) <= set(range(35))
    # ids on no board of the session: nothing
    assert detect_board_pose(_frame(img), _calib([end]), params) is None
    assert detect_board_pose(_frame(img), _calib([]), params) is None
    # with a pose guess the search is limited to the boards' projections: a guess with no board
    # in view finds nothing, a guess 3 cm off finds the board
    T_far = _camera(x=3.0)
    assert detect_board_pose(_frame(img), _calib([start]), params, T_WfromC_guess=T_far) is None
    T_near = T_true.copy()
    T_near[:3, 3] += [0.03, -0.02, 0.01]
    obs2 = detect_board_pose(_frame(img), _calib([start]), params, T_WfromC_guess=T_near)
    assert obs2 is not None and obs2.n_tags == obs.n_tags
    if detector == "aruco":  # the same corners in the box as in the whole image
        np.testing.assert_allclose(obs2.T_WfromC, obs.T_WfromC, atol=1e-6)
    else:  # AprilTag 3's corners move by up to ~0.1 px with the box's top row
        np.testing.assert_allclose(obs2.T_WfromC, obs.T_WfromC, atol=2e-3)


def _pixels(T_WfromC, P_W):
    p_C = (P_W - T_WfromC[:3, 3]) @ T_WfromC[:3, :3]
    return project(K, p_C)[0]


def _boxplus(T, d):
    out = T.copy()
    out[:3, :3] = T[:3, :3] @ so3_exp(d[:3])
    out[:3, 3] = T[:3, 3] + d[3:]
    return out


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_pose_jacobian_matches_finite_differences(seed):
    rng = np.random.default_rng(seed)
    T = _boxplus(_camera(), np.r_[rng.normal(0, 0.1, 3), rng.normal(0, 0.05, 3)])
    P_W = np.c_[rng.uniform(0.2, 0.6, 10), rng.uniform(-0.15, 0.15, 10), np.zeros(10)]
    H = camera_pose_jacobian(K, T, P_W)
    eps = 1e-6
    H_fd = np.zeros_like(H)
    for k in range(6):
        d = np.zeros(6)
        d[k] = eps
        H_fd[:, :, k] = (_pixels(_boxplus(T, d), P_W) - _pixels(_boxplus(T, -d), P_W)) / (2 * eps)
    assert np.linalg.norm(H - H_fd) / np.linalg.norm(H_fd) < 1e-5


def test_imu_pose_covariance_is_the_linearised_map():
    rng = np.random.default_rng(3)
    T_WfromC = _boxplus(_camera(), rng.normal(0, 0.1, 6))
    T_CfromI = _calib([]).T_CfromI @ _boxplus(np.eye(4), np.r_[rng.normal(0, 0.3, 3), 0, 0, 0])
    A = rng.normal(size=(6, 6))
    cov_C = A @ A.T * 1e-4
    T_WfromI, cov_I = imu_pose_from_camera(T_WfromC, cov_C, T_CfromI)
    np.testing.assert_allclose(T_WfromI, T_WfromC @ T_CfromI)
    # J from central differences of the IMU error as a function of the camera error
    eps = 1e-6
    J = np.zeros((6, 6))
    for k in range(6):
        d = np.zeros(6)
        d[k] = eps
        e = []
        for sgn in (1, -1):
            Ti = _boxplus(T_WfromC, sgn * d) @ T_CfromI
            e.append(np.r_[so3_log(T_WfromI[:3, :3].T @ Ti[:3, :3]), Ti[:3, 3] - T_WfromI[:3, 3]])
        J[:, k] = (e[0] - e[1]) / (2 * eps)
    np.testing.assert_allclose(cov_I, J @ cov_C @ J.T, rtol=1e-6, atol=1e-12)


def test_covariance_matches_monte_carlo_pnp():
    # (3.30): ε1 (Σ H̄ᵀH̄)^{-1} is the covariance of the PnP pose under corner noise ε1
    board = _board()
    T_true = _camera()
    P_B = np.concatenate([tag_corners_in_board(board, i) for i in range(0, 35, 3)])
    P_W = P_B @ board.T_WfromBoard[:3, :3].T + board.T_WfromBoard[:3, 3]
    uv = _pixels(T_true, P_W)
    sigma = 0.5
    cov = pose_covariance(K, T_true, P_W, sigma**2)
    rng = np.random.default_rng(4)
    errs = []
    for _ in range(300):
        img = uv + rng.normal(0, sigma, uv.shape)
        ok, rvec, tvec = cv.solvePnP(P_B, img, K, None, flags=cv.SOLVEPNP_IPPE)
        rvec, tvec = cv.solvePnPRefineLM(P_B, img, K, None, rvec, tvec)
        T_CfromB = np.eye(4)
        T_CfromB[:3, :3] = cv.Rodrigues(rvec)[0]
        T_CfromB[:3, 3] = tvec.ravel()
        T = board.T_WfromBoard @ np.linalg.inv(T_CfromB)
        errs.append(np.r_[so3_log(T_true[:3, :3].T @ T[:3, :3]), T[:3, 3] - T_true[:3, 3]])
    errs = np.array(errs)
    nees = np.einsum("ni,ij,nj->n", errs, np.linalg.inv(cov), errs)
    assert 5.0 < nees.mean() < 7.0  # χ²(6): mean 6, std of the mean of 300 ≈ 0.2
    emp = np.cov(errs.T)
    np.testing.assert_allclose(np.sqrt(np.diag(emp)), np.sqrt(np.diag(cov)), rtol=0.2)


def test_bad_parameters():
    board = _board()
    img = _render(board, _camera())
    with pytest.raises(ValueError, match="corner_refinement"):
        detect_board_pose(
            _frame(img), _calib([board]), AprilTagParams(detector="aruco", corner_refinement="x")
        )


def test_apriltag3_detector_is_freed_before_its_tag_families():
    # pupil-apriltags' own __del__ frees the families first, and the C detector's destructor
    # then reads freed memory (a segmentation fault at exit); close() frees in the C order
    calls = []

    class Fn:
        def __init__(self, name):
            self.name = name

        def __call__(self, arg):
            calls.append((self.name, arg))

    class Libc:
        def __getattr__(self, name):
            return Fn(name)

    class Binding:
        tag_detector_ptr = "det"
        tag_families = {"tag36h11": "fam"}
        libc = Libc()

    det = Binding()
    tag_detectors._AprilTag3(det).close()
    assert calls == [("apriltag_detector_destroy", "det"), ("tag36h11_destroy", "fam")]
    assert det.tag_detector_ptr is None  # the binding's __del__ frees nothing
    tag_detectors._AprilTag3(det).close()
    assert len(calls) == 2
