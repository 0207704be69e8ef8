"""Merge separately sampled accelerometer and gyroscope streams onto one time base.

RealSense devices (and many phones) deliver the accelerometer and the gyroscope as two streams
with their own rates and timestamps (D455: accel 63/250 Hz, gyro 200/400 Hz), and repeated
samples (identical timestamps) occur. The pipeline wants one stream with both vectors per
sample, so :func:`merge_imu_streams` puts the accelerometer onto the gyro timestamps by linear
interpolation: the gyro is usually the faster stream and rotation rate is the quantity that
suffers most from resampling.

The function is pure (arrays in, :class:`~gaitnet.io.types.ImuSamples` out) so every session
source can use it.
"""

from __future__ import annotations

import logging

import numpy as np

from gaitnet.errors import SessionError
from gaitnet.io.types import (
    IMU_ACCEL_LIMIT_MS2,
    IMU_GYRO_LIMIT_RADS,
    ImuSamples,
)

log = logging.getLogger(__name__)


def _clean_stream(
    t_ns: np.ndarray, values: np.ndarray, name: str, source: str
) -> tuple[np.ndarray, np.ndarray]:
    """Validate one stream, sort it by time and drop samples whose timestamp repeats."""
    t = np.asarray(t_ns)
    v = np.asarray(values, dtype=np.float64)
    if t.ndim != 1 or v.ndim != 2 or v.shape != (t.shape[0], 3):
        raise SessionError(
            f"{source}: {name} stream must be N timestamps and N×3 values, "
            f"got {t.shape} and {v.shape}"
        )
    if t.shape[0] == 0:
        raise SessionError(f"{source}: {name} stream is empty")
    if not np.issubdtype(t.dtype, np.integer):
        raise SessionError(f"{source}: {name} timestamps must be integer nanoseconds")
    t = t.astype(np.int64)
    bad = ~np.isfinite(v).all(axis=1)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise SessionError(
            f"{source}: {int(bad.sum())} non-finite {name} sample(s), the first at t_ns={int(t[k])}"
        )
    limit = IMU_GYRO_LIMIT_RADS if name == "gyroscope" else IMU_ACCEL_LIMIT_MS2
    wild = (np.abs(v) > limit).any(axis=1)
    if wild.any():
        k = int(np.flatnonzero(wild)[0])
        raise SessionError(
            f"{source}: {int(wild.sum())} impossible {name} sample(s) (beyond ±{limit:.1f} SI "
            f"units), the first at t_ns={int(t[k])}: damaged data"
        )
    order = np.argsort(t, kind="stable")
    t, v = t[order], v[order]
    keep = np.ones(t.shape[0], dtype=bool)
    keep[1:] = t[1:] != t[:-1]
    n_dup = int((~keep).sum())
    if n_dup:
        log.info("%s: dropped %d %s sample(s) with a repeated timestamp", source, n_dup, name)
    return t[keep], v[keep]


def _warn_gaps(t: np.ndarray, gap_warn_s: float, name: str, source: str) -> None:
    if t.shape[0] < 2:
        return
    gaps = np.diff(t) * 1e-9
    n_gaps = int((gaps > gap_warn_s).sum())
    if n_gaps:
        worst = int(np.argmax(gaps))
        log.warning(
            "%s: %d %s gap(s) longer than %.3f s, the longest %.3f s after t_ns=%d",
            source,
            n_gaps,
            name,
            gap_warn_s,
            gaps[worst],
            int(t[worst]),
        )


def merge_imu_streams(
    t_acc_ns: np.ndarray,
    acc: np.ndarray,
    t_gyr_ns: np.ndarray,
    gyr: np.ndarray,
    *,
    gap_warn_s: float = 0.05,
    source: str = "IMU",
) -> ImuSamples:
    """Merge an accelerometer and a gyroscope stream onto the gyro timestamps.

    Args:
        t_acc_ns, acc: accelerometer timestamps (integer ns, shape ``(N,)``) and specific force
            [m/s²] ``(N, 3)``; any order, repeated timestamps allowed.
        t_gyr_ns, gyr: gyroscope timestamps ``(M,)`` and angular rate [rad/s] ``(M, 3)``.
        gap_warn_s: gaps between consecutive samples of either stream longer than this are
            reported with ``logging.warning`` (interpolating across them is a guess).
        source: names the recording in log messages and errors (e.g. the bag path).

    Returns:
        :class:`ImuSamples` on the gyro timestamps (strictly increasing, int64), ``accel`` the
        accelerometer interpolated linearly onto them, both float64 ``(K, 3)``.

    Both streams are sorted by time; of samples with the same timestamp the first one (in the
    given order) is kept and the number dropped is logged. Gyro samples before the first or
    after the last accelerometer sample are dropped (extrapolation is not done).

    Raises:
        SessionError: an empty stream, non-finite values, values beyond what the sensor can
            measure (:data:`~gaitnet.io.types.IMU_ACCEL_LIMIT_MS2`,
            :data:`~gaitnet.io.types.IMU_GYRO_LIMIT_RADS`), malformed arrays, or no gyro
            sample inside the accelerometer's time span.
    """
    t_a, a = _clean_stream(t_acc_ns, acc, "accelerometer", source)
    t_g, g = _clean_stream(t_gyr_ns, gyr, "gyroscope", source)

    inside = (t_g >= t_a[0]) & (t_g <= t_a[-1])
    n_out = int((~inside).sum())
    if n_out:
        log.info(
            "%s: dropped %d gyroscope sample(s) outside the accelerometer's time span",
            source,
            n_out,
        )
    t_g, g = t_g[inside], g[inside]
    if t_g.shape[0] == 0:
        raise SessionError(
            f"{source}: no gyroscope sample lies within the accelerometer's time span "
            f"({int(t_a[0])}–{int(t_a[-1])} ns)"
        )

    # Interpolate on times relative to the first accel sample: int64 ns since the epoch do not
    # fit a float64 exactly, differences within a recording do.
    x_a = (t_a - t_a[0]).astype(np.float64)
    x_g = (t_g - t_a[0]).astype(np.float64)
    accel = np.stack([np.interp(x_g, x_a, a[:, k]) for k in range(3)], axis=1)

    _warn_gaps(t_a, gap_warn_s, "accelerometer", source)
    _warn_gaps(t_g, gap_warn_s, "gyroscope", source)
    return ImuSamples(t_ns=t_g, accel=accel, gyro=np.ascontiguousarray(g))
