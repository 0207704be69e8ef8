"""gaitnet's .bag reader against the RealSense SDK's own playback (pyrealsense2, the
``realsense`` extra), on a real D435 recording (``tests/data/README.md``).

The SDK plays the bag as recorded; gaitnet reads the same bag with a still IMU added (the
recording has none and gaitnet's reader requires one; every other message is copied byte for
byte). Both must give the same colour pixels, depth counts, time stamps, intrinsics, depth
scale and depth→colour extrinsic, and gaitnet's depth→colour alignment must agree with the
SDK's ``rs.align`` wherever both have depth.
"""

from __future__ import annotations

import ctypes
import importlib.util
import sys
import threading
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))

from bagfactory import _imu, _typestore  # noqa: E402

from gaitnet.errors import SessionError  # noqa: E402
from gaitnet.io.bag_index import RosBag  # noqa: E402
from gaitnet.io.depth_align import align_depth_to_color  # noqa: E402
from gaitnet.io.realsense_bag import TF_REF_TO_STREAM, RealSenseBag  # noqa: E402
from gaitnet.io.realsense_calibration import (  # noqa: E402
    BagCalibration,
    build_calibration,
    read_statics,
)
from gaitnet.io.realsense_frames import header_stamp  # noqa: E402
from gaitnet.io.realsense_streams import find_streams, timestamp_domain  # noqa: E402
from gaitnet.io.ros_image import decode_color, decode_depth  # noqa: E402

BAG = Path(__file__).parent / "data" / "single_depth_color_640x480.bag"


def _import_pyrealsense2():
    """pyrealsense2 (skipped when the ``realsense`` extra is not installed), with libusb from
    the libusb-package wheel when the system has none: the SDK's module links libusb-1.0 even
    for playback."""
    if importlib.util.find_spec("pyrealsense2") is None:
        pytest.skip("pyrealsense2 is not installed: pip install -e '.[realsense]'")
    try:
        import pyrealsense2 as rs
    except ImportError:
        import libusb_package

        ctypes.CDLL(str(libusb_package.get_library_path()), mode=ctypes.RTLD_GLOBAL)
        import pyrealsense2 as rs
    return rs


class SdkPlayback:
    """A bag as the SDK plays it: every frame of each stream (sensor playback), and the depth
    image its pipeline pairs with colour, raw and aligned to colour by ``rs.align``."""

    def __init__(self, rs, path: Path) -> None:
        self._align_first_pair(rs, path)  # the pipeline before the sensors: one player at once
        device = rs.context().load_device(str(path))
        playback = device.as_playback()
        playback.set_real_time(False)
        self.frames: dict[str, list[tuple[int, float, np.ndarray]]] = {"depth": [], "color": []}
        self.intrinsics, profiles_by_name = {}, {}
        finished = threading.Event()
        playback.set_status_changed_callback(
            lambda status: status == rs.playback_status.stopped and finished.set()
        )
        sensors = device.query_sensors()
        for sensor in sensors:
            profiles = sensor.get_stream_profiles()
            for profile in profiles:
                name = str(profile.stream_type()).split(".")[-1]
                profiles_by_name[name] = profile
                self.intrinsics[name] = profile.as_video_stream_profile().get_intrinsics()
            sensor.open(profiles)
            sensor.start(self._collect)
        self.depth_scale = device.first_depth_sensor().get_depth_scale()
        ext = profiles_by_name["depth"].get_extrinsics_to(profiles_by_name["color"])
        self.T_CfromD = np.eye(4)
        self.T_CfromD[:3, :3] = np.reshape(ext.rotation, (3, 3)).T  # stored column-major
        self.T_CfromD[:3, 3] = ext.translation
        if not finished.wait(30):
            raise TimeoutError(f"SDK playback of {path} did not finish")
        for sensor in sensors:
            sensor.stop()
            sensor.close()

    def _collect(self, frame) -> None:
        name = str(frame.profile.stream_type()).split(".")[-1]
        data = np.asanyarray(frame.get_data()).copy()
        self.frames[name].append((frame.get_frame_number(), frame.get_timestamp(), data))

    def _align_first_pair(self, rs, path: Path) -> None:
        pipeline, config = rs.pipeline(), rs.config()
        config.enable_device_from_file(str(path), repeat_playback=False)
        profile = pipeline.start(config)
        profile.get_device().as_playback().set_real_time(False)
        try:
            frames = pipeline.wait_for_frames(10_000)
            aligned = rs.align(rs.stream.color).process(frames).get_depth_frame()
            self.aligned_raw = np.asanyarray(aligned.get_data()).copy()
            self.paired_depth_raw = np.asanyarray(frames.get_depth_frame().get_data()).copy()
        finally:
            pipeline.stop()


def _bag_with_still_imu(src: Path, dst: Path) -> Path:
    """``src`` copied message for message, plus a still accelerometer and gyroscope at 200 Hz
    over the recording (header stamps in the frames' clock, record times in the bag's)."""
    from rosbags.rosbag1 import Reader, Writer

    store = _typestore()
    with Reader(src) as reader, Writer(dst) as writer:
        conns = {}
        for c in reader.connections:
            conns[c.id] = writer.add_connection(
                c.topic, c.msgtype, msgdef=c.msgdef.data, md5sum=c.digest, callerid=c.ext.callerid
            )
        for c, t_rec, raw in reader.messages():
            writer.write(conns[c.id], t_rec, raw)
        stamp0_ns, rec0_ns = 360_713_523_000 - 54_424_400, 0  # colour: stamp - record time
        for kind, sample in (("Accel", {"accel": (0.0, -9.81, 0.0)}), ("Gyro", {})):
            topic = f"/device_0/sensor_2/{kind}_0/imu/data"
            conn = writer.add_connection(topic, "sensor_msgs/msg/Imu", typestore=store)
            for seq, t_rec in enumerate(range(rec0_ns, reader.end_time + 5_000_000, 5_000_000)):
                msg = _imu(store, seq, stamp0_ns + t_rec, **sample)
                writer.write(conn, t_rec + 1, store.serialize_ros1(msg, "sensor_msgs/msg/Imu"))
    return dst


@pytest.fixture(scope="module")
def sdk():
    return SdkPlayback(_import_pyrealsense2(), BAG)


@dataclass
class GaitnetRead:
    """What gaitnet's reader takes from the bag: the calibration, and each image stream's
    frames by header stamp (colour RGB; depth in metres, not aligned)."""

    calibration: BagCalibration
    color: dict[int, np.ndarray]
    depth: dict[int, np.ndarray]


@pytest.fixture(scope="module")
def bag_with_imu(tmp_path_factory) -> Path:
    return _bag_with_still_imu(BAG, tmp_path_factory.mktemp("bag") / "with_imu.bag")


@pytest.fixture(scope="module")
def ours(bag_with_imu) -> GaitnetRead:
    """The reader's own steps (:class:`~gaitnet.io.realsense_bag.RealSenseBag` runs these and
    then pairs colour with depth, which this recording's 6 fps refuses: see the last test)."""
    bag = RosBag(bag_with_imu)
    streams = find_streams(bag)
    statics = read_statics(bag, streams)
    domain = timestamp_domain(bag, streams)
    calib = build_calibration(bag, streams, statics, TF_REF_TO_STREAM, np.eye(4), domain)
    frames = {}
    for stream in (streams.color, streams.depth):
        topic = stream.data_topic
        msgs = [bag.decode(ref, topic) for ref in bag.refs(topic)]
        decode = (lambda m: decode_depth(m, statics.depth_units_m)) if stream is streams.depth \
            else decode_color  # fmt: skip
        frames[stream.kind] = {header_stamp(m): decode(m) for m in msgs}
    bag.close()
    return GaitnetRead(calib, frames["Color"], frames["Depth"])


def test_the_sdk_plays_the_whole_recording(sdk) -> None:
    assert [n for n, _, _ in sdk.frames["depth"]] == [169, 170]
    assert [n for n, _, _ in sdk.frames["color"]] == [162]


def test_colour_pixels_and_time_stamps_are_the_sdks(sdk, ours) -> None:
    ((_, t_ms, rgb),) = sdk.frames["color"]
    ((t_ns, ours_rgb),) = ours.color.items()
    assert t_ns == round(t_ms * 1e6)  # the hardware clock; ms in the SDK
    np.testing.assert_array_equal(ours_rgb, rgb)


def test_depth_and_its_scale_are_the_sdks(sdk, ours) -> None:
    scale = ours.calibration.session.depth_scale_m
    assert scale == pytest.approx(sdk.depth_scale, rel=1e-6)
    assert sorted(ours.depth) == [round(t_ms * 1e6) for _, t_ms, _ in sdk.frames["depth"]]
    for _, t_ms, raw in sdk.frames["depth"]:
        expected = (raw.astype(np.float64) * scale).astype(np.float32)
        np.testing.assert_array_equal(ours.depth[round(t_ms * 1e6)], expected)


def test_intrinsics_and_extrinsic_are_the_sdks(sdk, ours) -> None:
    calib = ours.calibration
    assert not calib.depth_aligned
    for name, intr in (("color", calib.session.color), ("depth", calib.bag_depth)):
        ref = sdk.intrinsics[name]
        assert (intr.width, intr.height) == (ref.width, ref.height)
        np.testing.assert_allclose(
            [intr.fx, intr.fy, intr.cx, intr.cy], [ref.fx, ref.fy, ref.ppx, ref.ppy], rtol=1e-6
        )
        np.testing.assert_allclose(intr.distortion, ref.coeffs, atol=1e-7)
    np.testing.assert_allclose(calib.T_CfromD, sdk.T_CfromD, atol=1e-6)


def test_depth_aligned_to_colour_agrees_with_the_sdks_align(sdk, ours) -> None:
    """gaitnet's alignment (:func:`~gaitnet.io.depth_align.align_depth_to_color`) of the depth
    image the SDK's pipeline pairs with colour, against ``rs.align(color)`` of that pair."""
    calib = ours.calibration
    depth_m = (sdk.paired_depth_raw * sdk.depth_scale).astype(np.float32)
    ours_m = align_depth_to_color(depth_m, calib.bag_depth, calib.session.color, calib.T_CfromD)
    sdk_m = sdk.aligned_raw * sdk.depth_scale
    # The SDK writes each pixel's depth-camera z (librealsense's align_z_to_other), gaitnet
    # the colour-camera z: move ours back into the depth camera to compare.
    color = calib.session.color
    u, v = np.meshgrid(np.arange(color.width), np.arange(color.height))
    rays = np.stack([(u - color.cx) / color.fx, (v - color.cy) / color.fy, np.ones(u.shape)])
    R, t = calib.T_CfromD[:3, :3], calib.T_CfromD[:3, 3]
    ours_zD = np.einsum("i,ihw->hw", R[:, 2], ours_m * rays - t[:, None, None])
    both = (ours_m > 0) & (sdk_m > 0)
    assert both.sum() > 0.99 * ((ours_m > 0) | (sdk_m > 0)).sum()  # measured 99.7 %
    diff = np.abs(ours_zD[both] - sdk_m[both])
    # The same depth where both project a depth pixel alike (median measured 0.013 mm); the
    # footprints' rounding gives some pixels a neighbour's depth (83 % within 1 mm, 99th
    # percentile 14 mm on this office).
    assert np.median(diff) <= 1e-4
    assert np.mean(diff <= 0.001) > 0.75
    assert np.percentile(diff, 99) < 0.03


def test_the_reader_refuses_frames_too_sparse_to_pair(bag_with_imu) -> None:
    """6 fps: no colour frame has a depth frame within half a period (83 ms); one line."""
    with pytest.raises(SessionError, match="no colour frame has a depth frame within half"):
        RealSenseBag(bag_with_imu, T_CfromI=np.eye(4))
