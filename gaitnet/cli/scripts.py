"""The entry scripts' error contract (``train/``, ``export/``, ``data/``, ``benchmarks/``), as
``gaitnet``'s own: a user's error (:data:`gaitnet.errors.USER_ERRORS`, and a usage error of a
:class:`gaitnet.training.scripts.ScriptParser`) is one line on stderr and exit status 1, an
interrupt exit status 130; anything else is a bug and keeps its traceback. It prints, so it
lives at the top layer with the CLI::

    if __name__ == "__main__":
        raise SystemExit(run_script(main))
"""

from __future__ import annotations

import sys
from collections.abc import Callable

from gaitnet.errors import USER_ERRORS, user_error_message

__all__ = ["run_script"]


def run_script(main: Callable[[], int | None]) -> int:
    """``main()``'s exit status (None: 0) under the module's contract."""
    try:
        status = main()
    except USER_ERRORS as exc:
        print(f"error: {user_error_message(exc)}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("error: interrupted", file=sys.stderr)
        return 130
    return int(status or 0)
