"""The entry scripts' error contract (``train/``, ``export/``, ``data/``, ``benchmarks/``), as
``gaitnet``'s own: a user's error (:data:`gaitnet.errors.USER_ERRORS`, and a usage error of a
:class:`gaitnet.training.scripts.ScriptParser`) is one line on stderr and exit status 1, an
interrupt exit status 130; a module of the ``train`` extra missing from a core install
is one line naming it and the install command; anything else is a bug and keeps its
traceback. It prints, so it
lives at the top layer with the CLI::

    if __name__ == "__main__":
        raise SystemExit(run_script(main))
"""

from __future__ import annotations

import sys
from collections.abc import Callable

from gaitnet.errors import USER_ERRORS, user_error_message

__all__ = ["TRAIN_EXTRA_MODULES", "missing_train_extra", "run_script"]

#: What the ``train`` extra adds to the core install (PyTorch, ONNX export, training logs): a
#: script that needs one of them without it says so in one line.
TRAIN_EXTRA_MODULES = frozenset({"torch", "torchvision", "onnx", "onnxscript", "tensorboard"})


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
    except ModuleNotFoundError as exc:
        message = missing_train_extra(exc)
        if message is None:
            raise
        print(message, file=sys.stderr)
        return 1
    return int(status or 0)


def missing_train_extra(exc: ModuleNotFoundError) -> str | None:
    """The one line for a module of the ``train`` extra that is not installed (None for any
    other missing module, which is a bug)."""
    if exc.name not in TRAIN_EXTRA_MODULES:
        return None
    return f"error: {exc.name} is not installed: pip install -e '.[train]'"
