"""Exceptions that the command line turns into one-line messages and a non-zero exit."""


class GaitnetError(Exception):
    """Base class of every error a user can cause with their input (files, configs, options)."""


class ConfigError(GaitnetError):
    """A config file or override is invalid; the message names the file and the key."""


class SessionError(GaitnetError):
    """A recorded session (folder or bag) is broken; the message names the file and problem."""
