"""The benchmark scripts' error contract, as ``gaitnet``'s and the ``train/`` scripts'
(:mod:`gaitnet.training.scripts`): a user's mistake (a :class:`~gaitnet.errors.GaitnetError`,
an ``OSError`` on a path, a usage error of a :class:`~gaitnet.training.scripts.ScriptParser`)
is one line on stderr and exit status 1, an interrupt exit status 130; anything else is a bug
and keeps its traceback. Each script ends with::

    if __name__ == "__main__":
        from script_errors import run_script

        raise SystemExit(run_script(main))
"""

from __future__ import annotations

import sys
from collections.abc import Callable

from gaitnet.errors import USER_ERRORS, user_error_message


def run_script(main: Callable[[], int | None]) -> int:
    """``main()``'s exit status (None: 0) under the contract above."""
    try:
        status = main()
    except USER_ERRORS as exc:
        print(f"error: {user_error_message(exc)}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("error: interrupted", file=sys.stderr)
        return 130
    return int(status or 0)
