"""TUM trajectory files: ``t tx ty tz qx qy qz qw`` per line, world-from-sensor poses.

The format evo and the TUM RGB-D tools read (``evo_ape tum ref.txt est.txt -a``): time in
seconds, the sensor origin in the world and the Hamilton rotation ``R_WfromS`` as a
scalar-last quaternion (see :mod:`gaitnet.geometry.se3`).
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from gaitnet.errors import SessionError
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


def read_tum(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """Read a TUM trajectory: times (n,) and poses ``T_WfromS`` (n, 4, 4)."""
    path = Path(path)
    try:
        data = np.loadtxt(path, comments="#", ndmin=2)
    except (OSError, ValueError) as exc:
        raise SessionError(f"{path}: not a TUM trajectory ({exc})") from exc
    if data.shape[1] != 8:
        raise SessionError(f"{path}: TUM rows need 8 columns, found {data.shape[1]}")
    if not np.all(np.isfinite(data)):
        raise SessionError(f"{path}: non-finite values")
    if np.any(np.diff(data[:, 0]) <= 0):
        raise SessionError(f"{path}: timestamps are not strictly increasing")
    return data[:, 0], T_from_tum(data[:, 1:])
