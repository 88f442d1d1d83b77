"""The cnctwin error hierarchy.

Every error the library raises on bad input derives from :class:`CnctwinError`.
Each message names the bad value and what would be valid; the CLI prints the
message on one line and exits with status 2, never with a traceback.

The hierarchy::

    CnctwinError
    +-- InputError (also ValueError)    an argument of a public function or option is invalid
    |   +-- ConfigError                 ... and it came from a configuration file or table
    +-- DataError (also ValueError)     a data file or record cannot be read or is inconsistent
    +-- NCError (also ValueError)       an NC program cannot be interpreted
"""

from __future__ import annotations

__all__ = [
    "CnctwinError",
    "ConfigError",
    "DataError",
    "InputError",
    "NCError",
]


class CnctwinError(Exception):
    """Root of every error cnctwin raises on purpose."""


class InputError(CnctwinError, ValueError):
    """An argument is invalid: a value given to a public function or a command-line option.

    The message names the argument (or option), the value given and what would be valid,
    with its unit, e.g. ``"depth_m -0.001: give a depth > 0 m"``.
    """


class ConfigError(InputError):
    """A configuration file or value is invalid.

    Parameters
    ----------
    message
        What is wrong, naming the value and what would be valid.
    source
        The file (or other origin) of the configuration, if known.
    """

    def __init__(self, message: str, source: str | None = None) -> None:
        self.message = message
        self.source = source
        super().__init__(f"{source}: {message}" if source else message)


class DataError(CnctwinError, ValueError):
    """A data file (measurement, table, record) cannot be read or is inconsistent."""


class NCError(CnctwinError, ValueError):
    """An NC program cannot be interpreted.

    Parameters
    ----------
    message
        What is wrong, naming the construct or value and what would be valid.
    file
        Name of the NC file (``"<string>"`` for programs given as text).
    line
        1-based line number in ``file``; 0 when the error is not tied to a line.
    column
        1-based column of the offending text, or ``None`` when unknown.

    Notes
    -----
    ``str(error)`` is ``"FILE:LINE: message"``, the form the CLI prints.
    """

    def __init__(
        self,
        message: str,
        file: str = "<string>",
        line: int = 0,
        column: int | None = None,
    ) -> None:
        self.message = message
        self.file = file
        self.line = line
        self.column = column
        super().__init__(message)

    def __str__(self) -> str:
        where = f"{self.file}:{self.line}" if self.line else self.file
        return f"{where}: {self.message}"

    def __reduce__(self) -> tuple[type[NCError], tuple[str, str, int, int | None]]:
        return (type(self), (self.message, self.file, self.line, self.column))
