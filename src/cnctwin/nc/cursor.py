"""Where the interpreter is reading, shared by the parts of the interpreter that report.

One :class:`ProgramCursor` is shared by the block executor, the modal, offset, tool and
motion state and the O-word control: errors and warnings name the file and line it holds,
and segments carry them.
"""

from __future__ import annotations

from cnctwin.errors import NCError

__all__ = ["ProgramCursor"]


class ProgramCursor:
    """The file and line being read, and the warnings collected so far.

    Attributes
    ----------
    file
        Name of the file being read (``"<string>"`` for text).
    line
        1-based line being read; 0 before the first line.
    warnings
        ``"FILE:LINE: message"`` for everything accepted but worth a look, in order.
    """

    __slots__ = ("file", "line", "warnings")

    def __init__(self) -> None:
        self.file = "<string>"
        self.line = 0
        self.warnings: list[str] = []

    def error(self, message: str) -> NCError:
        """An :class:`~cnctwin.errors.NCError` at the current file and line (to raise)."""
        return NCError(message, self.file, self.line)

    def locate(self, err: NCError) -> NCError:
        """``err`` itself if it names a line, else the same message at the current line."""
        if err.line:
            return err
        return NCError(err.message, self.file, self.line, err.column)

    def warn(self, message: str) -> None:
        """Record a warning at the current file and line."""
        self.warnings.append(f"{self.file}:{self.line}: {message}")
