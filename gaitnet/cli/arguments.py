"""What every ``gaitnet`` command shares: the usage error, the parser class and the option types
(every value is validated where it enters)."""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import NoReturn

from gaitnet.errors import GaitnetError

PROG = "gaitnet"
EXIT_USER_ERROR = 1
EXIT_BUG = 2
EXIT_SIGINT = 130  # 128 + SIGINT, the shell's convention
EXIT_SIGTERM = 143  # 128 + SIGTERM


class UsageError(GaitnetError):
    """A bad command line; ``prog`` is the (sub)command whose parser found it."""

    def __init__(self, prog: str, message: str) -> None:
        super().__init__(message)
        self.prog = prog


class Parser(argparse.ArgumentParser):
    """An ArgumentParser whose errors raise :class:`UsageError` instead of exiting with 2.

    ``add_subparsers`` builds its subparsers with the parent's class, so subcommands inherit
    this behaviour.
    """

    def error(self, message: str) -> NoReturn:
        raise UsageError(self.prog, f"{message} (see '{self.prog} --help')")


# --- option value types: every value is validated where it enters --------------------------


def _integer(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None


def _finite_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return value


def _output_folder(text: str) -> Path:
    if not text:
        raise argparse.ArgumentTypeError("empty path")
    path = Path(text)
    if path.exists() and not path.is_dir():
        raise argparse.ArgumentTypeError(f"{text}: exists and is not a folder")
    return path


def _output_file(text: str) -> Path:
    if not text:
        raise argparse.ArgumentTypeError("empty path")
    path = Path(text)
    if path.is_dir():
        raise argparse.ArgumentTypeError(f"{text}: is a folder (give a file name)")
    if not path.parent.is_dir():
        raise argparse.ArgumentTypeError(f"{text}: folder {path.parent} does not exist")
    return path
