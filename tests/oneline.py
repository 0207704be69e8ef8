"""The one assertion every fuzz test makes: a user's error is exactly one line.

Two forms of it: :func:`assert_one_line_exit` for a command (exit status 1 and one stderr
line), :func:`assert_one_line_message` for a library call (a :class:`GaitnetError` whose
message is one line). Both return the line, for the checks a test adds of its own.
"""

from __future__ import annotations

import pytest

from gaitnet.errors import GaitnetError


def assert_one_line_exit(stderr: str | pytest.CaptureFixture[str], rc: int, *fragments: str) -> str:
    """Exit status 1 and a stderr of exactly one non-empty, newline-ended line, no traceback,
    containing each of ``fragments``. ``stderr`` is the text, or ``capsys`` to read it from."""
    err = stderr if isinstance(stderr, str) else stderr.readouterr().err
    assert rc == 1, (rc, err)
    assert "Traceback" not in err, err
    lines = err.splitlines()
    assert len(lines) == 1 and err.count("\n") == 1 and err.endswith("\n"), repr(err)
    line = lines[0]
    assert line.strip(), repr(err)
    for fragment in fragments:
        assert fragment in line, (fragment, line)
    return line


def assert_one_line_message(
    exc: BaseException | pytest.ExceptionInfo[BaseException],
    *fragments: str,
    error_type: type[BaseException] = GaitnetError,
) -> str:
    """The exception (or ``pytest.raises``'s ``excinfo``) is an ``error_type`` whose message is
    one non-empty line containing each of ``fragments``."""
    value = exc.value if isinstance(exc, pytest.ExceptionInfo) else exc
    message = str(value)
    assert isinstance(value, error_type), (type(value), message)
    assert message.strip() and "\n" not in message, repr(message)
    for fragment in fragments:
        assert fragment in message, (fragment, message)
    return message
