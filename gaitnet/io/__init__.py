"""Reading and writing recorded sessions (session folder v1, RealSense .bag)."""

from __future__ import annotations

from pathlib import Path

from gaitnet.errors import SessionError
from gaitnet.io.session_folder import SessionFolder, SessionWriter, copy_session
from gaitnet.io.types import (
    AprilTagBoard,
    CameraIntrinsics,
    Frame,
    ImuNoise,
    ImuSamples,
    SessionCalibration,
    SessionSource,
)


def open_session(path: str | Path, **options) -> SessionSource:
    """Open a session folder or a RealSense ``.bag`` recording behind one interface."""
    path = Path(path)
    if path.is_dir():
        return SessionFolder(path, **options)
    if path.suffix.lower() == ".bag":
        if not path.is_file():
            raise SessionError(f"{path}: bag file not found")
        from gaitnet.io.realsense_bag import RealSenseBag

        return RealSenseBag(path, **options)
    if not path.exists():
        raise SessionError(f"{path}: no such session folder or .bag file")
    raise SessionError(f"{path}: not a session folder or a .bag file")


__all__ = [
    "AprilTagBoard",
    "CameraIntrinsics",
    "Frame",
    "ImuNoise",
    "ImuSamples",
    "SessionCalibration",
    "SessionFolder",
    "SessionSource",
    "SessionWriter",
    "copy_session",
    "open_session",
]
