"""Atomic files and staged folders: permissions, kill leftovers, swaps, refusals."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from gaitnet.errors import InputError
from gaitnet.io import atomic
from gaitnet.io.atomic import (
    atomic_save,
    atomic_write_text,
    check_output_folder,
    clean_leftovers,
    staged_folder,
)


def _dead_pid() -> int:
    """The pid of a process that has exited (and been reaped)."""
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def test_files_follow_the_umask(tmp_path: Path) -> None:
    old = os.umask(0o027)
    try:
        atomic_write_text(tmp_path / "a.txt", "x")
        atomic_save(tmp_path / "b.bin", lambda tmp: Path(tmp).write_bytes(b"y"))
    finally:
        os.umask(old)
    assert (tmp_path / "a.txt").stat().st_mode & 0o777 == 0o640
    assert (tmp_path / "b.bin").stat().st_mode & 0o777 == 0o640


def test_a_failed_save_leaves_the_old_file_and_no_temp(tmp_path: Path) -> None:
    target = tmp_path / "best.pt"
    target.write_text("old")

    def broken(tmp: str) -> None:
        Path(tmp).write_text("half")
        raise RuntimeError("disk went away")

    with pytest.raises(RuntimeError):
        atomic_save(target, broken)
    assert target.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["best.pt"]


def test_leftovers_of_a_killed_writer_are_removed_on_the_next_write(tmp_path: Path) -> None:
    dead = _dead_pid()
    stale_file = tmp_path / f".best.pt.tmp-{dead}-abc.pt"
    stale_file.write_bytes(b"\0" * 1000)
    stale_dir = tmp_path / f".run.partial-{dead}"
    stale_dir.mkdir()
    live_file = tmp_path / f".best.pt.tmp-{os.getpid()}-zzz.pt"  # our own, in progress
    live_file.write_bytes(b"1")
    other = tmp_path / ".unrelated.tmp-1-x"
    other.write_text("keep")
    atomic_save(tmp_path / "best.pt", lambda tmp: Path(tmp).write_text("new"))
    with staged_folder(tmp_path / "run") as staging:
        (staging / "f").write_text("1")
    assert not stale_file.exists() and not stale_dir.exists()
    assert live_file.exists() and other.exists()
    assert (tmp_path / "best.pt").read_text() == "new"
    assert (tmp_path / "run" / "f").read_text() == "1"


def test_a_folder_lost_between_the_two_renames_of_a_swap_is_restored(tmp_path: Path) -> None:
    dead = _dead_pid()
    old = tmp_path / f".session.old-{dead}"
    old.mkdir()
    (old / "session.yaml").write_text("old")
    clean_leftovers(tmp_path / "session")
    assert (tmp_path / "session" / "session.yaml").read_text() == "old"
    assert not old.exists()


@pytest.mark.parametrize("exchange", [True, False])
def test_overwrite_replaces_the_folder_whole(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, exchange: bool
) -> None:
    if not exchange:
        monkeypatch.setattr(atomic, "_exchange", lambda a, b: False)
    root = tmp_path / "out"
    with staged_folder(root) as staging:
        (staging / "old.txt").write_text("old")
    with staged_folder(root, overwrite=True) as staging:
        assert not (root / "new.txt").exists()  # nothing visible before success
        (staging / "new.txt").write_text("new")
    assert sorted(p.name for p in root.iterdir()) == ["new.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_an_exception_leaves_the_old_folder_and_no_staging(tmp_path: Path) -> None:
    root = tmp_path / "out"
    with staged_folder(root) as staging:
        (staging / "old.txt").write_text("old")
    with pytest.raises(KeyboardInterrupt), staged_folder(root, overwrite=True) as staging:
        (staging / "new.txt").write_text("new")
        raise KeyboardInterrupt
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
    assert (root / "old.txt").read_text() == "old"


def test_output_paths_that_cannot_work_are_refused_up_front(tmp_path: Path) -> None:
    a_file = tmp_path / "file"
    a_file.write_text("x")
    with pytest.raises(InputError, match="is not a folder"):
        check_output_folder(a_file, overwrite=True)
    with pytest.raises(InputError, match="which is a file"):
        check_output_folder(a_file / "deeper" / "out", overwrite=False)
    full = tmp_path / "full"
    full.mkdir()
    (full / "x").write_text("x")
    with pytest.raises(InputError, match="not empty"):
        check_output_folder(full, overwrite=False)
    assert check_output_folder(full, overwrite=True) == full
    assert check_output_folder(tmp_path / "new" / "deeper", overwrite=False)
    with pytest.raises(InputError, match="is a folder"):
        atomic_write_text(full, "x")
