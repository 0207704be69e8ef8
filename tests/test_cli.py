"""Smoke tests of the ``gaitnet`` command through a real subprocess."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from oneline import assert_one_line_exit

import gaitnet
from gaitnet.io import open_session


def run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "gaitnet.cli", *args], capture_output=True, text=True, timeout=300
    )


def test_help_lists_commands() -> None:
    result = run("--help")
    assert result.returncode == 0
    for command in ["check", "convert"]:
        assert command in result.stdout


def test_version() -> None:
    result = run("--version")
    assert result.returncode == 0 and gaitnet.__version__ in result.stdout


def test_check_reports_a_good_session(tiny_session: Path) -> None:
    result = run("check", str(tiny_session), "--decode")
    assert result.returncode == 0, result.stderr
    assert "frames    4" in result.stdout and "ok: every frame decoded" in result.stdout


def test_check_truncated_png_one_line(tiny_session: Path) -> None:
    path = sorted((tiny_session / "color").iterdir())[0]
    path.write_bytes(path.read_bytes()[:100])
    result = run("check", str(tiny_session))
    assert_one_line_exit(result.stderr, result.returncode, str(path), "truncated PNG")


def test_check_wrong_depth_size_one_line(tiny_session: Path) -> None:
    import numpy as np

    from gaitnet.io.images import encode_png

    path = sorted((tiny_session / "depth").iterdir())[1]
    path.write_bytes(encode_png(np.zeros((10, 10), np.uint16)))
    result = run("check", str(tiny_session))
    assert_one_line_exit(result.stderr, result.returncode, str(path), "expected 32×24")


def test_check_unsorted_imu_one_line(tiny_session: Path) -> None:
    path = tiny_session / "imu.csv"
    lines = path.read_text().splitlines()
    lines[2], lines[3] = lines[3], lines[2]
    path.write_text("\n".join(lines) + "\n")
    result = run("check", str(tiny_session))
    assert_one_line_exit(result.stderr, result.returncode, str(path), "unsorted timestamps")


def test_convert_folder_to_folder(tiny_session: Path, tmp_path: Path) -> None:
    out = tmp_path / "converted"
    result = run("convert", str(tiny_session), str(out))
    assert result.returncode == 0, result.stderr
    assert (out / "imu.csv").read_bytes() == (tiny_session / "imu.csv").read_bytes()
    again = run("convert", str(tiny_session), str(out))
    assert_one_line_exit(again.stderr, again.returncode, "output exists and is not empty")


def test_convert_adds_the_sheets_of_a_board_file(tiny_session: Path, tmp_path: Path) -> None:
    """``convert --board``: the entry ``gaitnet tags`` prints goes into session.yaml (read
    back as the sheet it describes); a board file that does not parse, a name the session has
    already, or no file at all is one line naming the file (and the key), and nothing is
    written."""
    tags = run("tags", "--out", str(tmp_path / "s.png"), "--paper", "a4", "--rows", "5",
               "--cols", "3", "--dpi", "60", "--name", "end", "--first-id", "100")  # fmt: skip
    board = tmp_path / "board.yaml"
    board.write_text(tags.stdout.split("lies):\n", 1)[1])
    out = tmp_path / "with-sheet"
    result = run("convert", str(tiny_session), str(out), "--board", str(board))
    assert result.returncode == 0, result.stderr
    before = open_session(tiny_session).calibration.apriltag_boards
    *kept, sheet = open_session(out).calibration.apriltag_boards
    assert [b.name for b in kept] == [b.name for b in before]
    assert (sheet.name, sheet.rows, sheet.cols, sheet.first_id) == ("end", 5, 3, 100)
    assert sheet.tag_size_m == 0.04
    bad = tmp_path / "bad.yaml"
    bad.write_text(board.read_text().replace("cols:", "colls:"))
    again = run("convert", str(tiny_session), str(tmp_path / "x"), "--board", str(bad))
    assert_one_line_exit(again.stderr, again.returncode, str(bad), "apriltag_boards[0].colls")
    twice = run("convert", str(out), str(tmp_path / "y"), "--board", str(board))
    assert_one_line_exit(twice.stderr, twice.returncode, str(board), "named 'end'")
    none = run("convert", str(tiny_session), str(tmp_path / "z"), "--board", str(tmp_path / "n"))
    assert_one_line_exit(none.stderr, none.returncode, str(tmp_path / "n"), "not found")
    assert not any((tmp_path / d).exists() for d in ("x", "y", "z"))


def test_convert_bag_to_folder(tmp_path: Path) -> None:
    from bagfactory import write_sdk_bag

    spec = write_sdk_bag(tmp_path / "walk.bag", n_frames=4)
    out = tmp_path / "walk"
    result = run("convert", str(spec.path), str(out))
    assert result.returncode == 0, result.stderr
    assert "INFO" not in result.stderr  # quiet on success; -v tells what each stage does
    checked = run("check", str(out), "--decode")
    assert checked.returncode == 0 and "frames    4" in checked.stdout
    verbose = run("-v", "convert", str(spec.path), str(tmp_path / "again"))
    assert verbose.returncode == 0 and "INFO gaitnet" in verbose.stderr


def test_check_garbage_bag_one_line(tmp_path: Path) -> None:
    path = tmp_path / "broken.bag"
    path.write_bytes(b"#ROSBAG V2.0\n" + b"\x00" * 50)
    result = run("check", str(path))
    assert_one_line_exit(result.stderr, result.returncode, str(path))


def test_simulate_unknown_config_key_one_line(tmp_path: Path) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("scene:\n  floor_famly: wood\n")
    result = run("simulate", "--config", str(bad), "--out", str(tmp_path / "o"))
    assert_one_line_exit(
        result.stderr, result.returncode, str(bad), "unknown key 'scene.floor_famly'"
    )
    result = run("simulate", "--out", str(tmp_path / "o"), "camera.width=wide")
    assert_one_line_exit(
        result.stderr, result.returncode, "key 'camera.width' expects int, got 'wide'"
    )


def _popen_simulate(config: Path, tmp_path: Path) -> subprocess.Popen:
    return subprocess.Popen(
        [
            sys.executable,
            "-m",
            "gaitnet.cli",
            "simulate",
            "--config",
            str(config),
            "--out",
            str(tmp_path / "sim"),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,  # its own process group, as in a terminal
    )


@pytest.mark.parametrize(
    ("signame", "delay_s", "returncode", "last_line"),
    [
        ("SIGTERM", 0.3, 143, "gaitnet simulate: terminated"),
        ("SIGTERM", 0.0, 143, "gaitnet simulate: terminated"),  # workers starting
        ("SIGINT", 0.0, 130, "gaitnet simulate: interrupted"),
        ("SIGINT", 1.0, 130, "gaitnet simulate: interrupted"),
    ],
)
def test_signal_during_simulate_cleans_up(
    tmp_path: Path, signame: str, delay_s: float, returncode: int, last_line: str
) -> None:
    """SIGTERM to the process, or Ctrl-C (SIGINT to its whole process group, the worker
    processes and their forkserver included), while workers start or frames render: exit
    143 / 130, the CLI's one line last, no traceback from any process, no output and no
    staging folder left behind (the signal arrives as KeyboardInterrupt, so cleanup runs)."""
    import os
    import signal
    import time

    config = Path(__file__).parents[1] / "configs" / "sim" / "default.yaml"
    # a shell's background job ignores SIGINT and its children inherit that; as from a
    # terminal, the CLI must start with SIGINT handled
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        proc = _popen_simulate(config, tmp_path)
    finally:
        signal.signal(signal.SIGINT, previous)
    deadline = time.monotonic() + 120
    while not any(p.name.startswith(".") for p in tmp_path.iterdir()):  # staging folder
        assert proc.poll() is None and time.monotonic() < deadline, "never started writing"
        time.sleep(0.02)
    time.sleep(delay_s)
    if signame == "SIGINT":
        os.killpg(proc.pid, signal.SIGINT)
    else:
        proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == returncode, err
    assert err.strip().splitlines()[-1] == last_line, err
    assert "Traceback" not in err
    time.sleep(0.5)  # a worker or forkserver that outlived the CLI would still be writing
    assert list(tmp_path.iterdir()) == []


def test_a_progress_bar_stopped_while_being_built_is_forgotten_not_closed() -> None:
    """A signal inside ``tqdm.__init__`` leaves a bar registered but without a position:
    the interrupt's cleanup drops it instead of raising AttributeError from ``close``."""
    from tqdm import tqdm

    from gaitnet.cli import _end_progress_bars

    half_built = tqdm.__new__(tqdm)  # registered by __new__, as before __init__ is stopped
    assert half_built in tqdm._instances and not hasattr(half_built, "pos")
    _end_progress_bars()
    assert half_built not in tqdm._instances


@pytest.mark.parametrize("inferred", [0, 2])
def test_the_gait_table_aligns_and_counts_the_strides_through_unseen_stances(
    inferred: int, capsys: pytest.CaptureFixture[str]
) -> None:
    """``gaitnet infer``'s table: every row's columns start where the header's do, and a line
    counts the strides through a stance laid from the step rhythm only when there are some."""
    from gaitnet.cli.commands import _print_gait_summary

    stat = {"mean": 1.3, "sd": 0.01, "n": 3}
    _print_gait_summary({"left": {"n_strides": 3, "n_inferred": inferred, "stride_length_m": stat},
                         "right": {"n_strides": 0}, "symmetry_index_pct": {}})  # fmt: skip
    lines = capsys.readouterr().out.splitlines()
    assert {len(line) for line in lines[1:15]} == {len(lines[0])}  # long labels too
    assert "1.300 ± 0.010" in lines[1]
    counted = [line for line in lines if "never saw" in line]
    assert counted == ([f"strides through a stance the camera never saw, laid from the rhythm "
                        f"of the steps: {inferred} (gait_strides.csv: inferred)"]
                       if inferred else [])  # fmt: skip
