"""The project's error taxonomy: what a user caused versus what is a bug.

* :class:`GaitnetError` and its subclasses: the *input* is wrong (a file, a config value, a
  command-line option, a model file, a data set). The message is one line that names the file,
  key or option and says what is wrong; the command line prints it and exits with code 1.
* ``OSError`` raised while reading or writing a path the user named (permission denied, disk
  full, a folder where a file was expected): the command line also prints one line and exits 1.
* Anything else (``ValueError``, ``IndexError``, ...) escaping the library is a **bug** in
  gaitnet: the command line prints the traceback, asks for a report and exits with code 2
  (docs/cli.md, *Exit status and errors*). Library code therefore
  validates every value where it enters (configs, session files, bags, result folders, model
  inputs) and raises one of the classes below; it never lets a user's mistake surface as a bare
  ``ValueError`` from deep inside numpy or torch.
"""


class GaitnetError(Exception):
    """Base class of every error a user can cause with their input (files, configs, options)."""


class ConfigError(GaitnetError):
    """A config file or override is invalid; the message names the file and the key."""


class SessionError(GaitnetError):
    """A recorded session (folder or bag) is broken; the message names the file and problem."""


class InputError(GaitnetError):
    """Any other bad input: a command-line value, a result folder, a model or checkpoint file,
    a data set, labelme annotations, arrays handed to a model. The message names the file,
    option or input and what is wrong."""


#: What the commands and entry scripts report as the user's error (one line, exit status 1).
USER_ERRORS: tuple[type[BaseException], ...] = (GaitnetError, OSError)


def one_line(text: object, limit: int | None = None) -> str:
    """``text`` as one printable line: whitespace runs (newlines included) collapsed,
    undecodable bytes (surrogate escapes from argv or file names) shown as ``\\xNN``, and cut
    to ``limit`` characters when given (for messages quoted from other libraries)."""
    line = " ".join(str(text).split())
    line = line.encode("utf-8", "surrogateescape").decode("utf-8", "backslashreplace")
    if limit is not None and len(line) > limit:
        line = line[: limit - 3] + "..."
    return line


def user_error_message(exc: BaseException) -> str:
    """The one-line message of a user's error; an ``OSError`` reads ``PATH: reason`` (no errno
    numbers)."""
    if isinstance(exc, OSError) and not isinstance(exc, GaitnetError):
        reason = exc.strerror or str(exc)
        names = [str(n) for n in (exc.filename, exc.filename2) if n is not None]
        text = f"{' -> '.join(names)}: {reason}" if names else reason
    else:
        text = str(exc)
    return one_line(text) or type(exc).__name__
