"""Session folder v1: round trips through the writer/reader and clear errors on broken input."""

from __future__ import annotations

import logging
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml
from sessionfactory import HEIGHT, WIDTH, make_tiny_session, tiny_calibration, tiny_frames, tiny_imu

from gaitnet.errors import InputError, SessionError
from gaitnet.io import SessionFolder, SessionWriter, copy_session, open_session


def test_round_trip_is_exact(tiny_session: Path) -> None:
    session = SessionFolder(tiny_session)
    expected = tiny_frames()
    assert len(session) == len(expected)
    np.testing.assert_array_equal(session.frame_times_ns, [t for t, _, _ in expected])
    for frame, (t_ns, rgb, depth) in zip(session.frames(), expected, strict=True):
        assert frame.t_ns == t_ns
        np.testing.assert_array_equal(frame.rgb, rgb)
        assert frame.depth_m.dtype == np.float32
        np.testing.assert_allclose(frame.depth_m, depth, atol=1e-6)
        assert (frame.depth_m[0] == 0).all()
    imu = tiny_imu()
    np.testing.assert_array_equal(session.imu.t_ns, imu.t_ns)
    np.testing.assert_allclose(session.imu.accel, imu.accel, rtol=1e-8)
    np.testing.assert_allclose(session.imu.gyro, imu.gyro, rtol=1e-8, atol=1e-12)
    calib, ref = session.calibration, tiny_calibration()
    assert calib.color == ref.color and calib.imu_noise == ref.imu_noise
    np.testing.assert_allclose(calib.T_CfromI, ref.T_CfromI)
    board = calib.apriltag_boards[0]
    assert board.tag_centre_in_board(7) == pytest.approx([0.124, 0.072, 0.0])


def test_frames_read_ahead_keeps_order_errors_and_stops_its_thread(tiny_session: Path) -> None:
    """``frames()`` decodes ahead in a thread: the same frames as ``frame(i)``; a frame that
    became unreadable after opening raises when it is reached, after the frames before it;
    closing the iterator early leaves no reading thread behind."""
    import threading

    session = SessionFolder(tiny_session)
    assert len(session) > 3
    for i, frame in enumerate(session.frames()):
        np.testing.assert_array_equal(frame.rgb, session.frame(i).rgb)
    it = session.frames()
    next(it)
    it.close()
    assert not [t for t in threading.enumerate() if t.name.startswith("gaitnet-read")]
    broken = sorted((tiny_session / "color").iterdir())[2]
    broken.write_bytes(b"not a png")
    seen = []
    with pytest.raises(SessionError, match=broken.name):
        for frame in session.frames():
            seen.append(frame.index)
    assert seen == [0, 1]
    assert not [t for t in threading.enumerate() if t.name.startswith("gaitnet-read")]


def test_frames_load_lazily(tiny_session: Path) -> None:
    session = open_session(tiny_session)
    (tiny_session / "color" / f"{session.frame_times_ns[2]}.png").write_bytes(
        (tiny_session / "color" / f"{session.frame_times_ns[1]}.png").read_bytes()
    )
    # The swapped file is only read when frame 2 is requested.
    np.testing.assert_array_equal(session.frame(2).rgb, session.frame(1).rgb)
    assert session.frame(-1).index == len(session) - 1
    with pytest.raises(IndexError):
        session.frame(len(session))


def test_same_content_gives_identical_bytes(tmp_path: Path) -> None:
    a = make_tiny_session(tmp_path / "a")
    b = make_tiny_session(tmp_path / "b")
    files = sorted(p.relative_to(a) for p in a.rglob("*") if p.is_file())
    assert files == sorted(p.relative_to(b) for p in b.rglob("*") if p.is_file())
    for rel in files:
        assert (a / rel).read_bytes() == (b / rel).read_bytes(), rel


def test_copy_session_round_trip(tiny_session: Path, tmp_path: Path) -> None:
    out = copy_session(SessionFolder(tiny_session), tmp_path / "copy")
    for name in ["session.yaml", "imu.csv"]:
        assert (out / name).read_bytes() == (tiny_session / name).read_bytes()


def test_truncated_png_is_named(tiny_session: Path) -> None:
    path = sorted((tiny_session / "color").iterdir())[1]
    path.write_bytes(path.read_bytes()[:-40])
    with pytest.raises(SessionError, match=rf"{path.name}: truncated PNG"):
        SessionFolder(tiny_session)


def test_corrupt_png_fails_on_decode_when_headers_unchecked(tiny_session: Path) -> None:
    path = sorted((tiny_session / "depth").iterdir())[0]
    data = bytearray(path.read_bytes())
    data[60:80] = b"\x00" * 20
    path.write_bytes(bytes(data))
    session = SessionFolder(tiny_session, check_headers=False)
    with pytest.raises(SessionError, match=rf"{path.name}: cannot decode depth"):
        session.frame(0)


def test_depth_of_wrong_size_is_named(tiny_session: Path) -> None:
    from gaitnet.io.images import encode_png

    path = sorted((tiny_session / "depth").iterdir())[2]
    path.write_bytes(encode_png(np.ones((HEIGHT, WIDTH + 1), np.uint16)))
    with pytest.raises(SessionError, match=rf"{path.name}: image is 33×24, expected 32×24"):
        SessionFolder(tiny_session)


def test_colour_saved_as_depth_type_is_named(tiny_session: Path) -> None:
    from gaitnet.io.images import encode_png

    path = sorted((tiny_session / "depth").iterdir())[0]
    path.write_bytes(encode_png(np.zeros((HEIGHT, WIDTH, 3), np.uint8)))
    with pytest.raises(SessionError, match="3-channel 8-bit PNG, expected 1-channel 16-bit"):
        SessionFolder(tiny_session)


def test_missing_depth_frame_is_named(tiny_session: Path) -> None:
    path = sorted((tiny_session / "depth").iterdir())[3]
    path.unlink()
    with pytest.raises(SessionError, match="no depth frame with the same timestamp"):
        SessionFolder(tiny_session)


def _rewrite_imu(root: Path, edit) -> Path:
    path = root / "imu.csv"
    lines = path.read_text().splitlines()
    path.write_text("\n".join(edit(lines)) + "\n")
    return path


def test_unsorted_imu_is_named(tiny_session: Path) -> None:
    def swap(lines):
        lines[5], lines[6] = lines[6], lines[5]
        return lines

    path = _rewrite_imu(tiny_session, swap)
    with pytest.raises(SessionError, match=rf"{path.name}: unsorted timestamps at line 7"):
        SessionFolder(tiny_session)


def test_duplicate_imu_timestamp_is_named(tiny_session: Path) -> None:
    _rewrite_imu(tiny_session, lambda lines: lines[:4] + [lines[3]] + lines[4:])
    with pytest.raises(SessionError, match="duplicate timestamps at line 5"):
        SessionFolder(tiny_session)


def test_imu_gap_warns_then_errors(tiny_session: Path, caplog) -> None:
    _rewrite_imu(tiny_session, lambda lines: lines[:10] + lines[20:])
    with caplog.at_level(logging.WARNING):
        SessionFolder(tiny_session)
    assert "1 IMU gap(s) longer than 0.025 s, the longest 0.055 s" in caplog.text
    with pytest.raises(SessionError, match="IMU gap of 0.055 s"):
        SessionFolder(tiny_session, imu_gap_error_s=0.05)


def test_nan_in_imu_is_named(tiny_session: Path) -> None:
    def poison(lines):
        parts = lines[7].split(",")
        parts[3] = "nan"
        lines[7] = ",".join(parts)
        return lines

    _rewrite_imu(tiny_session, poison)
    with pytest.raises(SessionError, match="non-finite IMU value at line 8"):
        SessionFolder(tiny_session)


def test_bad_session_yaml_key_is_named(tiny_session: Path) -> None:
    path = tiny_session / "session.yaml"
    data = yaml.safe_load(path.read_text())
    data["color"]["fxx"] = 1.0
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(SessionError, match=r"session.yaml: unknown key 'color.fxx'"):
        SessionFolder(tiny_session)


def test_non_rigid_extrinsic_is_rejected(tiny_session: Path) -> None:
    path = tiny_session / "session.yaml"
    data = yaml.safe_load(path.read_text())
    data["T_CfromI"][0][0] = 2.0
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(SessionError, match="T_CfromI is not a rigid transform"):
        SessionFolder(tiny_session)


def test_writer_is_atomic_and_refuses_to_clobber(tmp_path: Path) -> None:
    root = tmp_path / "out"
    with pytest.raises(RuntimeError), SessionWriter(root, tiny_calibration()) as writer:
        t_ns, rgb, depth = tiny_frames(1)[0]
        writer.add_frame(t_ns, rgb, depth)
        raise RuntimeError("interrupted")
    assert not root.exists()
    assert list(tmp_path.iterdir()) == []
    make_tiny_session(root)
    with pytest.raises(InputError, match="output exists and is not empty"):
        make_tiny_session(root)
    (tmp_path / "file").write_text("x")
    with pytest.raises(InputError, match="exists and is not a folder"):
        SessionWriter(tmp_path / "file", tiny_calibration(), overwrite=True)


def test_open_session_rejects_unknown_path(tmp_path: Path) -> None:
    with pytest.raises(SessionError, match="no such session folder"):
        open_session(tmp_path / "nothing")
    (tmp_path / "x.txt").write_text("hi")
    with pytest.raises(SessionError, match="not a session folder or a .bag"):
        open_session(tmp_path / "x.txt")


def test_writer_refuses_wrong_data_with_session_errors(tmp_path: Path) -> None:
    t_ns, rgb, depth = tiny_frames(1)[0]
    root = tmp_path / "out"
    bad_calls = [
        (lambda w: w.add_frame(t_ns, rgb[:, :-1], depth), "colour must be uint8 (24, 32, 3)"),
        (lambda w: w.add_frame(t_ns, rgb.astype(np.float32), depth), "colour must be uint8"),
        (lambda w: w.add_frame(t_ns, rgb, depth[:-1]), "depth must be float metres (24, 32)"),
        (lambda w: w.add_frame(t_ns, rgb, (depth * 1000).astype(np.uint16)), "float metres"),
        (lambda w: w.add_frame(2**63, rgb, depth), "outside [0, 2**63)"),
        (lambda w: w.add_frame(1.5, rgb, depth), "must be integer ns"),
        (lambda w: (w.add_frame(t_ns, rgb, depth), w.add_frame(t_ns, rgb, depth)), "increase"),
    ]
    for call, fragment in bad_calls:
        with pytest.raises(SessionError) as excinfo, SessionWriter(root, tiny_calibration()) as w:
            call(w)
        assert fragment in str(excinfo.value) and str(root) in str(excinfo.value)
        assert list(tmp_path.iterdir()) == []  # staging removed, nothing published
    imu = tiny_imu()
    imu.accel[3, 0] = np.nan
    calib = tiny_calibration()
    with pytest.raises(SessionError, match="non-finite IMU value at sample 3"):
        SessionWriter(root, calib).set_imu(imu)
    for path in tmp_path.iterdir():  # the writer above was never closed: drop its staging
        shutil.rmtree(path)
    writer = SessionWriter(root, calib)
    writer.add_frame(t_ns, rgb, depth)
    with pytest.raises(SessionError, match="no IMU stream was set"):
        writer.close()
    assert list(tmp_path.iterdir()) == []


def test_overwrite_replaces_the_session_in_one_swap(tmp_path: Path) -> None:
    root = make_tiny_session(tmp_path / "s", n_frames=4)
    with SessionWriter(root, tiny_calibration(), overwrite=True) as writer:
        for t_ns, rgb, depth in tiny_frames(2):
            writer.add_frame(t_ns, rgb, depth)
        writer.set_imu(tiny_imu())
    assert len(SessionFolder(root)) == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s"]


def test_calibration_types_validate_and_round_trip(tmp_path: Path) -> None:
    from gaitnet.io.session_yaml import read_session_yaml, session_yaml_text
    from gaitnet.io.types import AprilTagBoard, CameraIntrinsics, ImuNoise, SessionCalibration

    calib = tiny_calibration()
    (tmp_path / "session.yaml").write_text(session_yaml_text(calib))
    back = read_session_yaml(tmp_path / "session.yaml")
    assert session_yaml_text(back) == session_yaml_text(calib)
    assert back.color == calib.color and back.imu_noise == calib.imu_noise
    np.testing.assert_array_equal(back.apriltag_boards[0].T_WfromBoard, np.eye(4))
    # numpy scalars are normalised, so they serialise like literals
    cam = CameraIntrinsics(np.int64(32), 24, np.float64(30.0), 30.0, np.float32(15.5), 11.5)
    assert cam == calib.color and type(cam.width) is int and type(cam.fx) is float
    for kwargs, fragment in [
        (dict(fx=float("nan")), "fx must be a finite number"),
        (dict(width=0), "width must be an integer of at least 1"),
        (dict(width=32.0), "width must be an integer"),
        (dict(cy=float("inf")), "cy must be a finite number"),
        (dict(distortion=(0.0, float("nan"))), "distortion[1] must be a finite number"),
    ]:
        args = dict(width=32, height=24, fx=30.0, fy=30.0, cx=15.5, cy=11.5) | kwargs
        with pytest.raises(ValueError) as excinfo:
            CameraIntrinsics(**args)
        assert fragment in str(excinfo.value)
    with pytest.raises(ValueError, match="gyro_noise_density must be at least 0"):
        ImuNoise(-1.0, 0.0, 0.0, 0.0)
    with pytest.raises(ValueError, match="accel_bias_random_walk must be a finite number"):
        ImuNoise(0.0, 0.0, 0.0, float("nan"))
    reflection = np.diag([1.0, 1.0, -1.0, 1.0])
    with pytest.raises(ValueError, match="T_WfromBoard is not a rigid transform"):
        AprilTagBoard("b", "tag36h11", 2, 2, 0.04, 0.01, 0, reflection)
    board = calib.apriltag_boards[0]
    for kwargs, fragment in [
        (dict(depth_scale_m=float("nan")), "depth_scale_m must be a finite number"),
        (dict(depth_scale_m=-0.001), "depth_scale_m must be positive"),
        (dict(T_CfromI=np.full((4, 4), np.nan)), "T_CfromI must be finite"),
        (dict(apriltag_boards=(board, board)), "two AprilTag boards are named 'start'"),
        (dict(extra={"x": float("inf")}), "extra.x must be a finite number"),
        (dict(extra={"x": object()}), "extra.x must be plain data"),
    ]:
        with pytest.raises(ValueError) as excinfo:
            SessionCalibration(**(vars(calib) | kwargs))
        assert fragment in str(excinfo.value)


def test_tag_corners_follow_the_aruco_order() -> None:
    from gaitnet.io.types import tag_corners_in_board

    board = tiny_calibration().apriltag_boards[0]  # 5 columns, 40 mm tags, 12 mm gaps
    corners = tag_corners_in_board(board, 6)  # row 1, column 1: centre (0.072, 0.072)
    np.testing.assert_allclose(
        corners,
        [[0.052, 0.092, 0], [0.092, 0.092, 0], [0.092, 0.052, 0], [0.052, 0.052, 0]],
        atol=1e-12,
    )
    with pytest.raises(KeyError):
        tag_corners_in_board(board, 35)


def test_interrupt_while_the_writer_is_built_leaves_nothing(tmp_path, monkeypatch) -> None:
    """A signal (arriving as KeyboardInterrupt) after the staging folder exists but before the
    caller holds the writer removes the staging folder: nothing is left beside the output."""
    import gaitnet.io.session_folder as session_folder

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(session_folder, "ThreadPoolExecutor", interrupted)
    with pytest.raises(KeyboardInterrupt):
        SessionWriter(tmp_path / "out", tiny_calibration(), encode_threads=2)
    assert list(tmp_path.iterdir()) == []
