"""Camera frame timing: the true exposure-mid times, the timestamps and the dropped frames.

A real D455 exposes its frames on a regular grid, but the timestamps it attaches are off by a
fraction of a millisecond, a frame is now and then lost on the way (USB), and its IMU runs on
a clock that is a few milliseconds off the frames' (docs/references.md, *Simulator realism:
IMU and timing*). Here the frames' true exposure-mid times lie on the nominal grid
``FRAME_MARGIN_S + k / fps`` (inside the IMU's span); each timestamp is its true time plus
``N(0, frame_jitter_s²)`` clipped to ±3σ (so the timestamps stay strictly increasing); each
frame is dropped with probability ``frame_drop_rate``, never the first or last one and never
two in a row; the IMU's timestamps are its true sampling instants plus
``imu_time_offset_s``, drawn once per session uniformly within ±``imu_time_offset_max_s``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gaitnet.checks import check_range

__all__ = ["FRAME_MARGIN_S", "FrameTimes", "FrameTimingConfig", "make_frame_times"]

FRAME_MARGIN_S = 0.05  # frames start/end this far inside the IMU stream, as on a real device


@dataclass(frozen=True)
class FrameTimingConfig:
    """Clocks and timestamps (section ``timing``; module docstring).

    ``frame_jitter_s``: std of the frame timestamps around the true exposure-mid times, 0–2 ms
    (default 0.2 ms); ``frame_drop_rate``: chance that a frame is missing, 0–0.05 (default
    0.3 %); ``imu_time_offset_max_s``: the IMU timestamps are off the camera's by a constant
    drawn uniformly within ± this, 0–0.05 s (default 5 ms). 0 switches each off.
    """

    frame_jitter_s: float = 2.0e-4
    frame_drop_rate: float = 0.003
    imu_time_offset_max_s: float = 0.005

    def __post_init__(self) -> None:
        check_range("frame_jitter_s", self.frame_jitter_s, 0.0, 0.002, " s")
        check_range("frame_drop_rate", self.frame_drop_rate, 0.0, 0.05)
        check_range("imu_time_offset_max_s", self.imu_time_offset_max_s, 0.0, 0.05, " s")

    def draw_imu_time_offset(self, rng: np.random.Generator) -> float:
        """The session's IMU time offset [s] (``rng`` untouched when the key is 0)."""
        if self.imu_time_offset_max_s <= 0:
            return 0.0
        return float(rng.uniform(-1.0, 1.0) * self.imu_time_offset_max_s)


@dataclass(frozen=True)
class FrameTimes:
    """The frames of a session: ``index`` (n,) on the nominal grid, ``true_s`` (n,) exposure
    mid-times, ``stamp_ns`` (n,) timestamps, and ``dropped`` (m,) grid indices left out."""

    index: np.ndarray
    true_s: np.ndarray
    stamp_ns: np.ndarray
    dropped: np.ndarray


def make_frame_times(
    duration_s: float, fps: float, cfg: FrameTimingConfig, rng: np.random.Generator
) -> FrameTimes:
    """Frame times of a session of ``duration_s`` at ``fps`` (module docstring)."""
    n = int(np.floor((duration_s - 2 * FRAME_MARGIN_S) * fps)) + 1
    grid = FRAME_MARGIN_S + np.arange(n) / fps
    keep = np.ones(n, dtype=bool)
    if cfg.frame_drop_rate > 0 and n > 2:
        drop = rng.random(n) < cfg.frame_drop_rate
        drop[0] = drop[-1] = False
        for k in range(1, n):  # never two in a row
            if drop[k] and drop[k - 1]:
                drop[k] = False
        keep = ~drop
    jitter = np.zeros(n)
    if cfg.frame_jitter_s > 0:
        sigma = min(cfg.frame_jitter_s, 0.1 / fps)
        jitter = np.clip(rng.normal(0.0, sigma, n), -3 * sigma, 3 * sigma)
    stamp_ns = np.round((grid + jitter) * 1e9).astype(np.int64)
    index = np.flatnonzero(keep)
    return FrameTimes(index, grid[keep], stamp_ns[keep], np.flatnonzero(~keep))
