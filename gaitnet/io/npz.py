"""``.npz`` archives of named arrays, read safely: never unpickled, every failure one line.

:func:`open_npz` opens an archive and :func:`npz_array` reads one member; a folder, a missing
or damaged file, a plain ``.npy`` array, an object array (which would need unpickling) or a
corrupt member is a :class:`~gaitnet.errors.GaitnetError` of the caller's choosing whose
message names the file (and key) and never advises ``allow_pickle=True``. Used for AMASS
clips, prepared training files, body models and result folders.
"""

from __future__ import annotations

import zipfile
import zlib
from pathlib import Path

import numpy as np

from gaitnet.errors import GaitnetError, InputError

__all__ = ["NPZ_READ_ERRORS", "npz_array", "open_npz"]

#: What reading a broken ``.npz`` raises (numpy, zipfile, zlib): caught and named by readers.
NPZ_READ_ERRORS: tuple[type[BaseException], ...] = (
    OSError,
    ValueError,
    EOFError,
    KeyError,
    zipfile.BadZipFile,
    zlib.error,
)


def _npz_reason(exc: BaseException) -> str:
    """One line saying why numpy could not read an archive (never advice to unpickle)."""
    text = " ".join(str(exc).split())
    if "allow_pickle" in text:
        if "pickled" in text:  # numpy took a non-zip file for a pickle
            return "not an .npz archive"
        return "an object array, which would need unpickling; gaitnet never unpickles data"
    if isinstance(exc, EOFError) or not text:
        return "the file is empty or truncated"
    return text[:200]


def open_npz(
    path: str | Path, what: str, error: type[GaitnetError] = InputError
) -> np.lib.npyio.NpzFile:
    """``np.load(path, allow_pickle=False)`` of an ``.npz`` archive of named arrays.

    A folder, a missing file, a file numpy cannot read and a plain ``.npy`` array are each an
    ``error`` (a :class:`~gaitnet.errors.GaitnetError` class) naming the file and ``what`` it
    should be; use the result as a context manager.
    """
    path = Path(path)
    if path.is_dir():
        raise error(f"{path}: is a folder, expected {what}")
    if not path.is_file():
        raise error(f"{path}: not found (expected {what})")
    try:
        data = np.load(path, allow_pickle=False)
    except NPZ_READ_ERRORS as exc:
        raise error(f"{path}: cannot be read as {what} ({_npz_reason(exc)})") from exc
    if not isinstance(data, np.lib.npyio.NpzFile):
        raise error(f"{path}: holds one array, expected {what} (an .npz archive of named arrays)")
    return data


def npz_array(
    data: np.lib.npyio.NpzFile, path: str | Path, key: str, error: type[GaitnetError] = InputError
) -> np.ndarray:
    """``data[key]``; a corrupt member or an object array is an ``error`` naming file and key."""
    try:
        value = data[key]
    except NPZ_READ_ERRORS as exc:
        raise error(f"{path}: key {key!r} is not a readable array ({_npz_reason(exc)})") from exc
    if not isinstance(value, np.ndarray):  # numpy hands back raw bytes of a non-.npy member
        raise error(f"{path}: key {key!r} is not a readable array (not in .npy format)")
    return value
