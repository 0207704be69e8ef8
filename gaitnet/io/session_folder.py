"""Session folder v1 (docs/session-format.md): lazy reader and atomic writer.

```
session.yaml      calibration (see gaitnet.io.session_yaml)
color/<t_ns>.png  8-bit RGB
depth/<t_ns>.png  16-bit depth aligned to colour, 0 = invalid
imu.csv           t_ns,ax,ay,az,gx,gy,gz
groundtruth/      optional (simulator)
```

Opening a folder validates everything that is cheap to check (session.yaml, the IMU stream,
that every colour frame has its depth frame, each PNG's size, type and completeness from its
header); pixels are decoded only when a frame is requested. Frame file names are decimal
nanoseconds in ``[0, 2**63)``. :meth:`SessionFolder.frames` decodes up to :data:`READ_AHEAD`
frames ahead in one background thread (PNG decoding releases the GIL, so it runs on another
core while the caller works on the current frame); the frames, their order and any error are
those of :meth:`SessionFolder.frame`.

Symbolic links: a link inside the session folder whose target lies outside it (``session.yaml``,
``imu.csv``, ``color/``, ``depth/`` or a frame file) is refused with a
:class:`~gaitnet.errors.SessionError` naming the link and its target, so a session is
self-contained and what ``check`` validated is what later stages read; so is a link that
leads back to itself (a loop). Links that stay inside the folder are followed.
"""

from __future__ import annotations

import logging
import re
from collections.abc import Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path

import numpy as np

from gaitnet.errors import SessionError
from gaitnet.io.atomic import StagedFolder, atomic_write_text
from gaitnet.io.images import (
    check_png,
    depth_to_units,
    encode_png,
    read_depth,
    read_rgb,
)
from gaitnet.io.imu_csv import imu_csv_text, read_imu_csv, validate_imu
from gaitnet.io.session_yaml import read_session_yaml, session_yaml_text
from gaitnet.io.types import T_NS_MAX, Frame, ImuSamples, SessionCalibration

log = logging.getLogger(__name__)

#: Frames :meth:`SessionFolder.frames` decodes ahead of the one it yields.
READ_AHEAD = 2

_T_NS_NAME = re.compile(r"^[0-9]{1,19}$")


def check_inside(path: Path, root: Path) -> None:
    """Refuse ``path`` if it is a symbolic link whose target lies outside ``root``, or a link
    that leads back to itself (a loop: to itself, or through other links)."""
    if not path.is_symlink():
        return
    try:
        target = path.resolve()
    except RuntimeError:  # pathlib's "Symlink loop from ..."
        raise SessionError(f"{path}: symbolic link loop (the link leads back to itself)") from None
    if not target.is_relative_to(root.resolve()):
        raise SessionError(
            f"{path}: symbolic link to {target}, outside the session folder "
            "(copy the file into the session instead)"
        )


def _frame_files(folder: Path, root: Path) -> dict[int, Path]:
    if not folder.is_dir():
        what = "not a folder" if folder.exists() else "missing folder"
        raise SessionError(f"{folder}: {what}")
    check_inside(folder, root)
    files: dict[int, Path] = {}
    for path in folder.iterdir():
        if path.name.startswith("."):
            continue
        if path.suffix.lower() != ".png":
            raise SessionError(f"{path}: unexpected file (frames are <t_ns>.png)")
        if not _T_NS_NAME.match(path.stem) or int(path.stem) > T_NS_MAX:
            raise SessionError(f"{path}: file name is not a timestamp in ns (digits, below 2**63)")
        check_inside(path, root)
        t_ns = int(path.stem)
        if t_ns in files:
            raise SessionError(f"{path}: duplicate timestamp (also {files[t_ns].name})")
        files[t_ns] = path
    return files


class SessionFolder:
    """Read a session folder lazily (implements :class:`gaitnet.io.types.SessionSource`)."""

    def __init__(
        self,
        root: str | Path,
        imu_gap_warn_s: float = 0.025,
        imu_gap_error_s: float = 1.0,
        check_headers: bool = True,
    ) -> None:
        self.root = Path(root)
        if not self.root.is_dir():
            raise SessionError(f"{self.root}: session folder not found")
        for name in ("session.yaml", "imu.csv"):
            check_inside(self.root / name, self.root)
        self._calib = read_session_yaml(self.root / "session.yaml")
        color = _frame_files(self.root / "color", self.root)
        depth = _frame_files(self.root / "depth", self.root)
        if not color:
            raise SessionError(f"{self.root / 'color'}: no frames")
        for t_ns, path in color.items():
            if t_ns not in depth:
                raise SessionError(f"{path}: no depth frame with the same timestamp")
        for t_ns, path in depth.items():
            if t_ns not in color:
                raise SessionError(f"{path}: no colour frame with the same timestamp")
        self._times = np.array(sorted(color), dtype=np.int64)
        self._color = [color[t] for t in self._times]
        self._depth = [depth[t] for t in self._times]
        if check_headers:
            c, d = self._calib.color, self._calib.depth
            for path in self._color:
                check_png(path, c.width, c.height, bit_depth=8, channels=3)
            for path in self._depth:
                check_png(path, d.width, d.height, bit_depth=16, channels=1)
        self._imu = read_imu_csv(self.root / "imu.csv", imu_gap_warn_s, imu_gap_error_s)
        if self._imu.t_ns[0] > self._times[0] or self._imu.t_ns[-1] < self._times[-1]:
            log.warning(
                "%s: IMU covers %.3f–%.3f s but frames span %.3f–%.3f s",
                self.root,
                self._imu.t_ns[0] * 1e-9,
                self._imu.t_ns[-1] * 1e-9,
                self._times[0] * 1e-9,
                self._times[-1] * 1e-9,
            )

    @property
    def calibration(self) -> SessionCalibration:
        return self._calib

    @property
    def frame_times_ns(self) -> np.ndarray:
        return self._times

    @property
    def imu(self) -> ImuSamples:
        return self._imu

    @property
    def groundtruth_dir(self) -> Path | None:
        path = self.root / "groundtruth"
        return path if path.is_dir() else None

    def __len__(self) -> int:
        return len(self._times)

    def frame(self, index: int) -> Frame:
        if not -len(self) <= index < len(self):
            raise IndexError(f"frame {index} out of range (session has {len(self)})")
        index %= len(self)
        c, d = self._calib.color, self._calib.depth
        rgb = read_rgb(self._color[index], c.width, c.height)
        depth = read_depth(self._depth[index], d.width, d.height, self._calib.depth_scale_m)
        return Frame(index=index, t_ns=int(self._times[index]), rgb=rgb, depth_m=depth)

    def frames(self) -> Iterator[Frame]:
        """Every frame in order, decoded :data:`READ_AHEAD` frames ahead in a background
        thread (module docstring); an unreadable frame raises when it is reached."""
        n = len(self)
        with ThreadPoolExecutor(1, thread_name_prefix="gaitnet-read") as pool:
            ahead: list[Future] = [pool.submit(self.frame, i) for i in range(min(n, READ_AHEAD))]
            try:
                for i in range(n):
                    frame = ahead.pop(0).result()
                    if i + READ_AHEAD < n:
                        ahead.append(pool.submit(self.frame, i + READ_AHEAD))
                    yield frame
            finally:  # stopped early (an error, or the caller closed the generator)
                for future in ahead:
                    future.cancel()


class SessionWriter:
    """Write a session folder; it appears at ``root`` only when :meth:`close` succeeds.

    Frames go to a hidden staging folder next to ``root``
    (:class:`gaitnet.io.atomic.StagedFolder`); on success it is swapped into place, so an
    interrupted write never leaves a folder that looks like a complete session, and with
    ``overwrite`` a kill during the swap leaves the old or the new session. Use as a context
    manager::

        with SessionWriter(out, calib) as writer:
            writer.add_frame(t_ns, rgb, depth_m)
            writer.set_imu(imu)
            (writer.staging / "groundtruth").mkdir()   # extra content, optional

    Data that does not fit the calibration or the format (image size or type, timestamps
    out of order or out of int64 range, NaN in the IMU stream) raises
    :class:`~gaitnet.errors.SessionError` naming the output folder; an output path that is a
    file, or a non-empty folder without ``overwrite``, raises
    :class:`~gaitnet.errors.InputError`. Non-finite or non-positive depths are written as 0
    (invalid), as the format defines. ``compress_frames=False`` writes the colour and depth
    PNGs uncompressed (:func:`gaitnet.io.images.encode_png`).
    """

    def __init__(
        self,
        root: str | Path,
        calibration: SessionCalibration,
        overwrite: bool = False,
        encode_threads: int = 1,
        compress_frames: bool = True,
    ):
        if not isinstance(calibration, SessionCalibration):
            raise TypeError(f"calibration must be SessionCalibration, got {calibration!r}")
        self.root = Path(root)
        self.calibration = calibration
        self.overwrite = overwrite
        self.compress_frames = compress_frames
        self._stage = StagedFolder(self.root, overwrite)
        self.staging = self._stage.path
        self._pool: ThreadPoolExecutor | None = None
        try:  # an interrupt before the caller holds the writer must not leave the staging folder
            (self.staging / "color").mkdir()
            (self.staging / "depth").mkdir()
            self._times: list[int] = []
            self._imu: ImuSamples | None = None
            self._pool = ThreadPoolExecutor(encode_threads) if encode_threads > 0 else None
            self._pending: list[Future] = []
        except BaseException:
            self.abort()
            raise

    def _fail(self, what: str) -> SessionError:
        return SessionError(f"{self.root}: {what}")

    def add_frame(self, t_ns: int, rgb: np.ndarray, depth_m: np.ndarray) -> None:
        """Add one frame: ``rgb`` uint8 (H, W, 3), ``depth_m`` float metres (H, W)."""
        c, d = self.calibration.color, self.calibration.depth
        if isinstance(t_ns, (bool, np.bool_)) or not isinstance(t_ns, (int, np.integer)):
            raise self._fail(f"frame timestamp must be integer ns, got {t_ns!r}")
        t_ns = int(t_ns)
        if not 0 <= t_ns <= T_NS_MAX:
            raise self._fail(f"frame timestamp {t_ns} ns is outside [0, 2**63)")
        rgb, depth_m = np.asarray(rgb), np.asarray(depth_m)
        if rgb.shape != (c.height, c.width, 3) or rgb.dtype != np.uint8:
            raise self._fail(
                f"frame t_ns={t_ns}: colour must be uint8 {(c.height, c.width, 3)}, "
                f"got {rgb.dtype} {rgb.shape}"
            )
        if depth_m.shape != (d.height, d.width) or not np.issubdtype(depth_m.dtype, np.floating):
            raise self._fail(
                f"frame t_ns={t_ns}: depth must be float metres {(d.height, d.width)}, "
                f"got {depth_m.dtype} {depth_m.shape}"
            )
        if self._times and t_ns <= self._times[-1]:
            raise self._fail(
                f"frame timestamps must increase (t_ns={t_ns} after {self._times[-1]})"
            )
        name = f"{t_ns}.png"
        self.write_png(self.staging / "color" / name, rgb.copy(), self.compress_frames)
        units = depth_to_units(depth_m, self.calibration.depth_scale_m)
        self.write_png(self.staging / "depth" / name, units, self.compress_frames)
        self._times.append(t_ns)

    def write_png(self, path: Path, image: np.ndarray, compress: bool = True) -> None:
        """Encode and write ``image`` (not modified afterwards by the caller) in the background
        (``compress``: :func:`gaitnet.io.images.encode_png`).

        PNG encoding releases the GIL, so with ``encode_threads`` ≥ 1 it overlaps with the
        caller's work; errors surface at the next call or at :meth:`close`.
        """
        self._raise_failures(block=False)
        if self._pool is None:
            path.write_bytes(encode_png(image, compress))
            return
        self._pending.append(
            self._pool.submit(lambda: path.write_bytes(encode_png(image, compress)))
        )

    def _raise_failures(self, block: bool) -> None:
        still = []
        for future in self._pending:
            if block or future.done():
                future.result()
            else:
                still.append(future)
        self._pending = still

    def set_imu(self, imu: ImuSamples) -> None:
        """Set the IMU stream (validated: ≥ 2 samples, increasing, finite, no gap > 1 s)."""
        t = np.asarray(imu.t_ns)
        if t.ndim != 1 or not np.issubdtype(t.dtype, np.integer):
            raise self._fail(f"IMU timestamps must be integer ns, got {t.dtype} {t.shape}")
        for name in ("accel", "gyro"):
            v = np.asarray(getattr(imu, name))
            if v.shape != (t.shape[0], 3) or not np.issubdtype(v.dtype, np.number):
                raise self._fail(f"IMU {name} must be {(t.shape[0], 3)} numbers, got {v.shape}")
        if t.size and (int(t.min()) < 0 or int(t.max()) > T_NS_MAX):
            raise self._fail("IMU timestamps are outside [0, 2**63)")
        validate_imu(imu, f"{self.root}: IMU stream")
        self._imu = imu

    def close(self) -> Path:
        """Write session.yaml and imu.csv, then publish the folder at ``root``."""
        if self._stage.done:
            return self.root
        try:
            if self._imu is None:
                raise self._fail("no IMU stream was set (set_imu)")
            if not self._times:
                raise self._fail("no frames were added")
            self._raise_failures(block=True)
            if self._pool is not None:
                self._pool.shutdown()
            atomic_write_text(self.staging / "session.yaml", session_yaml_text(self.calibration))
            atomic_write_text(self.staging / "imu.csv", imu_csv_text(self._imu))
        except BaseException:
            self.abort()
            raise
        return self._stage.commit()

    def abort(self) -> None:
        """Drop everything written so far; ``root`` keeps what it had."""
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
        self._stage.abort()

    def __enter__(self) -> SessionWriter:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()


def copy_session(
    source, out_dir: str | Path, overwrite: bool = False, progress=None, calibration=None
) -> Path:
    """Write any :class:`~gaitnet.io.types.SessionSource` as a session folder, with
    ``calibration`` (a :class:`~gaitnet.io.types.SessionCalibration`) in place of the
    source's when given (``gaitnet convert --board``).

    The IMU stream is read (and validated) before anything is written, so a broken stream
    fails fast. ``progress`` optionally wraps the frame iterator (e.g. ``tqdm``) for the CLI.
    """
    imu = source.imu
    calib = source.calibration if calibration is None else calibration
    writer = SessionWriter(out_dir, calib, overwrite=overwrite)
    with writer:
        writer.set_imu(imu)
        frames = source.frames()
        if progress is not None:
            frames = progress(frames, total=len(source))
        for frame in frames:
            writer.add_frame(frame.t_ns, frame.rgb, frame.depth_m)
    return Path(out_dir)
