"""Fuzz ``gaitnet evaluate`` with broken result folders, ground truth and ``--json`` targets.

Each generated broken input must give exit status 1, exactly one line on stderr, no traceback
and no JSON written; the valid result still evaluates to finite numbers. Runs the command
in-process (``gaitnet.cli.main``) with pytest's ``capsys`` on the shared simulated session.
"""

from __future__ import annotations

import json
import math
import shutil
import zipfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from oneline import assert_one_line_exit

from gaitnet.cli import main
from gaitnet.io.trajectory import read_tum, write_tum

# A warning would be a second line on a user's stderr: every one fails these tests.
pytestmark = [
    pytest.mark.filterwarnings("error::RuntimeWarning"),
    pytest.mark.filterwarnings("error::UserWarning"),
]


def _ground_truth(session: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    with np.load(session / "groundtruth" / "joints.npz") as data:
        t_ns, positions = data["t_ns"].copy(), data["positions"].copy()
    t, T = read_tum(session / "groundtruth" / "camera_frames.tum")
    return t_ns, positions, t, T


def _good_result(folder: Path, session: Path) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    t_ns, positions, t, T = _ground_truth(session)
    np.savez(folder / "joints.npz", t_ns=t_ns, positions=positions + [0.0, 0.01, 0.0])
    write_tum(folder / "camera_frames.tum", t, T)
    return folder


# Each case breaks a copy of a valid result folder (or its session); the name says how.
Breaker = Callable[[Path, Path], None]


def _joints(**arrays) -> Breaker:
    def brk(result: Path, session: Path) -> None:
        t_ns, positions, _, _ = _ground_truth(session)
        data = {"t_ns": t_ns, "positions": positions}
        data.update({k: (v(t_ns, positions) if callable(v) else v) for k, v in arrays.items()})
        data = {k: v for k, v in data.items() if v is not None}
        (result / "joints.npz").unlink()
        np.savez(result / "joints.npz", **data)

    return brk


def _with_nan(t_ns: np.ndarray, p: np.ndarray) -> np.ndarray:
    p = p.copy()
    p[len(p) // 2, 3, 1] = np.nan
    return p


def _write(name: str, content: bytes) -> Breaker:
    def brk(result: Path, session: Path) -> None:
        (result / name).write_bytes(content)

    return brk


def _truncate(name: str) -> Breaker:
    def brk(result: Path, session: Path) -> None:
        data = (result / name).read_bytes()
        (result / name).write_bytes(data[: len(data) // 2])

    return brk


def _tum_lines(edit: Callable[[list[str]], list[str]]) -> Breaker:
    """Edit the data lines of the (valid) result trajectory."""

    def brk(result: Path, session: Path) -> None:
        path = result / "camera_frames.tum"
        lines = [ln for ln in path.read_text().splitlines() if ln and not ln.startswith("#")]
        path.write_text("\n".join(edit(lines)) + "\n")

    return brk


def _set_field(row: int, col: int, value: str) -> Callable[[list[str]], list[str]]:
    def edit(lines: list[str]) -> list[str]:
        fields = lines[row].split()
        fields[col] = value
        lines[row] = " ".join(fields)
        return lines

    return edit


def _npy_as_npz(result: Path, session: Path) -> None:
    (result / "joints.npz").unlink()
    with open(result / "joints.npz", "wb") as handle:
        np.save(handle, np.zeros((3, 9, 3)))


def _zip_with_junk(result: Path, session: Path) -> None:
    (result / "joints.npz").unlink()
    with zipfile.ZipFile(result / "joints.npz", "w") as zf:
        zf.writestr("t_ns.npy", b"junk")
        zf.writestr("positions.npy", b"junk")


def _no_gt_joints(result: Path, session: Path) -> None:
    (session / "groundtruth" / "joints.npz").unlink()


def _nan_gt_trajectory(result: Path, session: Path) -> None:
    path = session / "groundtruth" / "camera_frames.tum"
    lines = path.read_text().splitlines()
    i = next(k for k, ln in enumerate(lines) if ln and not ln.startswith("#"))
    fields = lines[i].split()
    fields[2] = "nan"
    lines[i] = " ".join(fields)
    path.write_text("\n".join(lines) + "\n")


def _no_groundtruth(result: Path, session: Path) -> None:
    shutil.rmtree(session / "groundtruth")


def _result_is_file(result: Path, session: Path) -> None:
    shutil.rmtree(result)
    result.write_text("not a folder")


def _result_missing(result: Path, session: Path) -> None:
    shutil.rmtree(result)


def _empty_result(result: Path, session: Path) -> None:
    for f in result.iterdir():
        f.unlink()


def _joints_is_folder(result: Path, session: Path) -> None:
    (result / "joints.npz").unlink()
    (result / "joints.npz").mkdir()


CASES: dict[str, Breaker] = {
    "result_missing": _result_missing,
    "result_is_a_file": _result_is_file,
    "result_empty": _empty_result,
    "joints_garbage": _write("joints.npz", b"definitely not an npz"),
    "joints_empty_file": _write("joints.npz", b""),
    "joints_truncated": _truncate("joints.npz"),
    "joints_npy_not_npz": _npy_as_npz,
    "joints_zip_of_junk": _zip_with_junk,
    "joints_is_a_folder": _joints_is_folder,
    "joints_no_positions": _joints(positions=None),
    "joints_7_joints": _joints(positions=lambda t, p: p[:, :7]),
    "joints_rank_2": _joints(positions=lambda t, p: p.reshape(len(p), -1)),
    "joints_nan": _joints(positions=_with_nan),
    "joints_inf": _joints(positions=lambda t, p: np.where(p > 0.5, np.inf, p)),
    "joints_overflowing_values": _joints(positions=lambda t, p: p * 1e200 + 1e307),
    "joints_strings": _joints(positions=lambda t, p: p.astype(str)),
    "joints_object_array": _joints(positions=lambda t, p: np.array([object()] * len(p))),
    "joints_float_times": _joints(t_ns=lambda t, p: t.astype(float) + 0.5),
    "joints_times_2d": _joints(t_ns=lambda t, p: t[:, None]),
    "joints_length_mismatch": _joints(t_ns=lambda t, p: t[:-1]),
    "joints_no_frames": _joints(t_ns=lambda t, p: t[:0], positions=lambda t, p: p[:0]),
    "joints_times_match_nothing": _joints(t_ns=lambda t, p: t + 10**12),
    "joints_uint64_overflow": _joints(t_ns=lambda t, p: t.astype(np.uint64) + np.uint64(2**63)),
    "tum_nan": _tum_lines(_set_field(3, 1, "nan")),
    "tum_inf": _tum_lines(_set_field(2, 3, "inf")),
    "tum_7_columns": _tum_lines(lambda ls: [" ".join(ln.split()[:7]) for ln in ls]),
    "tum_text": _tum_lines(_set_field(1, 2, "abc")),
    "tum_not_increasing": _tum_lines(lambda ls: ls[::-1]),
    "tum_huge_times": _tum_lines(lambda ls: [f"1e30 {' '.join(ln.split()[1:])}" for ln in ls[:1]]),
    "tum_one_pose": _tum_lines(lambda ls: ls[:1]),
    "tum_empty": _write("camera_frames.tum", b""),
    "tum_non_utf8": _write("camera_frames.tum", b"0.0 1 2 3 0 0 0 1\n\xff\xfe\n"),
    "tum_zero_quaternion": _tum_lines(
        lambda ls: [f"{' '.join(ln.split()[:4])} 0 0 0 0" for ln in ls]
    ),
    "tum_comments_only": _write("camera_frames.tum", b"# t tx ty tz qx qy qz qw\n"),
    "gt_joints_missing": _no_gt_joints,
    "gt_trajectory_nan": _nan_gt_trajectory,
    "no_ground_truth": _no_groundtruth,
}


@pytest.fixture()
def case_dirs(tmp_path: Path, tiny_sim_session: Path) -> tuple[Path, Path]:
    session = tmp_path / "session"
    shutil.copytree(tiny_sim_session, session)
    return _good_result(tmp_path / "result", session), session


def test_valid_result_evaluates(case_dirs, capsys, tmp_path: Path) -> None:
    result, session = case_dirs
    out = tmp_path / "eval.json"
    rc = main(["evaluate", str(result), "--session", str(session), "--json", str(out)])
    captured = capsys.readouterr()
    assert rc == 0, captured.err
    data = json.loads(out.read_text())
    # a shift of the whole body: the world-frame error, which the alignment takes away
    assert data["mpjpe_m"] == pytest.approx(0.01, abs=1e-9)
    assert data["mpjpe_aligned_m"] == pytest.approx(0.0, abs=1e-9)
    assert data["body_ate_m"] < 1e-6 and data["counts"]["mpjpe_frames"] > 0
    assert all(math.isfinite(data[k]) for k in ("mpjpe_m", "body_ate_m"))


@pytest.mark.parametrize("case", sorted(CASES))
def test_broken_input_is_one_line(case: str, case_dirs, capsys, tmp_path: Path) -> None:
    result, session = case_dirs
    CASES[case](result, session)
    out = tmp_path / "eval.json"
    rc = main(["evaluate", str(result), "--session", str(session), "--json", str(out)])
    assert_one_line_exit(capsys, rc, "error")
    assert not out.exists()  # never a JSON (and so never a NaN in one) for broken input


JOINT_TIMES = {
    "all_equal": lambda t, p: np.full_like(t, t[0]),
    "one_step_back": lambda t, p: t[[0, 2, 1, *range(3, len(t))]],
}


@pytest.mark.parametrize("times", sorted(JOINT_TIMES))
def test_joint_times_that_do_not_increase_are_refused(times: str, case_dirs, capsys) -> None:
    """Result joints all at one time (or out of order) would be matched and scored frame by
    frame against the truth: refused, naming the result file."""
    result, session = case_dirs
    _joints(t_ns=JOINT_TIMES[times])(result, session)
    rc = main(["evaluate", str(result), "--session", str(session)])
    assert_one_line_exit(capsys, rc, f"{result / 'joints.npz'}: 't_ns' must be strictly increasing")


@pytest.mark.parametrize("target", ["folder", "parent_is_file"])
def test_json_target_that_cannot_be_written(target: str, case_dirs, capsys, tmp_path) -> None:
    result, session = case_dirs
    if target == "folder":
        out = tmp_path / "a_folder"
        out.mkdir()
    else:
        (tmp_path / "plain").write_text("x")
        out = tmp_path / "plain" / "eval.json"
    rc = main(["evaluate", str(result), "--session", str(session), "--json", str(out)])
    line = assert_one_line_exit(capsys, rc)
    assert str(out) in line or str(out.parent) in line, line
