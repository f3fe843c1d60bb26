"""Exception types.

Every error a user can cause (bad file, bad option, unsafe trajectory, lost connection) is an
:class:`UridentError`. Its message is one line that names the file, line or key at fault; the CLI
prints it without a traceback and exits non-zero.
"""

from __future__ import annotations


class UridentError(Exception):
    """Base class of all user-facing errors. ``exit_code`` is what the CLI returns; ``data`` holds
    what the message names as fields (e.g. ``path``, ``line``, ``key``, ``violations``,
    ``log_path``), each also an attribute, for callers of the Python API."""

    exit_code = 2

    def __init__(self, *args: object, **data: object) -> None:
        super().__init__(*args)
        self.data = data
        for name, value in data.items():
            setattr(self, name, value)


class ConfigError(UridentError, ValueError):
    """A robot, experiment, trajectory or effects file is malformed or inconsistent."""


class LogFormatError(UridentError, ValueError):
    """A log file is malformed, truncated or holds unusable values."""


class UnknownRobotError(ConfigError, KeyError):
    """The requested robot name has no robot file."""

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0]) if self.args else ""


class SafetyError(UridentError):
    """A trajectory or robot state failed a safety check; nothing was moved."""

    exit_code = 3


class ControllerUnreachable(SafetyError, ConnectionError):
    """No controller answers at the address (or it failed before any motion); nothing moved."""


class SessionAborted(UridentError):
    """A running session stopped the robot before the end (monitor, fault or operator)."""

    exit_code = 4


class Interrupted(UridentError):
    """A signal (SIGTERM, SIGHUP) ended the command before any motion."""

    exit_code = 130


class ConnectionLost(SessionAborted, ConnectionError):
    """The controller stopped answering."""


def shown(value: object, limit: int = 60) -> str:
    """``value`` as it may appear inside a one-line message: control characters escaped, long
    text shortened (user input such as a YAML key can hold newlines)."""
    text = str(value).encode("unicode_escape").decode("ascii")
    return text if len(text) <= limit else text[: limit - 1] + "…"


class OutputError(UridentError):
    """An output path cannot be written safely: it exists (without ``--overwrite``), is a
    symbolic link or a directory, or its directory is missing or not writable."""
