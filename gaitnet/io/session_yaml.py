"""``session.yaml`` of the session folder v1: its one reader and its one writer.

The schema is :class:`~gaitnet.io.types.SessionCalibration` and the types it holds (their
fields are the file's keys, their ``__post_init__`` checks are the file's value checks), plus
the file-level key ``format_version``. The file is parsed with the same typed-config machinery
as every other YAML file (:func:`gaitnet.config.parse_config`), so an unknown or mistyped key,
a non-finite number or an out-of-range value is a :class:`~gaitnet.errors.SessionError` whose
one-line message names the file and the key. It is written with
:func:`gaitnet.config.config_to_dict` in a fixed key order, so the same calibration always
gives the same bytes.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from gaitnet.config import config_to_dict, parse_config, read_yaml
from gaitnet.errors import ConfigError, SessionError
from gaitnet.io.types import SESSION_FORMAT_VERSION, AprilTagBoard, SessionCalibration

HEADER = "# gaitnet recorded session, folder format v1 (see docs/session-format.md)\n"


def _load_mapping(path: Path) -> dict[str, Any]:
    """The file's mapping, read by the project's one YAML reader (:func:`read_yaml`: size,
    UTF-8, nesting and alias limits, duplicate keys), with errors as SessionError."""
    source = str(path)
    if not path.is_file():
        what = "is not a file" if path.exists() else "missing"
        raise SessionError(f"{source}: {what} (every session folder needs session.yaml)")
    try:
        data = read_yaml(path)
    except ConfigError as exc:
        raise SessionError(str(exc)) from None
    if data is None:
        raise SessionError(f"{source}: empty file")
    if not isinstance(data, dict):
        raise SessionError(f"{source}: must be a mapping of keys, got {type(data).__name__}")
    return data


def read_session_yaml(path: Path) -> SessionCalibration:
    """Parse and validate ``session.yaml`` into a :class:`SessionCalibration`."""
    path = Path(path)
    source = str(path)
    data = _load_mapping(path)
    if "format_version" not in data:
        raise SessionError(f"{source}: missing required key 'format_version'")
    version = data.pop("format_version")
    if version != SESSION_FORMAT_VERSION or isinstance(version, bool):
        raise SessionError(
            f"{source}: format_version {version!r} is not supported "
            f"(this gaitnet reads version {SESSION_FORMAT_VERSION})"
        )
    if "extra" in data and data["extra"] is None:
        del data["extra"]  # "extra:" with nothing after it
    try:
        return parse_config(SessionCalibration, data, source)
    except ConfigError as exc:
        raise SessionError(str(exc)) from None


def session_yaml_text(calib: SessionCalibration) -> str:
    """Serialise a calibration to the text of ``session.yaml`` (deterministic).

    Key order: ``format_version``, ``device``, then the calibration's fields in their declared
    order; ``extra`` only when it holds something.
    """
    fields = config_to_dict(calib)
    data = {"format_version": SESSION_FORMAT_VERSION, "device": fields.pop("device"), **fields}
    if not data["extra"]:
        del data["extra"]
    return HEADER + yaml.safe_dump(data, sort_keys=False, default_flow_style=None)


@dataclass(frozen=True)
class BoardFile:
    """A board file (``gaitnet convert --board``): the ``apriltag_boards`` list of
    ``session.yaml``, alone (what ``gaitnet tags`` prints)."""

    apriltag_boards: tuple[AprilTagBoard, ...]


def read_board_file(path: str | Path) -> tuple[AprilTagBoard, ...]:
    """The AprilTag boards of a board file, each checked as ``session.yaml``'s are; a file
    that does not parse is a :class:`~gaitnet.errors.SessionError` naming it and the key."""
    path = Path(path)
    if not path.is_file():
        what = "is not a file" if path.exists() else "not found"
        raise SessionError(f"{path}: {what} (a board file: an apriltag_boards list)")
    data = _load_mapping(path)
    try:
        return parse_config(BoardFile, data, str(path)).apriltag_boards
    except ConfigError as exc:
        raise SessionError(str(exc)) from None
