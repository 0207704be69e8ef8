"""What the entry scripts (``train/*.py``, ``export/*.py``, ``data/*.py``, ``benchmarks/*.py``)
share: a usage error is an :class:`~gaitnet.errors.InputError`, so that
:func:`gaitnet.cli.scripts.run_script` (the contract of a command, as ``gaitnet`` itself: bad
input is ONE line on stderr and exit status 1; anything else is a bug and keeps its traceback)
reports it like any other bad input.
"""

from __future__ import annotations

import argparse
from typing import NoReturn

from gaitnet.errors import InputError

__all__ = ["ScriptParser"]


class ScriptParser(argparse.ArgumentParser):
    """An argument parser whose usage errors are an :class:`InputError` (one line, exit 1)
    instead of argparse's usage block and exit status 2."""

    def error(self, message: str) -> NoReturn:
        raise InputError(f"{self.prog}: {message} (see --help)")
