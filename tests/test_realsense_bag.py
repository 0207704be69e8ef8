"""RealSense SDK ``.bag`` reader, IMU stream merge and depth→colour alignment."""

from __future__ import annotations

import logging
import pickle
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))

from bagfactory import (  # noqa: E402
    COLOR_INTR,
    DEPTH_INTR_NATIVE,
    T_COLOR_FROM_DEPTH,
    T_IMU_FROM_DEPTH,
    plane_depth,
    write_empty_bag,
    write_sdk_bag,
)
from oneline import assert_one_line_message  # noqa: E402

from gaitnet.errors import SessionError  # noqa: E402
from gaitnet.geometry import invert_T  # noqa: E402
from gaitnet.io.bag_index import RosBag  # noqa: E402
from gaitnet.io.depth_align import align_depth_to_color  # noqa: E402
from gaitnet.io.imu_merge import merge_imu_streams  # noqa: E402
from gaitnet.io.realsense_bag import TF_REF_TO_STREAM, TF_STREAM_TO_REF, RealSenseBag  # noqa: E402
from gaitnet.io.realsense_extrinsics import relative_extrinsic  # noqa: E402
from gaitnet.io.types import CameraIntrinsics  # noqa: E402


@pytest.fixture
def sdk_bag(tmp_path: Path):
    return write_sdk_bag(tmp_path / "walk.bag")


def expected_depth_m(raw: np.ndarray, units: float) -> np.ndarray:
    return (raw.astype(np.float64) * units).astype(np.float32)


# -- frames -----------------------------------------------------------------------------------


def test_frame_count_and_timestamps_are_colour_header_stamps(sdk_bag):
    bag = RealSenseBag(sdk_bag.path)
    assert len(bag) == 5
    assert bag.frame_times_ns.dtype == np.int64
    np.testing.assert_array_equal(bag.frame_times_ns, sdk_bag.color_t_ns)
    frames = list(bag.frames())
    assert [f.index for f in frames] == list(range(5))
    assert [f.t_ns for f in frames] == sdk_bag.color_t_ns


def test_pixels_round_trip_exactly(sdk_bag):
    bag = RealSenseBag(sdk_bag.path)
    assert bag.calibration.depth_scale_m == 0.001
    for i, frame in enumerate(bag.frames()):
        assert frame.rgb.dtype == np.uint8 and frame.rgb.shape == (48, 64, 3)
        np.testing.assert_array_equal(frame.rgb, sdk_bag.rgb[i])
        assert frame.depth_m.dtype == np.float32 and frame.depth_m.shape == (48, 64)
        np.testing.assert_array_equal(frame.depth_m, expected_depth_m(sdk_bag.depth_raw[i], 0.001))
        assert (frame.depth_m[sdk_bag.depth_raw[i] == 0] == 0).all()


def test_negative_and_out_of_range_indices(sdk_bag):
    bag = RealSenseBag(sdk_bag.path)
    assert bag.frame(-1).index == 4
    with pytest.raises(IndexError):
        bag.frame(5)


def test_bgr8_colour_is_returned_as_rgb(tmp_path):
    spec = write_sdk_bag(tmp_path / "bgr.bag", color_encoding="bgr8", n_frames=2)
    bag = RealSenseBag(spec.path)
    np.testing.assert_array_equal(bag.frame(1).rgb, spec.rgb[1])


def test_depth_units_come_from_the_option_topic_with_a_space(tmp_path):
    spec = write_sdk_bag(tmp_path / "units.bag", depth_units=0.0001, n_frames=2)
    bag = RealSenseBag(spec.path)
    assert bag.calibration.depth_scale_m == 0.0001
    np.testing.assert_array_equal(bag.frame(0).depth_m, expected_depth_m(spec.depth_raw[0], 0.0001))


def test_depth_units_default_to_a_millimetre(tmp_path):
    spec = write_sdk_bag(tmp_path / "nounits.bag", depth_units=None, n_frames=2)
    bag = RealSenseBag(spec.path)
    assert bag.calibration.depth_scale_m == 0.001


def test_bag_without_file_version_is_accepted(tmp_path):
    spec = write_sdk_bag(tmp_path / "ros.bag", include_file_version=False, n_frames=2)
    bag = RealSenseBag(spec.path)
    assert len(bag) == 2
    assert bag.calibration.extra["file_version"] is None


def test_unpaired_frames_are_dropped_with_a_warning(tmp_path, caplog):
    spec = write_sdk_bag(tmp_path / "unpaired.bag", unpaired=True)
    with caplog.at_level(logging.WARNING, logger="gaitnet.io.realsense_bag"):
        bag = RealSenseBag(spec.path)
    assert len(bag) == 5
    np.testing.assert_array_equal(bag.frame_times_ns, spec.color_t_ns[:5])
    # depth frame k+1 of the spec pairs with colour frame k (one extra depth frame first)
    np.testing.assert_array_equal(bag.frame(2).depth_m, expected_depth_m(spec.depth_raw[3], 0.001))
    assert "dropped 1 colour and 1 depth frame(s)" in caplog.text


def test_compressed_bag_with_many_chunks_reads_the_same(tmp_path):
    plain = write_sdk_bag(tmp_path / "plain.bag")
    lz4 = write_sdk_bag(tmp_path / "lz4.bag", compression=True, chunk_threshold=4096)
    a, b = RealSenseBag(plain.path), RealSenseBag(lz4.path)
    np.testing.assert_array_equal(a.frame_times_ns, b.frame_times_ns)
    for fa, fb in zip(a.frames(), b.frames(), strict=True):
        np.testing.assert_array_equal(fa.rgb, fb.rgb)
        np.testing.assert_array_equal(fa.depth_m, fb.depth_m)
    np.testing.assert_array_equal(a.imu.accel, b.imu.accel)
    np.testing.assert_array_equal(a.imu.t_ns, b.imu.t_ns)


def test_small_chunks_uncompressed(tmp_path):
    spec = write_sdk_bag(tmp_path / "chunks.bag", chunk_threshold=2048)
    bag = RealSenseBag(spec.path)
    np.testing.assert_array_equal(bag.frame(3).rgb, spec.rgb[3])


def test_a_frame_reads_only_its_two_messages(sdk_bag, monkeypatch):
    bag = RealSenseBag(sdk_bag.path)
    calls = []
    original = RosBag.read

    def spy(self, ref, limit=None):
        calls.append(ref)
        return original(self, ref, limit)

    monkeypatch.setattr(RosBag, "read", spy)
    bag.frame(3)
    assert len(calls) == 2


def test_reader_pickles_for_worker_processes(sdk_bag):
    bag = RealSenseBag(sdk_bag.path)
    clone = pickle.loads(pickle.dumps(bag))
    np.testing.assert_array_equal(clone.frame(2).rgb, sdk_bag.rgb[2])
    np.testing.assert_array_equal(clone.imu.t_ns, bag.imu.t_ns)


def test_bag_copies_to_a_session_folder(sdk_bag, tmp_path):
    """copy_session writes the bag as a folder; the calibration (extra included) is YAML-safe."""
    import yaml

    from gaitnet.io.session_folder import SessionFolder, copy_session

    bag = RealSenseBag(sdk_bag.path)
    out = copy_session(bag, tmp_path / "session")
    assert len(list((out / "color").glob("*.png"))) == len(bag)
    saved = yaml.safe_load((out / "session.yaml").read_text())
    assert saved["extra"] == bag.calibration.extra
    np.testing.assert_allclose(saved["T_CfromI"], bag.calibration.T_CfromI, atol=1e-12)
    assert saved["depth"]["width"] == bag.calibration.color.width
    folder = SessionFolder(out)
    assert folder.calibration.extra == bag.calibration.extra
    np.testing.assert_array_equal(folder.frame_times_ns, bag.frame_times_ns)
    np.testing.assert_array_equal(folder.frame(1).rgb, bag.frame(1).rgb)
    np.testing.assert_allclose(folder.frame(1).depth_m, bag.frame(1).depth_m, atol=5e-4)
    np.testing.assert_array_equal(folder.imu.t_ns, bag.imu.t_ns)


# -- IMU --------------------------------------------------------------------------------------


def test_imu_is_merged_onto_gyro_timestamps(sdk_bag, caplog):
    bag = RealSenseBag(sdk_bag.path)
    with caplog.at_level(logging.INFO, logger="gaitnet.io.imu_merge"):
        imu = bag.imu
    t_a, a = sdk_bag.t_acc, sdk_bag.acc
    t_g, g = sdk_bag.t_gyr, sdk_bag.gyr
    # expected: unique gyro stamps inside the accelerometer's span
    t_g_u, first = np.unique(t_g, return_index=True)
    inside = (t_g_u >= t_a.min()) & (t_g_u <= t_a.max())
    np.testing.assert_array_equal(imu.t_ns, t_g_u[inside])
    np.testing.assert_array_equal(imu.gyro, g[first][inside])
    # independent linear interpolation of the accelerometer (seconds from the first frame)
    t_a_u, first_a = np.unique(t_a, return_index=True)
    s_a = (t_a_u - t_a_u[0]) / 1e9
    s_g = (imu.t_ns - t_a_u[0]) / 1e9
    for axis in range(3):
        np.testing.assert_allclose(
            imu.accel[:, axis], np.interp(s_g, s_a, a[first_a, axis]), rtol=0, atol=1e-12
        )
    assert len(t_a) - len(t_a_u) == 1 and len(t_g) - len(t_g_u) == 1
    assert "dropped 1 accelerometer sample(s) with a repeated timestamp" in caplog.text
    assert "dropped 1 gyroscope sample(s) with a repeated timestamp" in caplog.text
    assert (np.diff(imu.t_ns) > 0).all()


def test_fast_imu_parser_matches_generic_deserialization(sdk_bag, monkeypatch):
    import gaitnet.io.realsense_bag as rb

    fast = RealSenseBag(sdk_bag.path).imu
    monkeypatch.setattr(rb, "parse_imu_payload", lambda raw, gyro: None)
    slow = RealSenseBag(sdk_bag.path).imu
    np.testing.assert_array_equal(fast.t_ns, slow.t_ns)
    np.testing.assert_array_equal(fast.accel, slow.accel)
    np.testing.assert_array_equal(fast.gyro, slow.gyro)


def test_T_CfromI_composes_the_tf_extrinsics(sdk_bag):
    expected = T_COLOR_FROM_DEPTH @ np.linalg.inv(T_IMU_FROM_DEPTH)
    bag = RealSenseBag(sdk_bag.path)
    np.testing.assert_allclose(bag.calibration.T_CfromI, expected, atol=1e-12)
    np.testing.assert_allclose(bag.calibration.extra["T_CfromD"], T_COLOR_FROM_DEPTH, atol=1e-12)
    # the other reading of the SDK's tf direction, selectable and different
    other = RealSenseBag(sdk_bag.path, tf_convention=TF_STREAM_TO_REF)
    np.testing.assert_allclose(
        other.calibration.T_CfromI,
        np.linalg.inv(T_COLOR_FROM_DEPTH) @ T_IMU_FROM_DEPTH,
        atol=1e-12,
    )
    assert not np.allclose(other.calibration.T_CfromI, expected)


def test_relative_extrinsic_maps_points_between_streams():
    rng = np.random.default_rng(3)
    p_ref = rng.normal(size=3)
    p_color = T_COLOR_FROM_DEPTH[:3, :3] @ p_ref + T_COLOR_FROM_DEPTH[:3, 3]
    p_imu = T_IMU_FROM_DEPTH[:3, :3] @ p_ref + T_IMU_FROM_DEPTH[:3, 3]
    T = relative_extrinsic(T_COLOR_FROM_DEPTH, T_IMU_FROM_DEPTH, TF_REF_TO_STREAM)
    np.testing.assert_allclose(T[:3, :3] @ p_imu + T[:3, 3], p_color, atol=1e-12)
    # with tf read as T_{ref from stream} the same geometry is stored inverted
    T2 = relative_extrinsic(
        invert_T(T_COLOR_FROM_DEPTH), invert_T(T_IMU_FROM_DEPTH), TF_STREAM_TO_REF
    )
    np.testing.assert_allclose(T2, T, atol=1e-12)


def test_explicit_T_CfromI_overrides_the_bag(sdk_bag):
    T = np.eye(4)
    T[:3, 3] = (0.01, 0.02, 0.03)
    bag = RealSenseBag(sdk_bag.path, T_CfromI=T)
    np.testing.assert_array_equal(bag.calibration.T_CfromI, T)


def test_imu_noise_densities_from_imu_intrinsic(sdk_bag):
    noise = RealSenseBag(sdk_bag.path).calibration.imu_noise
    assert noise is not None
    f32 = lambda v: float(np.mean(np.float32(v)))  # noqa: E731 - stored as float32
    assert noise.accel_noise_density == pytest.approx(np.sqrt(f32(sdk_bag.acc_noise_var) / 250))
    assert noise.gyro_noise_density == pytest.approx(np.sqrt(f32(sdk_bag.gyr_noise_var) / 200))
    assert noise.accel_bias_random_walk == pytest.approx(np.sqrt(f32(sdk_bag.acc_bias_var) * 250))
    assert noise.gyro_bias_random_walk == pytest.approx(np.sqrt(f32(sdk_bag.gyr_bias_var) * 200))


def test_calibration_describes_the_delivered_frames(sdk_bag):
    calib = RealSenseBag(sdk_bag.path).calibration
    assert calib.color == COLOR_INTR
    assert calib.depth == COLOR_INTR
    assert calib.depth_aligned_to_color
    assert calib.device == "Intel RealSense D455"
    assert calib.extra["depth_aligned_in_bag"] is True


# -- merge_imu_streams ------------------------------------------------------------------------


def _stream(t):
    t = np.asarray(t, dtype=np.int64)
    return t, np.stack([t * 1e-9, -t * 1e-9, np.ones(len(t))], axis=1)


def test_merge_sorts_and_interpolates():
    t_a, a = _stream([0, 10, 20, 30])
    t_g, g = _stream([25, 5, 15, 35, 5])
    imu = merge_imu_streams(t_a[::-1], a[::-1], t_g, g)
    np.testing.assert_array_equal(imu.t_ns, [5, 15, 25])
    np.testing.assert_allclose(imu.accel[:, 0], [5e-9, 15e-9, 25e-9])
    np.testing.assert_allclose(imu.gyro[:, 0], [5e-9, 15e-9, 25e-9])


def test_merge_rejects_empty_and_non_finite_streams():
    t, v = _stream([0, 10, 20])
    with pytest.raises(SessionError, match="accelerometer stream is empty"):
        merge_imu_streams(t[:0], v[:0], t, v, source="x.bag")
    with pytest.raises(SessionError, match="gyroscope stream is empty"):
        merge_imu_streams(t, v, t[:0], v[:0], source="x.bag")
    bad = v.copy()
    bad[1, 2] = np.nan
    with pytest.raises(SessionError, match=r"x\.bag: 1 non-finite gyroscope"):
        merge_imu_streams(t, v, t, bad, source="x.bag")
    with pytest.raises(SessionError, match="no gyroscope sample"):
        merge_imu_streams(t, v, t + 1000, v)


def test_merge_warns_about_gaps(caplog):
    t_a, a = _stream(np.arange(0, 1_000_000_000, 4_000_000))
    t_g = np.concatenate([np.arange(0, 300_000_000, 5_000_000), [500_000_000, 505_000_000]])
    t_g, g = _stream(t_g)
    with caplog.at_level(logging.WARNING, logger="gaitnet.io.imu_merge"):
        merge_imu_streams(t_a, a, t_g, g, gap_warn_s=0.05, source="gap.bag")
    assert "1 gyroscope gap(s) longer than 0.050 s" in caplog.text
    assert "accelerometer gap" not in caplog.text


# -- errors -----------------------------------------------------------------------------------


def test_garbage_file_is_a_session_error(tmp_path):
    path = tmp_path / "garbage.bag"
    path.write_bytes(np.random.default_rng(0).bytes(5000))
    with pytest.raises(SessionError) as excinfo:
        RealSenseBag(path)
    assert_one_line_message(excinfo, str(path), "not a readable ROS1 bag")


def test_truncated_bag_is_a_session_error(sdk_bag):
    data = sdk_bag.path.read_bytes()
    sdk_bag.path.write_bytes(data[: len(data) // 2])
    with pytest.raises(SessionError) as excinfo:
        RealSenseBag(sdk_bag.path)
    assert_one_line_message(excinfo, str(sdk_bag.path))


def test_bag_truncated_inside_the_index_is_a_session_error(sdk_bag):
    data = sdk_bag.path.read_bytes()
    sdk_bag.path.write_bytes(data[:-100])
    with pytest.raises(SessionError) as excinfo:
        RealSenseBag(sdk_bag.path)
    assert_one_line_message(excinfo, str(sdk_bag.path))


def test_empty_bag_is_a_session_error(tmp_path):
    path = write_empty_bag(tmp_path / "empty.bag")
    with pytest.raises(SessionError) as excinfo:
        RealSenseBag(path)
    assert_one_line_message(excinfo, str(path), "no messages")


def test_missing_file_is_a_session_error(tmp_path):
    with pytest.raises(SessionError, match="not found"):
        RealSenseBag(tmp_path / "nope.bag")


@pytest.mark.parametrize(
    "missing,fragment",
    [
        ("include_color", "no colour image topic"),
        ("include_depth", "no depth image topic"),
        ("include_imu", "no accelerometer topic"),
    ],
)
def test_missing_stream_is_a_session_error(tmp_path, missing, fragment):
    spec = write_sdk_bag(tmp_path / "partial.bag", n_frames=2, **{missing: False})
    with pytest.raises(SessionError) as excinfo:
        RealSenseBag(spec.path)
    assert_one_line_message(excinfo, str(spec.path), fragment)


def test_unsupported_encoding_is_a_session_error(tmp_path):
    spec = write_sdk_bag(tmp_path / "yuv.bag", color_encoding="yuv422", n_frames=2)
    with pytest.raises(SessionError) as excinfo:
        RealSenseBag(spec.path)
    assert_one_line_message(excinfo, str(spec.path), "unsupported colour encoding 'yuv422'")


# -- depth → colour alignment -----------------------------------------------------------------


DEPTH_CAM = CameraIntrinsics(width=64, height=48, fx=40.0, fy=40.0, cx=31.5, cy=23.5)
COLOR_CAM = CameraIntrinsics(width=96, height=72, fx=66.0, fy=65.0, cx=47.0, cy=36.2)


def _rigid(rotvec_deg, t):
    from scipy.spatial.transform import Rotation

    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(np.radians(rotvec_deg)).as_matrix()
    T[:3, 3] = t
    return T


def test_alignment_of_a_plane_seen_by_two_cameras():
    n_d, d_d = np.array([0.15, -0.2, 1.0]), 1.8  # plane n·p = d in the depth frame
    T = _rigid((2.0, -3.0, 1.0), (0.06, -0.01, 0.02))
    depth = plane_depth(DEPTH_CAM, n_d, d_d).astype(np.float32)
    aligned = align_depth_to_color(depth, DEPTH_CAM, COLOR_CAM, T)
    assert aligned.shape == (72, 96) and aligned.dtype == np.float32

    # the same plane in the colour frame: n_C = R n, d_C = d + n_C · t
    n_c = T[:3, :3] @ n_d
    d_c = d_d + n_c @ T[:3, 3]
    truth = plane_depth(COLOR_CAM, n_c, d_c)
    # colour pixels whose ray hits the plane at a point the depth camera sees well inside
    u, v = np.meshgrid(np.arange(96), np.arange(72))
    rays = np.stack(
        [(u - COLOR_CAM.cx) / COLOR_CAM.fx, (v - COLOR_CAM.cy) / COLOR_CAM.fy, np.ones(u.shape)],
        axis=-1,
    )
    p_c = rays * truth[..., None]
    p_d = (p_c - T[:3, 3]) @ T[:3, :3]  # R^T (p_C - t)
    ud = DEPTH_CAM.fx * p_d[..., 0] / p_d[..., 2] + DEPTH_CAM.cx
    vd = DEPTH_CAM.fy * p_d[..., 1] / p_d[..., 2] + DEPTH_CAM.cy
    inner = (ud > 1) & (ud < DEPTH_CAM.width - 2) & (vd > 1) & (vd < DEPTH_CAM.height - 2)
    outer = (ud < -2) | (ud > DEPTH_CAM.width + 1) | (vd < -2) | (vd > DEPTH_CAM.height + 1)
    assert inner.sum() > 2000
    assert (aligned[inner] > 0).all(), "holes inside the region the depth camera sees"
    rel = np.abs(aligned[inner] - truth[inner]) / truth[inner]
    assert rel.max() < 0.01
    assert (aligned[outer] == 0).all()


def test_alignment_keeps_the_nearest_surface():
    cam = CameraIntrinsics(width=40, height=10, fx=50.0, fy=50.0, cx=19.5, cy=4.5)
    depth = np.full((10, 40), 2.0, dtype=np.float32)
    depth[:, 20:24] = 1.0  # a near strip
    T = np.eye(4)
    T[0, 3] = 0.1  # colour camera 10 cm to the left: near things shift 5 px, far 2.5 px
    aligned = align_depth_to_color(depth, cam, cam, T)
    # the strip lands on columns 25..28 (20+5 .. 23+5) and hides the background there
    assert (aligned[:, 25:29] == 1.0).all()
    assert (aligned[:, 8:20] == 2.0).all()


def test_alignment_with_identical_cameras_is_the_identity():
    rng = np.random.default_rng(5)
    depth = rng.uniform(0.3, 4.0, size=(48, 64)).astype(np.float32)
    depth[rng.random(depth.shape) < 0.2] = 0
    aligned = align_depth_to_color(depth, DEPTH_CAM, DEPTH_CAM, np.eye(4))
    np.testing.assert_array_equal(aligned, depth)


def test_misaligned_bag_depth_is_aligned_to_colour(tmp_path):
    spec = write_sdk_bag(tmp_path / "native.bag", aligned=False, n_frames=3)
    bag = RealSenseBag(spec.path)
    calib = bag.calibration
    assert calib.depth == COLOR_INTR and calib.depth_aligned_to_color
    assert calib.extra["depth_aligned_in_bag"] is False
    assert calib.extra["bag_depth_intrinsics"]["width"] == DEPTH_INTR_NATIVE.width
    for i, frame in enumerate(bag.frames()):
        assert frame.depth_m.shape == (COLOR_INTR.height, COLOR_INTR.width)
        raw_m = expected_depth_m(spec.depth_raw[i], 0.001)
        expected = align_depth_to_color(raw_m, DEPTH_INTR_NATIVE, COLOR_INTR, T_COLOR_FROM_DEPTH)
        np.testing.assert_allclose(frame.depth_m, expected, rtol=1e-6, atol=0)
        # and it is the plane the factory drew, seen from the colour camera
        n_d, d_d = np.array([0.1, -0.15, 1.0]), 1.6 + 0.05 * i
        n_c = T_COLOR_FROM_DEPTH[:3, :3] @ n_d
        truth = plane_depth(COLOR_INTR, n_c, d_d + n_c @ T_COLOR_FROM_DEPTH[:3, 3])
        valid = frame.depth_m > 0
        assert valid.mean() > 0.8
        assert (np.abs(frame.depth_m[valid] - truth[valid]) / truth[valid]).max() < 0.01


# -- hardening --------------------------------------------------------------------------------


def test_depth_65535_is_no_data_not_65_metres(tmp_path):
    spec = write_sdk_bag(tmp_path / "nodata.bag", n_frames=2, no_data_pixels=True)
    depth = RealSenseBag(spec.path).frame(1).depth_m
    raw = spec.depth_raw[1]
    assert (raw == 65535).sum() == 15
    assert (depth[raw == 65535] == 0).all()
    ok = (raw != 65535) & (raw != 0)
    np.testing.assert_array_equal(depth[ok], expected_depth_m(raw, 0.001)[ok])


def test_one_timestamp_domain_is_recorded(tmp_path):
    domains = {k: "Hardware Clock" for k in ("Color", "Depth", "Accel", "Gyro")}
    spec = write_sdk_bag(tmp_path / "hw.bag", n_frames=3, timestamp_domains=domains)
    assert RealSenseBag(spec.path).calibration.extra["timestamp_domain"] == "Hardware Clock"
    plain = write_sdk_bag(tmp_path / "plain.bag", n_frames=2)
    assert "timestamp_domain" not in RealSenseBag(plain.path).calibration.extra


def test_mixed_timestamp_domains_are_refused(tmp_path):
    domains = {"Color": "Global Time", "Depth": "Global Time", "Gyro": "System Time"}
    spec = write_sdk_bag(tmp_path / "mixed.bag", n_frames=3, timestamp_domains=domains)
    with pytest.raises(SessionError) as excinfo:
        RealSenseBag(spec.path)
    assert_one_line_message(
        excinfo, str(spec.path), "colour image 'Global Time'", "gyroscope 'System Time'"
    )


def test_a_missing_domain_is_assumed_with_a_warning(tmp_path, caplog):
    domains = {"Color": "Global Time", "Depth": "Global Time"}
    spec = write_sdk_bag(tmp_path / "partial.bag", n_frames=3, timestamp_domains=domains)
    with caplog.at_level(logging.WARNING, logger="gaitnet.io.realsense_bag"):
        bag = RealSenseBag(spec.path)
    assert bag.calibration.extra["timestamp_domain"] == "Global Time"
    assert "no timestamp domain for the accelerometer, gyroscope stream(s)" in caplog.text


def test_unindexed_bag_says_how_to_fix_it(tmp_path):
    from bagfactory import unindex_bag

    spec = write_sdk_bag(tmp_path / "cut.bag", n_frames=3)
    unindex_bag(spec.path)
    with pytest.raises(SessionError) as excinfo:
        RealSenseBag(spec.path)
    assert_one_line_message(excinfo, str(spec.path), "no index", "rosbag reindex cut.bag")


def test_frames_out_of_order_are_sorted_with_a_warning(tmp_path, caplog):
    """Stamps a little out of record order (within a frame) are sorted, never silently."""
    spec = write_sdk_bag(tmp_path / "order.bag", n_frames=4, out_of_order=True)
    with caplog.at_level(logging.WARNING, logger="gaitnet.io.realsense_bag"):
        bag = RealSenseBag(spec.path)
    assert "1 colour image frame(s) out of order by up to 33.3 ms" in caplog.text
    np.testing.assert_array_equal(bag.frame_times_ns, spec.color_t_ns)
    for i in range(4):
        np.testing.assert_array_equal(bag.frame(i).rgb, spec.rgb[i])


def test_explicit_T_CfromI_must_be_rigid(sdk_bag):
    with pytest.raises(ValueError, match="T_CfromI is not a rigid transform"):
        RealSenseBag(sdk_bag.path, T_CfromI=np.diag([1.0, 1.0, 2.0, 1.0]))
