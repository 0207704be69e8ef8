"""TUM trajectory files: ``t tx ty tz qx qy qz qw`` per line, world-from-sensor poses.

The format evo and the TUM RGB-D tools read (``evo_ape tum ref.txt est.txt -a``): time in
seconds, the sensor origin in the world and the Hamilton rotation ``R_WfromS`` as a
scalar-last quaternion (see :mod:`gaitnet.geometry.se3`).
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from gaitnet.errors import GaitnetError, SessionError
from gaitnet.geometry import T_from_tum, tum_from_T
from gaitnet.io.atomic import atomic_write_text


def tum_text(t_s: np.ndarray, T_WfromS: np.ndarray, comment: str = "") -> str:
    """TUM text of poses ``T_WfromS`` (n, 4, 4) at times ``t_s`` (n,)."""
    if len(t_s) != len(T_WfromS):
        raise ValueError("times and poses differ in length")
    rows = tum_from_T(np.asarray(T_WfromS))
    if not np.all(np.isfinite(rows)):
        raise ValueError("non-finite pose in trajectory")
    out = io.StringIO()
    for line in comment.splitlines():
        out.write(f"# {line}\n")
    out.write("# timestamp tx ty tz qx qy qz qw\n")
    for t, row in zip(t_s, rows, strict=True):
        out.write(f"{t:.9f} " + " ".join(f"{v:.9f}" for v in row) + "\n")
    return out.getvalue()


def write_tum(path: str | Path, t_s: np.ndarray, T_WfromS: np.ndarray, comment: str = "") -> None:
    """Write a TUM trajectory atomically."""
    atomic_write_text(path, tum_text(t_s, T_WfromS, comment))


def read_tum(
    path: str | Path, error: type[GaitnetError] = SessionError
) -> tuple[np.ndarray, np.ndarray]:
    """Read a TUM trajectory: times (n,) and poses ``T_WfromS`` (n, 4, 4).

    Every failure is an ``error`` naming the file: not UTF-8, no poses, rows that are not
    8 numbers, non-finite values, a quaternion of (near) zero norm, times not increasing.
    """
    path = Path(path)
    if path.is_dir():
        raise error(f"{path}: is a folder, expected a TUM trajectory file")
    try:
        text = path.read_bytes().decode("utf-8")
    except UnicodeDecodeError as exc:
        raise error(f"{path}: not a TUM trajectory (byte {exc.start} is not UTF-8 text)") from exc
    rows = [line.split() for line in text.splitlines()]
    rows = [row for row in rows if row and not row[0].startswith("#")]
    if not rows:
        raise error(f"{path}: no poses")
    for i, row in enumerate(rows):
        if len(row) != 8:
            raise error(f"{path}: TUM rows need 8 columns, pose {i} has {len(row)}")
    try:
        data = np.array(rows, dtype=np.float64)
    except ValueError as exc:
        raise error(f"{path}: not a TUM trajectory (a value is not a number)") from exc
    if not np.all(np.isfinite(data)):
        raise error(f"{path}: non-finite values")
    if np.any(np.linalg.norm(data[:, 4:8], axis=1) < 1e-6):
        raise error(f"{path}: a quaternion has zero length")
    if np.any(np.diff(data[:, 0]) <= 0):
        raise error(f"{path}: timestamps are not strictly increasing")
    return data[:, 0], T_from_tum(data[:, 1:])
