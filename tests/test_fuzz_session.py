"""Fuzz the session-folder input: broken folders → ``gaitnet check`` / ``convert`` exit 1 with
one line naming the broken file, no traceback and nothing written; valid folders still pass.

Each case starts from a tiny valid session (``sessionfactory``) and breaks one thing.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

import pytest
import yaml
from oneline import assert_one_line_exit
from sessionfactory import make_tiny_session

from gaitnet.cli import main
from gaitnet.io import SessionFolder


def _yaml_edit(edit: Callable[[dict], None]) -> Callable[[Path], Path]:
    def build(root: Path) -> Path:
        path = root / "session.yaml"
        data = yaml.safe_load(path.read_text())
        edit(data)
        path.write_text(yaml.safe_dump(data, sort_keys=False))
        return path

    return build


def _set(*keys, value) -> Callable[[dict], None]:
    def edit(data: dict) -> None:
        node = data
        for key in keys[:-1]:
            node = node[key]
        node[keys[-1]] = value

    return edit


def _write(name: str, content: bytes) -> Callable[[Path], Path]:
    def build(root: Path) -> Path:
        (root / name).write_bytes(content)
        return root / name

    return build


def _imu_line(line: int, text: str) -> Callable[[Path], Path]:
    """Replace line ``line`` (1-based, 1 = header) of imu.csv with ``text``."""

    def build(root: Path) -> Path:
        path = root / "imu.csv"
        lines = path.read_bytes().split(b"\n")
        lines[line - 1] = text.encode("utf-8", "surrogateescape")
        path.write_bytes(b"\n".join(lines))
        return path

    return build


def _imu_bytes(line: int, raw: bytes) -> Callable[[Path], Path]:
    def build(root: Path) -> Path:
        path = root / "imu.csv"
        lines = path.read_bytes().split(b"\n")
        lines[line - 1] = raw
        path.write_bytes(b"\n".join(lines))
        return path

    return build


def _frame(folder: str, k: int) -> Callable[[Path], Path]:
    """The path of frame ``k`` of ``color`` or ``depth``."""
    return lambda root: sorted((root / folder).iterdir())[k]


def _truncate_frame(root: Path) -> Path:
    path = _frame("color", 1)(root)
    path.write_bytes(path.read_bytes()[:-40])
    return path


def _empty_frame(root: Path) -> Path:
    path = _frame("depth", 2)(root)
    path.write_bytes(b"")
    return path


def _huge_timestamp_frame(root: Path) -> Path:
    big = f"{2**64}.png"
    for folder in ("color", "depth"):
        _frame(folder, 0)(root).rename(root / folder / big)
    return root / "color" / big


def _symlink_out(name: str) -> Callable[[Path], Path]:
    def build(root: Path) -> Path:
        folder, _, k = name.partition("/")
        path = _frame(folder, int(k))(root) if k else root / name
        outside = root.parent / f"outside-{path.name}"
        path.rename(outside)
        path.symlink_to(outside)
        return path

    return build


def _symlink_loop(root: Path) -> Path:
    """Frame 1 of ``color`` replaced by a link to itself."""
    path = _frame("color", 1)(root)
    path.unlink()
    path.symlink_to(path.name)
    return path


def _remove(name: str) -> Callable[[Path], Path]:
    def build(root: Path) -> Path:
        path = root / name
        if path.is_dir():
            for child in path.iterdir():
                child.unlink()
            path.rmdir()
        else:
            path.unlink()
        return path

    return build


def _yaml_is_folder(root: Path) -> Path:
    (root / "session.yaml").unlink()
    (root / "session.yaml").mkdir()
    return root / "session.yaml"


NAN, INF = float("nan"), float("inf")
BROKEN: dict[str, Callable[[Path], Path]] = {
    # session.yaml: every value checked where it enters (the types' __post_init__)
    "depth_scale_nan": _yaml_edit(_set("depth_scale_m", value=NAN)),
    "depth_scale_inf": _yaml_edit(_set("depth_scale_m", value=INF)),
    "depth_scale_zero": _yaml_edit(_set("depth_scale_m", value=0.0)),
    "fx_nan": _yaml_edit(_set("color", "fx", value=NAN)),
    "fy_negative": _yaml_edit(_set("depth", "fy", value=-30.0)),
    "width_zero": _yaml_edit(_set("color", "width", value=0)),
    "distortion_inf": _yaml_edit(_set("color", "distortion", value=[INF, 0, 0, 0, 0])),
    "imu_noise_nan": _yaml_edit(_set("imu_noise", "gyro_noise_density", value=NAN)),
    "imu_noise_negative": _yaml_edit(_set("imu_noise", "accel_bias_random_walk", value=-1e-4)),
    "T_CfromI_nan": _yaml_edit(_set("T_CfromI", 0, 3, value=NAN)),
    "T_CfromI_reflection": _yaml_edit(_set("T_CfromI", 2, 2, value=-1.0)),
    "T_CfromI_3x3": _yaml_edit(_set("T_CfromI", value=[[1, 0, 0], [0, 1, 0], [0, 0, 1]])),
    "board_rows_zero": _yaml_edit(_set("apriltag_boards", 0, "rows", value=0)),
    "board_pose_nan": _yaml_edit(_set("apriltag_boards", 0, "T_WfromBoard", 1, 3, value=NAN)),
    "board_family_unsupported": _yaml_edit(_set("apriltag_boards", 0, "family", value="tag25h9")),
    "unknown_key": _yaml_edit(_set("colour", value={})),
    "missing_key": _yaml_edit(lambda data: data.pop("depth")),
    "wrong_type": _yaml_edit(_set("depth_aligned_to_color", value="yes")),
    "format_version_2": _yaml_edit(_set("format_version", value=2)),
    "yaml_not_utf8": _write("session.yaml", b"format_version: 1\ndevice: \xff\xfe\n"),
    "yaml_empty": _write("session.yaml", b""),
    "yaml_list": _write("session.yaml", b"- 1\n- 2\n"),
    "yaml_syntax": _write("session.yaml", b"format_version: [1\n"),
    "yaml_deeply_nested": _write(
        "session.yaml", b"format_version: 1\nextra: " + b"[" * 5000 + b"]" * 5000 + b"\n"
    ),
    "yaml_is_a_folder": _yaml_is_folder,
    "yaml_missing": _remove("session.yaml"),
    # imu.csv
    "imu_timestamp_beyond_int64": _imu_line(5, f"{2**63},0,0,9.8,0,0,0"),
    "imu_timestamp_negative": _imu_line(2, "-5,0,0,9.8,0,0,0"),
    "imu_not_utf8": _imu_bytes(4, b"995000000,0.1,\xff,9.81,0,0,0"),
    "imu_nan": _imu_line(6, "1015000000,nan,0,9.8,0,0,0"),
    "imu_inf": _imu_line(6, "1015000000,0,0,9.8,0,-inf,0"),
    "imu_impossible_value": _imu_line(6, "1015000000,0,0,1e30,0,0,0"),
    "imu_text_value": _imu_line(6, "1015000000,zero,0,9.8,0,0,0"),
    "imu_six_columns": _imu_line(6, "1015000000,0,0,9.8,0,0"),
    "imu_empty_file": _write("imu.csv", b""),
    "imu_header_only": _write("imu.csv", b"t_ns,ax,ay,az,gx,gy,gz\n"),
    "imu_missing": _remove("imu.csv"),
    # frames
    "frame_timestamp_beyond_int64": _huge_timestamp_frame,
    "frame_truncated_png": _truncate_frame,
    "frame_empty_png": _empty_frame,
    "depth_folder_missing": _remove("depth"),
    # symbolic links leading out of the session folder are refused
    "symlink_imu_outside": _symlink_out("imu.csv"),
    "symlink_yaml_outside": _symlink_out("session.yaml"),
    "symlink_frame_outside": _symlink_out("color/2"),
    "symlink_frame_loop": _symlink_loop,
}


@pytest.mark.parametrize("case", sorted(BROKEN))
def test_broken_session_is_one_line_and_writes_nothing(case, tmp_path, capsys):
    root = make_tiny_session(tmp_path / "session")
    broken = BROKEN[case](root)
    before = sorted(p.name for p in tmp_path.iterdir())
    rc = main(["check", str(root)])
    assert assert_one_line_exit(capsys, rc, str(broken)).startswith("gaitnet check: error: ")

    out = tmp_path / "out"
    rc = main(["convert", str(root), str(out)])
    assert_one_line_exit(capsys, rc, str(broken))
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # no output, no staging


def test_messages_name_the_key_and_the_problem(tmp_path, capsys):
    expected = {
        "depth_scale_nan": "depth_scale_m' must be a finite number",
        "fx_nan": "color.fx' must be a finite number",
        "fy_negative": "fy must be positive",
        "T_CfromI_reflection": "T_CfromI is not a rigid transform",
        "imu_noise_negative": "imu_noise",
        "imu_timestamp_beyond_int64": "line 5: timestamp '9223372036854775808' is not integer ns",
        "imu_not_utf8": "not UTF-8 text",
        "symlink_imu_outside": "symbolic link to",
        "symlink_frame_loop": "symbolic link loop",
        "board_family_unsupported": "apriltag_boards[0]: family 'tag25h9' cannot be decoded "
        "(supported: tag36h11)",
    }
    for case, fragment in expected.items():
        root = make_tiny_session(tmp_path / case)
        broken = BROKEN[case](root)
        rc = main(["check", str(root)])
        assert_one_line_exit(capsys, rc, str(broken), fragment)


def test_valid_sessions_still_pass(tmp_path, capsys):
    root = make_tiny_session(tmp_path / "session")
    assert main(["check", str(root), "--decode"]) == 0
    assert main(["convert", str(root), str(tmp_path / "copy")]) == 0
    for name in ("session.yaml", "imu.csv"):
        assert (tmp_path / "copy" / name).read_bytes() == (root / name).read_bytes()
    # a link that stays inside the folder is fine
    frame = sorted((root / "color").iterdir())[0]
    kept = root / "kept.png"
    frame.rename(kept)
    frame.symlink_to(os.path.relpath(kept, frame.parent))
    assert main(["check", str(root), "--decode"]) == 0
    assert len(SessionFolder(root)) == 4
    capsys.readouterr()
