"""``imu.csv`` of the session folder: ``t_ns,ax,ay,az,gx,gy,gz`` (SI units), one row per sample.

Rows must be in strictly increasing time. A gap longer than ``gap_warn_s`` is logged; one
longer than ``gap_error_s`` is an error (the filter cannot bridge it).
"""

from __future__ import annotations

import io
import logging
import math
import re
from pathlib import Path

import numpy as np

from gaitnet.errors import SessionError
from gaitnet.io.types import (
    IMU_ACCEL_LIMIT_MS2,
    IMU_GYRO_LIMIT_RADS,
    T_NS_MAX,
    ImuSamples,
    implausible_imu,
)

log = logging.getLogger(__name__)

IMU_HEADER = "t_ns,ax,ay,az,gx,gy,gz"
_T_NS = re.compile(r"^[0-9]{1,19}$")


def imu_csv_text(imu: ImuSamples) -> str:
    """Deterministic CSV text of an IMU stream (9 significant digits, enough for float32)."""
    out = io.StringIO()
    out.write(IMU_HEADER + "\n")
    for t, a, g in zip(imu.t_ns, imu.accel, imu.gyro, strict=True):
        values = ",".join(f"{v:.9g}" for v in (*a, *g))
        out.write(f"{int(t)},{values}\n")
    return out.getvalue()


def validate_imu(
    imu: ImuSamples,
    source: str,
    gap_warn_s: float = 0.025,
    gap_error_s: float = 1.0,
    first_line: int | None = None,
) -> None:
    """Check ordering, finiteness, range and gaps of an IMU stream; ``source`` names it.

    Range: values beyond :data:`~gaitnet.io.types.IMU_ACCEL_LIMIT_MS2` or
    :data:`~gaitnet.io.types.IMU_GYRO_LIMIT_RADS` are impossible for the sensor (damaged data).

    With ``first_line`` (the file line of sample 0), errors name file lines, not sample indices.
    """

    def where(k: int) -> str:
        return f"line {k + first_line}" if first_line is not None else f"sample {k}"

    t = imu.t_ns
    if len(t) < 2:
        raise SessionError(f"{source}: needs at least 2 IMU samples, found {len(t)}")
    bad = ~np.isfinite(imu.accel).all(axis=1) | ~np.isfinite(imu.gyro).all(axis=1)
    if bad.any():
        row = int(np.flatnonzero(bad)[0])
        raise SessionError(f"{source}: non-finite IMU value at {where(row)} (t_ns={int(t[row])})")
    wild = implausible_imu(imu.accel, imu.gyro)
    if wild.any():
        row = int(np.flatnonzero(wild)[0])
        raise SessionError(
            f"{source}: impossible IMU value at {where(row)} (t_ns={int(t[row])}): beyond "
            f"±{IMU_ACCEL_LIMIT_MS2:.0f} m/s² or ±{IMU_GYRO_LIMIT_RADS:.1f} rad/s"
        )
    dt = np.diff(t)
    if (dt <= 0).any():
        k = int(np.flatnonzero(dt <= 0)[0])
        what = "duplicate" if dt[k] == 0 else "unsorted"
        raise SessionError(
            f"{source}: {what} timestamps at {where(k + 1)} "
            f"(t_ns {int(t[k + 1])} follows {int(t[k])})"
        )
    gaps = dt * 1e-9
    worst = int(np.argmax(gaps))
    if gaps[worst] > gap_error_s:
        raise SessionError(
            f"{source}: IMU gap of {gaps[worst]:.3f} s after t_ns={int(t[worst])} "
            f"(more than {gap_error_s} s)"
        )
    n_gaps = int((gaps > gap_warn_s).sum())
    if n_gaps:
        log.warning(
            "%s: %d IMU gap(s) longer than %.3f s, the longest %.3f s after t_ns=%d",
            source,
            n_gaps,
            gap_warn_s,
            gaps[worst],
            int(t[worst]),
        )


def read_imu_csv(path: Path, gap_warn_s: float = 0.025, gap_error_s: float = 1.0) -> ImuSamples:
    """Read and validate ``imu.csv``.

    Errors (:class:`SessionError`, naming the file and line): a missing or empty file, bytes
    that are not UTF-8, a wrong header, a row without 7 columns, a timestamp that is not a
    decimal integer in ``[0, 2**63)``, a value that is not a number, NaN or infinity, and the
    checks of :func:`validate_imu`.
    """
    if not path.is_file():
        what = "is not a file" if path.exists() else "missing"
        raise SessionError(f"{path}: {what} (every session folder needs imu.csv)")
    try:
        with open(path, encoding="utf-8", newline="") as handle:
            rows, first_line = _parse_rows(path, handle)
    except UnicodeDecodeError as exc:
        raise SessionError(f"{path}: not UTF-8 text (bad byte at offset {exc.start})") from None
    except OSError as exc:
        raise SessionError(f"{path}: cannot read ({exc.strerror})") from None
    if not rows:
        raise SessionError(f"{path}: no IMU samples")
    t_ns = np.array([r[0] for r in rows], dtype=np.int64)
    values = np.array([r[1] for r in rows], dtype=np.float64)
    imu = ImuSamples(t_ns=t_ns, accel=values[:, :3], gyro=values[:, 3:])
    validate_imu(imu, str(path), gap_warn_s, gap_error_s, first_line=first_line)
    return imu


def _parse_rows(path: Path, handle) -> tuple[list[tuple[int, list[float]]], int | None]:
    first = handle.readline()
    if not first:
        raise SessionError(f"{path}: empty file (expected the header '{IMU_HEADER}')")
    header = first.strip().replace(" ", "")
    if header != IMU_HEADER:
        shown = header if len(header) <= 60 else header[:60] + "…"
        raise SessionError(f"{path}: header must be '{IMU_HEADER}', found {shown!r}")
    rows: list[tuple[int, list[float]]] = []
    first_line: int | None = None
    for line_no, line in enumerate(handle, start=2):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        parts = line.split(",")
        if len(parts) != 7:
            raise SessionError(f"{path}: line {line_no} has {len(parts)} columns, expected 7")
        stamp = parts[0].strip()
        if not _T_NS.match(stamp) or int(stamp) > T_NS_MAX:
            raise SessionError(
                f"{path}: line {line_no}: timestamp {stamp[:30]!r} is not integer ns in [0, 2**63)"
            )
        try:
            values = [float(p) for p in parts[1:]]
        except ValueError:
            raise SessionError(f"{path}: line {line_no} is not numeric ({line[:80]!r})") from None
        if not all(math.isfinite(v) for v in values):
            raise SessionError(f"{path}: non-finite IMU value at line {line_no} (t_ns={stamp})")
        rows.append((int(stamp), values))
        first_line = line_no if first_line is None else first_line
    return rows, first_line
