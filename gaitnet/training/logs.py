"""Logging for training runs: a rank-0 filter, tqdm-friendly console output and a log file.

Library code only uses ``logging``; :func:`setup_logging` (called by an entry script) sends
records to stderr through ``tqdm.write`` (so progress bars stay intact) and to
``<run_dir>/train.log``. On ranks other than 0 :class:`RankZeroFilter` drops everything below
WARNING, so a multi-process run logs once.
"""

from __future__ import annotations

import logging
import sys
from pathlib import Path

from tqdm import tqdm

__all__ = ["RankZeroFilter", "TqdmHandler", "close_logging", "setup_logging"]

_FORMAT = "%(asctime)s %(levelname)s %(name)s: %(message)s"
_CONSOLE_FORMAT = "%(asctime)s %(message)s"


class RankZeroFilter(logging.Filter):
    """Pass every record on rank 0; on other ranks only warnings and errors."""

    def __init__(self, rank: int) -> None:
        super().__init__()
        self.rank = int(rank)

    def filter(self, record: logging.LogRecord) -> bool:
        return self.rank == 0 or record.levelno >= logging.WARNING


class TqdmHandler(logging.Handler):
    """Write records with ``tqdm.write`` to stderr so they do not break progress bars."""

    def emit(self, record: logging.LogRecord) -> None:
        try:
            tqdm.write(self.format(record), file=sys.stderr)
        except Exception:  # logging must never raise
            self.handleError(record)


def setup_logging(
    rank: int = 0, run_dir: str | Path | None = None, level: int = logging.INFO
) -> logging.Logger:
    """Configure the root logger for a training run and return it.

    Replaces handlers previously installed by this function (safe to call twice in one
    process, e.g. in tests). ``run_dir`` adds ``train.log`` (rank 0 only, appended on resume).
    """
    close_logging()
    root = logging.getLogger()
    root.setLevel(level)
    rank_filter = RankZeroFilter(rank)
    console = TqdmHandler()
    console.setFormatter(logging.Formatter(_CONSOLE_FORMAT, "%H:%M:%S"))
    handlers: list[logging.Handler] = [console]
    if run_dir is not None and rank == 0:
        Path(run_dir).mkdir(parents=True, exist_ok=True)
        file_handler = logging.FileHandler(Path(run_dir) / "train.log", encoding="utf-8")
        file_handler.setFormatter(logging.Formatter(_FORMAT))
        handlers.append(file_handler)
    for handler in handlers:
        handler.addFilter(rank_filter)
        handler._gaitnet_training = True  # type: ignore[attr-defined]
        root.addHandler(handler)
    return root


def close_logging() -> None:
    """Remove and close the handlers :func:`setup_logging` installed (closes ``train.log``)."""
    root = logging.getLogger()
    for handler in list(root.handlers):
        if getattr(handler, "_gaitnet_training", False):
            root.removeHandler(handler)
            handler.close()
