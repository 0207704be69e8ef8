"""Atomic file and folder writes.

Files: write to a temporary sibling, then rename over the target, so a reader never sees a
half-written file and an interrupted run leaves the previous version (or nothing) in place.
Folders (:func:`staged_folder`): fill a hidden staging folder next to the target, then swap it
into place; the swap exchanges the two folders in one system call where the kernel offers it
(Linux ``renameat2(RENAME_EXCHANGE)``), so a kill at any moment leaves either the old or the new
folder at the target.

A process killed with SIGKILL cannot clean up after itself. Every temporary name therefore
carries the writer's process id (``.NAME.tmp-PID-XXXX``, ``.NAME.partial-PID``,
``.NAME.old-PID``); the next write to the same target removes the leftovers of processes that
no longer run, and restores a folder that a killed swap left only under its ``.old-PID`` name.
Files get the permissions the user's umask gives (not ``mkstemp``'s 0600).
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import logging
import os
import re
import shutil
import tempfile
import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import IO

from gaitnet.errors import InputError

log = logging.getLogger(__name__)

_UMASK_LOCK = threading.Lock()
_RENAME_EXCHANGE = 2  # linux/fs.h


def _current_umask() -> int:
    with _UMASK_LOCK:
        mask = os.umask(0)
        os.umask(mask)
    return mask


def _pid_alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _leftovers(path: Path) -> Iterator[tuple[Path, str, int]]:
    """Siblings of ``path`` named by an atomic writer: ``(sibling, kind, pid)``."""
    pattern = re.compile(rf"^\.{re.escape(path.name)}\.(tmp|partial|old)-(\d+)(-.*)?$")
    if not path.parent.is_dir():
        return
    for sibling in path.parent.iterdir():
        match = pattern.match(sibling.name)
        if match:
            yield sibling, match.group(1), int(match.group(2))


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        with contextlib.suppress(FileNotFoundError):
            path.unlink()


def clean_leftovers(path: str | Path) -> None:
    """Remove what killed writers of ``path`` left behind; restore a folder lost mid-swap.

    A ``.NAME.old-PID`` folder of a dead process while ``path`` itself is missing is the old
    content of a swap that was killed between its two renames: it is moved back to ``path``.
    """
    path = Path(path)
    for sibling, kind, pid in list(_leftovers(path)):
        if _pid_alive(pid):
            continue
        if kind == "old" and not path.exists():
            log.warning("%s: restoring the folder a killed overwrite left (%s)", path, sibling)
            os.replace(sibling, path)
            continue
        log.info("removing %s (left by an interrupted run, process %d)", sibling, pid)
        _remove(sibling)


def _make_temp(path: Path, suffix: str) -> str:
    fd, tmp_name = tempfile.mkstemp(
        prefix=f".{path.name}.tmp-{os.getpid()}-", suffix=suffix, dir=path.parent
    )
    os.fchmod(fd, 0o666 & ~_current_umask())
    os.close(fd)
    return tmp_name


@contextlib.contextmanager
def atomic_open(path: str | Path, mode: str = "w", **kwargs) -> Iterator[IO]:
    """Open a temporary sibling of ``path`` for writing; it replaces ``path`` on success."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.is_dir():
        raise InputError(f"{path}: is a folder, expected a file path")
    clean_leftovers(path)
    tmp_name = _make_temp(path, ".tmp")
    try:
        with open(tmp_name, mode, **kwargs) as handle:
            yield handle
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp_name, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp_name)
        raise


def atomic_write_text(path: str | Path, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    with atomic_open(path, "w", encoding="utf-8") as handle:
        handle.write(text)


def atomic_write_bytes(path: str | Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically."""
    with atomic_open(path, "wb") as handle:
        handle.write(data)


def atomic_save(path: str | Path, save: Callable[[str], None]) -> None:
    """Call ``save(tmp_path)`` (e.g. ``torch.save`` or ``np.savez``) then rename into place."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.is_dir():
        raise InputError(f"{path}: is a folder, expected a file path")
    clean_leftovers(path)
    tmp_name = _make_temp(path, path.suffix)
    try:
        save(tmp_name)
        os.replace(tmp_name, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp_name)
        raise


def check_output_folder(root: str | Path, overwrite: bool) -> Path:
    """Refuse an output path that is a file, lies below a file, or is a non-empty folder
    without ``overwrite``."""
    root = Path(root)
    if root.exists() and not root.is_dir():
        raise InputError(f"{root}: output path exists and is not a folder")
    parent = root.absolute().parent
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        raise InputError(f"{root}: cannot create a folder below {parent}, which is a file")
    if root.is_dir() and any(root.iterdir()) and not overwrite:
        raise InputError(
            f"{root}: output exists and is not empty (choose another folder or add --overwrite)"
        )
    return root


def _exchange(a: Path, b: Path) -> bool:
    """Swap two paths in one step (Linux ``renameat2``); False where unsupported."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        renameat2 = libc.renameat2
    except (OSError, AttributeError):
        return False
    at_fdcwd = -100
    rc = renameat2(at_fdcwd, os.fsencode(a), at_fdcwd, os.fsencode(b), _RENAME_EXCHANGE)
    if rc == 0:
        return True
    err = ctypes.get_errno()
    if err in (errno.EINVAL, errno.ENOSYS, errno.EOPNOTSUPP):
        return False
    raise OSError(err, os.strerror(err), str(b))


def publish_folder(staging: Path, root: Path) -> None:
    """Move the finished ``staging`` folder to ``root``, replacing what is there."""
    if not root.exists():
        os.replace(staging, root)
        return
    if _exchange(staging, root):
        shutil.rmtree(staging)  # now holds the old content
        return
    old = root.parent / f".{root.name}.old-{os.getpid()}"
    os.replace(root, old)
    os.replace(staging, root)
    shutil.rmtree(old, ignore_errors=True)


class StagedFolder:
    """A hidden staging folder next to ``root`` that becomes ``root`` on :meth:`commit`.

    The object form of :func:`staged_folder`, for writers whose lifetime is not one ``with``
    block (e.g. :class:`gaitnet.io.SessionWriter`). Creating it checks ``root`` (it must not
    exist, be empty, or ``overwrite`` is set), cleans what killed writers left next to it and
    makes the empty staging folder :attr:`path`. :meth:`commit` swaps it into place
    (:func:`publish_folder`); :meth:`abort` removes it and leaves ``root`` untouched. Both are
    idempotent once one of them has run.
    """

    def __init__(self, root: str | Path, overwrite: bool = False) -> None:
        self.root = check_output_folder(root, overwrite)
        self.root.parent.mkdir(parents=True, exist_ok=True)
        clean_leftovers(self.root)
        self.path = self.root.parent / f".{self.root.name}.partial-{os.getpid()}"
        self.done = False
        _remove(self.path)
        try:
            self.path.mkdir()
        except BaseException:  # an interrupt right after mkdir (signals arrive as exceptions)
            self.abort()
            raise

    def commit(self) -> Path:
        """Publish the staging folder as ``root`` and return ``root``."""
        if self.done:
            raise RuntimeError(f"{self.root}: staging folder already committed or aborted")
        try:
            publish_folder(self.path, self.root)
        except BaseException:
            self.abort()
            raise
        self.done = True
        return self.root

    def abort(self) -> None:
        """Remove the staging folder; ``root`` keeps what it had."""
        shutil.rmtree(self.path, ignore_errors=True)
        self.done = True


@contextlib.contextmanager
def staged_folder(root: str | Path, overwrite: bool = False) -> Iterator[Path]:
    """Yield an empty hidden staging folder; on success it becomes ``root``.

    ``root`` must not exist, be empty, or (with ``overwrite``) is replaced. On an exception
    the staging folder is removed and ``root`` is untouched.
    """
    stage = StagedFolder(root, overwrite)
    try:
        yield stage.path
    except BaseException:
        stage.abort()
        raise
    stage.commit()
