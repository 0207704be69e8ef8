"""Write tiny RealSense-SDK-style ``.bag`` files with fully known content (tests only).

The layout mimics librealsense's recorder: SDK topic names, ``sensor_msgs`` types, custom
``realsense_msgs`` types registered from message definitions written here, static messages
at record time 0, image/IMU header stamps in the device's time domain (far from the record
times, which count from the start of the recording), tf extrinsics stored as
``T_{stream from reference}`` with the depth stream as reference (group ``0``).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field, replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
from rosbags.rosbag1 import Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from scipy.spatial.transform import Rotation

from gaitnet.io.types import CameraIntrinsics

IMU_INTRINSIC_MSGDEF = """\
float32[12] data
float32[3] noise_variances
float32[3] bias_variances
"""
STREAM_INFO_MSGDEF = """\
uint32 fps
string encoding
bool is_recommended
"""

T0_NS = 1_700_000_000_123_000_000  # device time of the first colour frame
COLOR_PERIOD_NS = 33_333_333
DEPTH_OFFSET_NS = 1_000_000  # depth stamps trail colour by 1 ms
ACC_PERIOD_NS = 4_000_000  # 250 Hz
GYR_PERIOD_NS = 5_000_000  # 200 Hz

COLOR_INTR = CameraIntrinsics(width=64, height=48, fx=40.0, fy=41.0, cx=31.5, cy=23.25)
DEPTH_INTR_NATIVE = CameraIntrinsics(width=40, height=30, fx=26.0, fy=26.0, cx=19.5, cy=14.5)


def rigid(rotvec_deg: tuple[float, float, float], t: tuple[float, float, float]) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(np.radians(rotvec_deg)).as_matrix()
    T[:3, 3] = t
    return T


# Ground truth extrinsics, T_{stream from depth}: non-trivial rotations and translations.
T_COLOR_FROM_DEPTH = rigid((1.5, -2.0, 0.7), (-0.059, 0.0012, 0.0006))
T_IMU_FROM_DEPTH = rigid((0.4, 3.0, -91.0), (-0.0302, 0.0074, 0.016))


@dataclass
class BagSpec:
    """What a written bag contains (the ground truth for tests)."""

    path: Path
    color_t_ns: list[int] = field(default_factory=list)
    depth_t_ns: list[int] = field(default_factory=list)
    rgb: list[np.ndarray] = field(default_factory=list)  # as RGB, per colour frame
    depth_raw: list[np.ndarray] = field(default_factory=list)  # uint16, per depth frame
    depth_units: float | None = 0.001
    color_intr: CameraIntrinsics = COLOR_INTR
    depth_intr: CameraIntrinsics = COLOR_INTR
    t_acc: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    acc: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    t_gyr: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    gyr: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    tf: dict[str, np.ndarray] = field(default_factory=dict)  # kind -> T_{stream from ref}
    acc_noise_var: tuple[float, float, float] = (4e-4, 5e-4, 6e-4)
    gyr_noise_var: tuple[float, float, float] = (1e-5, 2e-5, 3e-5)
    acc_bias_var: tuple[float, float, float] = (1e-7, 1e-7, 1e-7)
    gyr_bias_var: tuple[float, float, float] = (2e-9, 2e-9, 2e-9)
    acc_fps: int = 250
    gyr_fps: int = 200


def _typestore():
    store = get_typestore(Stores.ROS1_NOETIC)
    store.register(get_types_from_msg(IMU_INTRINSIC_MSGDEF, "realsense_msgs/msg/ImuIntrinsic"))
    store.register(get_types_from_msg(STREAM_INFO_MSGDEF, "realsense_msgs/msg/StreamInfo"))
    return store


def _header(store, seq: int, t_ns: int):
    Header = store.types["std_msgs/msg/Header"]
    Time = store.types["builtin_interfaces/msg/Time"]
    return Header(seq=seq, stamp=Time(sec=t_ns // 10**9, nanosec=t_ns % 10**9), frame_id="")


def _camera_info(store, c: CameraIntrinsics | SimpleNamespace):
    CameraInfo = store.types["sensor_msgs/msg/CameraInfo"]
    RegionOfInterest = store.types["sensor_msgs/msg/RegionOfInterest"]
    K = np.array([c.fx, 0, c.cx, 0, c.fy, c.cy, 0, 0, 1], dtype=np.float64)
    P = np.array([c.fx, 0, c.cx, 0, 0, c.fy, c.cy, 0, 0, 0, 1, 0], dtype=np.float64)
    return CameraInfo(
        header=_header(store, 0, 0),
        height=c.height,
        width=c.width,
        distortion_model="Brown Conrady",
        D=np.array(c.distortion, dtype=np.float64),
        K=K,
        R=np.eye(3).ravel(),
        P=P,
        binning_x=0,
        binning_y=0,
        roi=RegionOfInterest(x_offset=0, y_offset=0, height=0, width=0, do_rectify=False),
    )


def _transform(store, T: np.ndarray, zero_rotation: bool = False):
    Transform = store.types["geometry_msgs/msg/Transform"]
    Vector3 = store.types["geometry_msgs/msg/Vector3"]
    Quaternion = store.types["geometry_msgs/msg/Quaternion"]
    x, y, z, w = (0.0,) * 4 if zero_rotation else Rotation.from_matrix(T[:3, :3]).as_quat()
    return Transform(
        translation=Vector3(x=float(T[0, 3]), y=float(T[1, 3]), z=float(T[2, 3])),
        rotation=Quaternion(x=float(x), y=float(y), z=float(z), w=float(w)),
    )


def _image(store, seq: int, t_ns: int, pixels: np.ndarray, encoding: str):
    Image = store.types["sensor_msgs/msg/Image"]
    h, w = pixels.shape[:2]
    data = np.ascontiguousarray(pixels)
    return Image(
        header=_header(store, seq, t_ns),
        height=h,
        width=w,
        encoding=encoding,
        is_bigendian=0,
        step=data.nbytes // h,
        data=np.frombuffer(data.tobytes(), dtype=np.uint8),
    )


def _imu(store, seq: int, t_ns: int, accel=None, gyro=None):
    Imu = store.types["sensor_msgs/msg/Imu"]
    Vector3 = store.types["geometry_msgs/msg/Vector3"]
    Quaternion = store.types["geometry_msgs/msg/Quaternion"]
    a = (0.0, 0.0, 0.0) if accel is None else accel
    g = (0.0, 0.0, 0.0) if gyro is None else gyro
    return Imu(
        header=_header(store, seq, t_ns),
        orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=0.0),
        orientation_covariance=np.zeros(9),
        angular_velocity=Vector3(x=float(g[0]), y=float(g[1]), z=float(g[2])),
        angular_velocity_covariance=np.zeros(9),
        linear_acceleration=Vector3(x=float(a[0]), y=float(a[1]), z=float(a[2])),
        linear_acceleration_covariance=np.zeros(9),
    )


def plane_depth(intr: CameraIntrinsics, normal, d: float) -> np.ndarray:
    """Depth [m] along z of the plane ``normal · p = d`` seen by a pinhole camera."""
    u, v = np.meshgrid(np.arange(intr.width), np.arange(intr.height))
    rays = np.stack([(u - intr.cx) / intr.fx, (v - intr.cy) / intr.fy, np.ones(u.shape)], axis=-1)
    return d / (rays @ np.asarray(normal, dtype=np.float64))


def acc_signal(t_ns: np.ndarray) -> np.ndarray:
    s = (np.asarray(t_ns) - T0_NS) * 1e-9
    return np.stack([np.sin(7 * s), 0.5 * np.cos(3 * s), 9.81 + 0.2 * s], axis=1)


def gyr_signal(t_ns: np.ndarray) -> np.ndarray:
    s = (np.asarray(t_ns) - T0_NS) * 1e-9
    return np.stack([0.1 * s, np.sin(5 * s), -0.3 * np.cos(2 * s)], axis=1)


def write_sdk_bag(
    path: Path,
    *,
    n_frames: int = 5,
    color_encoding: str = "rgb8",
    aligned: bool = True,
    depth_units: float | None = 0.001,
    include_color: bool = True,
    include_depth: bool = True,
    include_imu: bool = True,
    include_file_version: bool = True,
    unpaired: bool = False,
    compression: bool = False,
    chunk_threshold: int | None = None,
    no_data_pixels: bool = False,
    timestamp_domains: dict[str, str] | None = None,
    out_of_order: bool = False,
    fault: str | None = None,
) -> BagSpec:
    """Write an SDK-style bag; see :class:`BagSpec` for what ends up in it.

    ``aligned``: depth has colour's size and intrinsics; otherwise depth is a smaller native
    image (``DEPTH_INTR_NATIVE``) of a tilted plane. ``unpaired``: add a colour frame without
    depth (at the end) and a depth frame without colour (before the first). ``chunk_threshold``
    small values spread messages over many chunks. ``no_data_pixels``: some depth pixels are
    65535 (the SDK's "no data"). ``timestamp_domains``: write per-frame metadata topics with
    these ``timestamp_domain`` values (keys ``Color``, ``Depth``, ``Accel``, ``Gyro``; a value
    ``"A->B"`` switches from A to B halfway). ``fault``: one of :data:`FAULTS`, a damage that
    the reader must refuse. ``out_of_order``: colour frames 1 and 2 are recorded in swapped
    order (each keeps its stamp and pixels), as a host can deliver them.
    """
    if fault is not None and fault not in FAULTS:
        raise ValueError(f"unknown fault {fault!r}")
    store = _typestore()
    spec = BagSpec(path=Path(path), depth_units=depth_units)
    spec.depth_intr = COLOR_INTR if aligned else DEPTH_INTR_NATIVE
    rng = np.random.default_rng(7)

    # -- frames --------------------------------------------------------------------------
    n_color = n_frames + (1 if unpaired else 0)
    spec.color_t_ns = [T0_NS + i * COLOR_PERIOD_NS for i in range(n_color)]
    spec.depth_t_ns = [T0_NS + i * COLOR_PERIOD_NS + DEPTH_OFFSET_NS for i in range(n_frames)]
    if unpaired:
        spec.depth_t_ns.insert(0, T0_NS - COLOR_PERIOD_NS + DEPTH_OFFSET_NS)
    units = depth_units if depth_units is not None else 0.001
    c = COLOR_INTR
    for _ in spec.color_t_ns:
        spec.rgb.append(rng.integers(0, 256, size=(c.height, c.width, 3), dtype=np.uint8))
    d = spec.depth_intr
    for k in range(len(spec.depth_t_ns)):
        if aligned:
            raw = rng.integers(300, 6000, size=(d.height, d.width)).astype(np.uint16)
            raw[rng.random(raw.shape) < 0.1] = 0
        else:
            z = plane_depth(d, normal=(0.1, -0.15, 1.0), d=1.6 + 0.05 * k)
            raw = np.round(z / units).astype(np.uint16)
            raw[:2, :3] = 0  # a hole
        if no_data_pixels:
            raw[-3:, -5:] = 65535
        spec.depth_raw.append(raw)
    if fault == "color_size_change":
        for i in range(n_color // 2, n_color):
            spec.rgb[i] = spec.rgb[i][::2, ::2].copy()
    if fault == "depth_size_change":
        spec.depth_raw[-1] = spec.depth_raw[-1][:-2].copy()

    # -- IMU -----------------------------------------------------------------------------
    span = n_color * COLOR_PERIOD_NS
    t_acc = T0_NS - 20_000_000 + ACC_PERIOD_NS * np.arange(span // ACC_PERIOD_NS + 12)
    t_gyr = T0_NS - 31_300_000 + GYR_PERIOD_NS * np.arange(span // GYR_PERIOD_NS + 16)
    # duplicates, as the SDK sometimes delivers
    t_acc = np.insert(t_acc, 10, t_acc[9])
    t_gyr = np.insert(t_gyr, 20, t_gyr[20])
    spec.t_acc, spec.acc = t_acc.astype(np.int64), acc_signal(t_acc)
    spec.t_gyr, spec.gyr = t_gyr.astype(np.int64), gyr_signal(t_gyr)
    if fault == "imu_spike":
        spec.gyr[7] = (1.0e6, 0.0, 0.0)
    if fault == "imu_nan":
        spec.acc[5, 1] = np.nan

    spec.tf = {
        "Depth": np.eye(4),
        "Color": T_COLOR_FROM_DEPTH.copy(),
        "Accel": T_IMU_FROM_DEPTH,
        "Gyro": T_IMU_FROM_DEPTH,
    }
    if fault == "tf_nan":
        spec.tf["Color"][1, 3] = np.nan
    color_intr = c
    if fault == "intrinsics_nan":
        color_intr = _Intr(c, cx=float("nan"))
    if fault == "distortion_inf":
        color_intr = _Intr(c, distortion=(float("inf"), 0.0, 0.0, 0.0, 0.0))
    if fault == "depth_units_nan":
        depth_units = float("nan")

    # -- write ---------------------------------------------------------------------------
    writer = Writer(spec.path)
    if compression:
        writer.set_compression(Writer.CompressionFormat.LZ4)
    if chunk_threshold is not None:
        writer.chunk_threshold = chunk_threshold
    conns: dict[str, object] = {}

    def write(topic: str, msgtype: str, t_rec: int, msg) -> None:
        if topic not in conns:
            conns[topic] = writer.add_connection(topic, msgtype, typestore=store)
        writer.write(conns[topic], t_rec, store.serialize_ros1(msg, msgtype))

    def rec_time(t_ns: int) -> int:  # SDK record time: since the start of the recording
        return int(t_ns - (T0_NS - 50_000_000))

    depth_s, color_s, imu_s = "/device_0/sensor_0", "/device_0/sensor_1", "/device_0/sensor_2"
    with writer:
        if include_file_version:
            write(
                "/file_version",
                "std_msgs/msg/UInt32",
                0,
                store.types["std_msgs/msg/UInt32"](data=4),
            )
        KeyValue = store.types["diagnostic_msgs/msg/KeyValue"]
        for key, value in (("Name", "Intel RealSense D455"), ("Serial Number", "123456789012")):
            write(
                "/device_0/info", "diagnostic_msgs/msg/KeyValue", 0, KeyValue(key=key, value=value)
            )
        if depth_units is not None:
            Float32 = store.types["std_msgs/msg/Float32"]
            String = store.types["std_msgs/msg/String"]
            write(
                f"{depth_s}/option/Depth Units/value",
                "std_msgs/msg/Float32",
                0,
                Float32(data=depth_units),
            )
            write(
                f"{depth_s}/option/Depth Units/description",
                "std_msgs/msg/String",
                0,
                String(data="Number of meters represented by a single depth unit"),
            )
        if include_depth:
            write(
                f"{depth_s}/Depth_0/info/camera_info",
                "sensor_msgs/msg/CameraInfo",
                0,
                _camera_info(store, d),
            )
            write(
                f"{depth_s}/Depth_0/tf/0",
                "geometry_msgs/msg/Transform",
                0,
                _transform(store, spec.tf["Depth"]),
            )
        if include_color:
            write(
                f"{color_s}/Color_0/info/camera_info",
                "sensor_msgs/msg/CameraInfo",
                0,
                _camera_info(store, color_intr),
            )
            write(
                f"{color_s}/Color_0/tf/0",
                "geometry_msgs/msg/Transform",
                0,
                _transform(store, spec.tf["Color"], zero_rotation=fault == "tf_zero_quaternion"),
            )
        if include_imu:
            ImuIntrinsic = store.types["realsense_msgs/msg/ImuIntrinsic"]
            StreamInfo = store.types["realsense_msgs/msg/StreamInfo"]
            for kind, nv, bv, fps in (
                ("Accel", spec.acc_noise_var, spec.acc_bias_var, spec.acc_fps),
                ("Gyro", spec.gyr_noise_var, spec.gyr_bias_var, spec.gyr_fps),
            ):
                prefix = f"{imu_s}/{kind}_0"
                data = np.zeros(12, dtype=np.float32)
                data[[0, 5, 10]] = 1.0
                write(
                    f"{prefix}/imu_intrinsic",
                    "realsense_msgs/msg/ImuIntrinsic",
                    0,
                    ImuIntrinsic(
                        data=data,
                        noise_variances=np.array(nv, dtype=np.float32),
                        bias_variances=np.array(bv, dtype=np.float32),
                    ),
                )
                write(
                    f"{prefix}/info",
                    "realsense_msgs/msg/StreamInfo",
                    0,
                    StreamInfo(fps=fps, encoding="MOTION_XYZ32F", is_recommended=False),
                )
                write(
                    f"{prefix}/tf/0",
                    "geometry_msgs/msg/Transform",
                    0,
                    _transform(store, spec.tf[kind]),
                )

        # time-ordered stream of data messages
        events: list[tuple[int, int, str, object]] = []
        if include_color:
            for i, t in enumerate(spec.color_t_ns):
                pixels = spec.rgb[i][:, :, ::-1] if color_encoding == "bgr8" else spec.rgb[i]
                stamp = t + (3_600 * 10**9 if fault == "color_stamp_garbled" and i == 2 else 0)
                msg = _image(store, i, stamp, pixels, color_encoding)
                if fault == "color_stamp_nsec" and i == 1:
                    msg.header.stamp.nanosec = 1_500_000_000
                if fault in ("color_data_short", "color_data_long") and i == 2:
                    data = msg.data[:-7] if fault == "color_data_short" else msg.data
                    if fault == "color_data_long":
                        data = np.concatenate([data, np.zeros(64, np.uint8)])
                    msg = replace(msg, data=data)
                if fault == "color_step_short" and i == 3:
                    msg = replace(msg, step=msg.step - 3)
                if fault == "color_encoding_change" and i == 3:
                    msg = replace(msg, encoding="bgr8")
                t_rec = rec_time(t) + 2_000_000
                if out_of_order and i in (1, 2):
                    t_rec += COLOR_PERIOD_NS * (1 if i == 1 else -1)
                events.append((t_rec, 0, f"{color_s}/Color_0/image/data", msg))
        if include_depth:
            for i, t in enumerate(spec.depth_t_ns):
                msg = _image(store, i, t, spec.depth_raw[i], "mono16")
                events.append((rec_time(t) + 1_000_000, 1, f"{depth_s}/Depth_0/image/data", msg))
        if timestamp_domains:
            for kind, sensor, times in (
                ("Color", color_s, spec.color_t_ns),
                ("Depth", depth_s, spec.depth_t_ns),
                ("Accel", imu_s, spec.t_acc),
                ("Gyro", imu_s, spec.t_gyr),
            ):
                if kind not in timestamp_domains:
                    continue
                first, _, last = timestamp_domains[kind].partition("->")
                medium = "image" if kind in ("Color", "Depth") else "imu"
                topic = f"{sensor}/{kind}_0/{medium}/metadata"
                for i, t in enumerate(times):
                    domain = last if last and i >= len(times) // 2 else first
                    for key, value in (
                        ("system_time", str(1_700_000_000_000 + i)),
                        ("timestamp_domain", domain),
                        ("Frame Counter", str(i)),
                    ):
                        events.append(
                            (rec_time(int(t)) + 2_000_001, 4, topic, KeyValue(key=key, value=value))
                        )
        if include_imu:
            for i, t in enumerate(spec.t_acc):
                msg = _imu(store, i, int(t), accel=spec.acc[i])
                events.append((rec_time(int(t)) + 300_000, 2, f"{imu_s}/Accel_0/imu/data", msg))
            for i, t in enumerate(spec.t_gyr):
                garbled = 3_600 * 10**9 if fault == "imu_stamp_garbled" and i == 12 else 0
                msg = _imu(store, i, int(t) + garbled, gyro=spec.gyr[i])
                events.append((rec_time(int(t)) + 300_000, 3, f"{imu_s}/Gyro_0/imu/data", msg))
        events.sort(key=lambda e: (e[0], e[1]))
        types = {"image": "sensor_msgs/msg/Image", "imu": "sensor_msgs/msg/Imu"}
        cut_done = False
        for t_rec, _, topic, msg in events:
            if topic.endswith("/metadata"):
                write(topic, "diagnostic_msgs/msg/KeyValue", max(t_rec, 1), msg)
                continue
            msgtype = types[topic.split("/")[-2]]
            if fault == "color_payload_cut" and "Color" in topic and not cut_done:
                cut_done = True
                if topic not in conns:
                    conns[topic] = writer.add_connection(topic, msgtype, typestore=store)
                raw = store.serialize_ros1(msg, msgtype)
                writer.write(conns[topic], max(t_rec, 1), raw[: len(raw) // 2])
                continue
            write(topic, msgtype, max(t_rec, 1), msg)
    return spec


FAULTS = (
    "color_size_change",
    "depth_size_change",
    "imu_spike",
    "imu_nan",
    "imu_stamp_garbled",
    "tf_nan",
    "tf_zero_quaternion",
    "intrinsics_nan",
    "distortion_inf",
    "depth_units_nan",
    "color_stamp_garbled",
    "color_stamp_nsec",
    "color_data_short",
    "color_data_long",
    "color_step_short",
    "color_encoding_change",
    "color_payload_cut",
)
"""Damages :func:`write_sdk_bag` can build into a bag (each must make the reader refuse it)."""


def _Intr(c: CameraIntrinsics, **changes) -> SimpleNamespace:
    """Intrinsics-like values that may be invalid (CameraIntrinsics itself refuses NaN)."""
    fields = {f: getattr(c, f) for f in ("width", "height", "fx", "fy", "cx", "cy", "distortion")}
    return SimpleNamespace(**(fields | changes))


def bag_header_fields(path: Path) -> tuple[int, int, dict[bytes, bytes]]:
    """(start, end) byte range of the bag header record's fields and the fields themselves."""
    data = path.read_bytes()
    pos = data.index(b"\n") + 1  # after "#ROSBAG V2.0\n"
    (header_len,) = struct.unpack_from("<I", data, pos)
    fields: dict[bytes, bytes] = {}
    p = pos + 4
    while p < pos + 4 + header_len:
        (n,) = struct.unpack_from("<I", data, p)
        name, _, value = data[p + 4 : p + 4 + n].partition(b"=")
        fields[name] = value
        p += 4 + n
    return pos + 4, pos + 4 + header_len, fields


@dataclass(frozen=True)
class ChunkRecord:
    """Where a CHUNK record of a bag file lies: the record's byte offset (what error messages
    name), the offset of its header's 4-byte ``size`` value and of its (compressed) data."""

    pos: int
    size_at: int
    data_at: int
    data_len: int


def chunk_records(path: Path) -> list[ChunkRecord]:
    """The bag's CHUNK records in file order (a walk over its top-level records)."""
    data = path.read_bytes()
    pos = data.index(b"\n") + 1  # after "#ROSBAG V2.0\n"
    chunks = []
    while pos < len(data):
        (header_len,) = struct.unpack_from("<I", data, pos)
        header = data[pos + 4 : pos + 4 + header_len]
        (data_len,) = struct.unpack_from("<I", data, pos + 4 + header_len)
        fields, p = {}, 0
        while p < header_len:
            (n,) = struct.unpack_from("<I", header, p)
            name, _, _ = header[p + 4 : p + 4 + n].partition(b"=")
            fields[name] = pos + 4 + p + 4 + len(name) + 1  # where the value starts
            p += 4 + n
        if data[fields[b"op"]] == 5:  # CHUNK
            data_at = pos + 8 + header_len
            chunks.append(ChunkRecord(pos, fields[b"size"], data_at, data_len))
        pos += 8 + header_len + data_len
    return chunks


def unindex_bag(path: Path) -> Path:
    """Make ``path`` look like a recording that was cut off: no index, index_pos = 0.

    rosbag writes the connection and chunk-info records at the end and then fills in
    ``index_pos`` in the bag header; a killed recorder leaves ``index_pos`` 0 and no index.
    """
    data = bytearray(path.read_bytes())
    start, end, fields = bag_header_fields(path)
    (index_pos,) = struct.unpack("<Q", fields[b"index_pos"])
    at = data.index(b"index_pos=", start, end) + len(b"index_pos=")
    data[at : at + 8] = struct.pack("<Q", 0)
    path.write_bytes(bytes(data[:index_pos]))
    return path


def write_empty_bag(path: Path) -> Path:
    """A valid bag with one connection and no messages."""
    store = get_typestore(Stores.ROS1_NOETIC)
    with Writer(path) as writer:
        writer.add_connection("/file_version", "std_msgs/msg/UInt32", typestore=store)
    return path
