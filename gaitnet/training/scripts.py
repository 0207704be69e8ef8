"""What the entry scripts (``train/*.py``, ``export/*.py``) share: the error contract of a command.

As ``gaitnet`` itself (:data:`gaitnet.errors.USER_ERRORS`): bad input, i.e. a
:class:`~gaitnet.errors.GaitnetError` or an ``OSError`` on a user's path, and a usage error, is
ONE line on stderr and exit status 1; anything else is a bug and keeps its traceback. The
scripts print (library code does not):

    try:
        return main(ScriptParser(...).parse_args(argv))
    except USER_ERRORS as exc:
        print(f"error: {user_error_message(exc)}", file=sys.stderr)
        return 1
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
