"""Which sessions a batch runs and where each one's result goes (docs/batch.md, *Sessions and
names*).

Each input is a session folder (a folder holding ``session.yaml``), a RealSense ``.bag`` file,
or a folder searched recursively for both (hidden entries, the output folder and the inside of
a session folder are not searched). A session's output name is its path relative to the input
folder it was found in, the parts joined by ``__`` (``s01/visit1/walk.bag`` → ``s01__visit1__walk``;
a ``.bag`` loses its suffix); a session given itself is named by its last part. Two sessions
with one name, an input folder with no session and an output folder inside a session are
refused before anything runs, with one line naming them.
"""

from __future__ import annotations

import os
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

from gaitnet.errors import InputError

__all__ = [
    "NAME_SEPARATOR",
    "BatchSession",
    "find_sessions",
    "is_session_folder",
]

NAME_SEPARATOR = "__"
SESSION_FILE = "session.yaml"
RESERVED = frozenset({"cohort.csv", "cohort.html", "failures.csv"})


@dataclass(frozen=True)
class BatchSession:
    """One session of a batch: ``path`` as found (absolute, so that every worker and node reads
    the same path) and ``name``, its output folder's name in the batch's output folder."""

    path: Path
    name: str


def is_session_folder(path: Path) -> bool:
    """A folder holding ``session.yaml`` (docs/session-format.md)."""
    return path.is_dir() and (path / SESSION_FILE).is_file()


def _is_bag(path: Path) -> bool:
    return path.suffix.lower() == ".bag" and path.is_file()


def _search(folder: Path, skip: Path, seen: set[Path]) -> Iterator[Path]:
    """Session folders and ``.bag`` files below ``folder``, in name order."""
    real = folder.resolve()
    if real in seen:  # a symbolic link back to a folder already searched
        return
    seen.add(real)
    for entry in sorted(folder.iterdir(), key=lambda p: p.name):
        if entry.name.startswith(".") or entry.resolve() == skip:
            continue
        if is_session_folder(entry) or _is_bag(entry):
            yield entry
        elif entry.is_dir():
            yield from _search(entry, skip, seen)


def _name(path: Path, base: Path | None) -> str:
    relative = path.relative_to(base) if base is not None else Path(path.name)
    parts = [*relative.parts[:-1], relative.stem if _is_bag(path) else relative.name]
    return NAME_SEPARATOR.join(parts)


def _found_in(text: str, out_real: Path) -> list[BatchSession]:
    """The sessions one input ``text`` names (module docstring)."""
    path = Path(text)
    if not path.exists():
        raise InputError(f"{text}: no such session folder, .bag file or folder")
    if is_session_folder(path) or _is_bag(path):
        return [BatchSession(path.absolute(), _name(path, None))]
    if not path.is_dir():
        raise InputError(f"{text}: not a session folder, a .bag file or a folder of them")
    found = [BatchSession(p.absolute(), _name(p, path)) for p in _search(path, out_real, set())]
    if not found:
        raise InputError(
            f"{text}: no session found (no folder with {SESSION_FILE} and no .bag file in it)"
        )
    return found


def find_sessions(
    inputs: Sequence[str | os.PathLike], out: str | os.PathLike
) -> list[BatchSession]:
    """The sessions of ``inputs`` (module docstring) sorted by name; a session named twice
    (the same real path) is taken once. :class:`InputError` for a missing input, an input
    folder with no session, an output folder ``out`` that lies in a session folder, and two
    sessions that would get the same name."""
    if not inputs:
        raise InputError("no session given")
    out_real = Path(out).resolve()
    by_real: dict[Path, BatchSession] = {}
    for text in inputs:
        for session in _found_in(os.fspath(text), out_real):
            by_real.setdefault(session.path.resolve(), session)
    by_name: dict[str, BatchSession] = {}
    for real, session in by_real.items():
        if real.is_dir() and out_real.is_relative_to(real):
            raise InputError(
                f"{out}: the output folder lies inside the session {session.path} "
                "(choose a folder outside every session)"
            )
        if session.name in RESERVED:
            raise InputError(
                f"{session.path}: its output name {session.name!r} is a file of the batch's "
                "own (rename the session or give its parent folder)"
            )
        other = by_name.setdefault(session.name, session)
        if other is not session:
            raise InputError(
                f"{other.path} and {session.path} would both be written to "
                f"{Path(out) / session.name} (give a folder above both, so that their names "
                "keep the folders that tell them apart)"
            )
    return sorted(by_name.values(), key=lambda s: s.name)
