"""Lines of an NC file, read lazily, with the byte offsets that O-word jumps need.

The file is never held in memory as a whole: lines are read one at a time, and only the
positions of O-word statements that may be jumped back to are remembered.
"""

from __future__ import annotations

import io
from collections.abc import Iterator
from pathlib import Path
from typing import BinaryIO

__all__ = ["LineSource"]


class LineSource:
    """A seekable stream of numbered lines.

    Parameters
    ----------
    stream
        A binary, seekable stream positioned at the start of the program.
    name
        The name used in error messages (usually the file path).
    """

    def __init__(self, stream: BinaryIO, name: str) -> None:
        self.name = name
        self._stream = stream
        self._pending: tuple[int, int] | None = None
        self.offset = 0
        self.lineno = 0

    @classmethod
    def from_path(cls, path: str | Path) -> LineSource:
        """Open a file (read lazily, binary, decoded as UTF-8 with replacement)."""
        return cls(open(path, "rb"), str(path))  # noqa: SIM115 - closed by close()

    @classmethod
    def from_text(cls, text: str, name: str = "<string>") -> LineSource:
        """Wrap program text held in memory."""
        return cls(io.BytesIO(text.encode("utf-8")), name)

    def close(self) -> None:
        """Close the underlying stream."""
        self._stream.close()

    def seek(self, offset: int, lineno: int) -> None:
        """Continue at byte ``offset``, which starts line ``lineno + 1``."""
        self._pending = (offset, lineno)

    def __iter__(self) -> Iterator[tuple[int, int, str]]:
        """Yield ``(line_number, start_offset, text)`` for each line, honouring seeks.

        ``self.offset`` is the offset just past the yielded line and ``self.lineno`` its
        1-based number while the caller handles it.
        """
        stream = self._stream
        while True:
            if self._pending is not None:
                self.offset, self.lineno = self._pending
                self._pending = None
                stream.seek(self.offset)
            for raw in stream:
                start = self.offset
                self.offset = start + len(raw)
                self.lineno += 1
                yield self.lineno, start, raw.decode("utf-8", "replace").rstrip("\r\n")
                if self._pending is not None:
                    break
            else:
                return
