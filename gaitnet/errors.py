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
