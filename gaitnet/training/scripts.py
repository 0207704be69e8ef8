"""What the entry scripts (``train/*.py``, ``export/*.py``) share: the error contract of a command.

As ``gaitnet`` itself (gaitnet/errors.py): bad input, i.e. a :class:`~gaitnet.errors.GaitnetError`
or an ``OSError`` on a user's path, and a usage error, is ONE line on stderr and exit status 1;
anything else is a bug and keeps its traceback. The scripts print (library code does not):

    try:
        return main(ScriptParser(...).parse_args(argv))
    except USER_ERRORS as exc:
        print(f"error: {error_line(exc)}", file=sys.stderr)
        return 1
"""

from __future__ import annotations

import argparse
from typing import NoReturn

from gaitnet.errors import GaitnetError, InputError

__all__ = ["USER_ERRORS", "ScriptParser", "error_line"]

#: Exceptions that are the user's input, not a bug.
USER_ERRORS: tuple[type[BaseException], ...] = (GaitnetError, OSError)


class ScriptParser(argparse.ArgumentParser):
    """An argument parser whose usage errors are an :class:`InputError` (one line, exit 1)
    instead of argparse's usage block and exit status 2."""

    def error(self, message: str) -> NoReturn:
        raise InputError(f"{self.prog}: {message} (see --help)")


def error_line(exc: BaseException) -> str:
    """The exception's message on one line (whitespace, newlines included, collapsed)."""
    return " ".join(str(exc).split()) or type(exc).__name__
