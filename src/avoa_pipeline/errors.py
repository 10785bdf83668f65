"""Errors a user can fix. The CLI prints them as one line and exits 2, without a traceback."""


class UserError(Exception):
    """Bad input: a file, a field or an argument the user gave. The message names it."""


class ConfigError(UserError):
    """An impossible or malformed configuration."""


class DataError(UserError):
    """A malformed or inconsistent data file."""
