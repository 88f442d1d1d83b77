"""Lines of an NC file, read lazily in bounded chunks, with the byte offsets that O-word
jumps need.

The file is never held in memory as a whole: it is read in chunks of
:data:`CHUNK_BYTES`, and only the positions of O-word statements that may be jumped back
to are remembered. CR, LF and CR LF (mixed freely) all end a line. Reading is bounded:
only regular files are opened (never a FIFO or a device such as ``/dev/zero``), a file
larger than its byte limit, a line longer than :data:`~cnctwin.nc.limits.MAX_LINE_BYTES`
and a NUL byte (a binary file) are refused, and the lines read again after jumps back
are counted against a :class:`RepeatBudget`.
"""

from __future__ import annotations

import io
import os
import re
import stat
from collections.abc import Iterator
from pathlib import Path
from typing import BinaryIO, Final

from cnctwin.errors import NCError
from cnctwin.nc.limits import MAX_LINE_BYTES, MAX_PROGRAM_BYTES, MAX_REPEATED_LINES

__all__ = ["CHUNK_BYTES", "LineSource", "RepeatBudget"]

#: Bytes read from the file at a time; a run of moves read in bulk (:mod:`cnctwin.nc.runs`)
#: is taken from one chunk, so larger chunks make fewer, longer runs.
CHUNK_BYTES: Final = 262_144
_EOL: Final = re.compile(rb"\r\n|\r|\n")
_CR: Final = 13


class RepeatBudget:
    """How many more lines O-word loops and subroutine calls may read again.

    One budget is shared by the program and the subroutine files it opens.

    Parameters
    ----------
    limit
        Lines that may be read a second (or later) time, >= 0.
    """

    __slots__ = ("limit", "remaining")

    def __init__(self, limit: int = MAX_REPEATED_LINES) -> None:
        self.limit = limit
        self.remaining = limit

    def charge(self, name: str, lineno: int) -> None:
        """Count one line read again.

        Raises
        ------
        NCError
            When more than ``limit`` lines have been read again.
        """
        self.remaining -= 1
        if self.remaining < 0:
            raise NCError(
                f"more than {self.limit} lines were executed again by O-word loops and "
                "subroutine calls: stopped as a runaway program (raise the limit with "
                "--max-repeated-lines or NCSetup.max_repeated_lines if it is meant to)",
                name,
                lineno,
            )


class LineSource:
    """A seekable stream of numbered lines.

    Parameters
    ----------
    stream
        A binary, seekable stream positioned at the start of the program.
    name
        The name used in error messages (usually the file path).
    max_bytes
        Largest program accepted, bytes.
    budget
        The budget of lines read again, shared with other sources of the same program;
        a fresh one of :data:`~cnctwin.nc.limits.MAX_REPEATED_LINES` if omitted.
    """

    def __init__(
        self,
        stream: BinaryIO,
        name: str,
        max_bytes: int = MAX_PROGRAM_BYTES,
        budget: RepeatBudget | None = None,
    ) -> None:
        self.name = name
        self.max_bytes = max_bytes
        self.budget = budget if budget is not None else RepeatBudget()
        self._stream = stream
        self._pending: tuple[int, int] | None = None
        self._seen_to = 0
        # The bytes read last (from file offset _cache_base; to the end of the file if
        # _cache_eof): a jump back into them (a loop) reads nothing again.
        self._cache = b""
        self._cache_base = 0
        self._cache_eof = False
        # _cache decoded, when it is ASCII without CR (its lines end at LF and its
        # character offsets are its byte offsets); else None.
        self._cache_text: str | None = ""
        self.offset = 0
        self.lineno = 0

    @classmethod
    def from_path(
        cls,
        path: str | Path,
        max_bytes: int = MAX_PROGRAM_BYTES,
        budget: RepeatBudget | None = None,
    ) -> LineSource:
        """Open a regular file (read lazily, binary, decoded as UTF-8 with replacement).

        Raises
        ------
        NCError
            If ``path`` is not a regular file (a FIFO, device or directory) or is larger
            than ``max_bytes``.
        OSError
            If it cannot be opened.
        """
        name = str(path)
        # Non-blocking, so that opening a FIFO without a writer does not wait forever.
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_BINARY", 0))
        try:
            info = os.fstat(fd)
            if not stat.S_ISREG(info.st_mode):
                raise NCError(
                    "not a regular file (a FIFO, device or directory): NC programs are read "
                    "from files",
                    name,
                )
            if info.st_size > max_bytes:
                raise NCError(
                    f"the file has {info.st_size} bytes; at most {max_bytes} are read "
                    "(raise the limit with --max-bytes or NCSetup.max_program_bytes)",
                    name,
                )
            stream = os.fdopen(fd, "rb")
        except BaseException:
            os.close(fd)
            raise
        return cls(stream, name, max_bytes, budget)

    @classmethod
    def from_text(
        cls, text: str, name: str = "<string>", budget: RepeatBudget | None = None
    ) -> LineSource:
        """Wrap program text held in memory (no byte limit: the caller holds it already)."""
        data = text.encode("utf-8", "replace")
        return cls(io.BytesIO(data), name, max(len(data), MAX_PROGRAM_BYTES), budget)

    def close(self) -> None:
        """Close the underlying stream."""
        self._stream.close()

    def seek(self, offset: int, lineno: int) -> None:
        """Continue at byte ``offset``, which starts line ``lineno + 1``."""
        self._pending = (offset, lineno)

    def ahead(self) -> bytes | None:
        """The bytes read from the file after the current line (the next lines, the last
        perhaps incomplete), when they are read for the first time and no seek is pending;
        else ``None``. See :meth:`skip`."""
        if self._pending is not None or self.offset < self._seen_to:
            return None
        at = self.offset - self._cache_base
        if not 0 <= at <= len(self._cache):
            return None
        return self._cache[at:]

    def skip(self, size: int, lines: int) -> None:
        """Go on ``size`` bytes, ``lines`` complete lines, further (taken from
        :meth:`ahead` and handled by the caller)."""
        self.offset += size
        self.lineno += lines
        self._seen_to = self.offset

    def _read(self, at: int) -> bytes:
        """The next chunk, which starts at byte ``at``; checked for size and NUL bytes."""
        chunk = self._stream.read(CHUNK_BYTES)
        if at + len(chunk) > self.max_bytes:
            raise NCError(
                f"the program is longer than {self.max_bytes} bytes (raise the limit "
                "with --max-bytes or NCSetup.max_program_bytes)",
                self.name,
            )
        nul = chunk.find(b"\0")
        if nul >= 0:
            raise NCError(
                f"NUL byte at byte offset {at + nul}: this is a binary file, not an NC "
                "program (NC programs are text)",
                self.name,
            )
        return chunk

    def _too_long(self) -> NCError:
        return NCError(
            f"line longer than {MAX_LINE_BYTES} bytes: not an NC program line",
            self.name,
            self.lineno + 1,
        )

    def _moved(self, offset: int) -> bool:
        """Whether a seek, or another reader of this source (a forward scan for an O-word),
        moved on from byte ``offset`` while a line was handled. A method, not an
        expression in :meth:`__iter__`: there mypy would keep ``_pending`` narrowed to
        ``None`` across the ``yield``, and code compiled by mypyc would check it."""
        return self._pending is not None or self.offset != offset

    def __iter__(self) -> Iterator[tuple[int, int, str]]:
        """Yield ``(line_number, start_offset, text)`` for each line, honouring seeks.

        ``text`` is without its line terminator. ``self.offset`` is the offset just past
        the yielded line and ``self.lineno`` its 1-based number while the caller handles
        it. Several iterators may take turns on one source: each goes on from where the
        last one left ``self.offset``.
        """
        while True:
            if self._pending is not None:
                self.offset, self.lineno = self._pending
                self._pending = None
            base = self._cache_base  # file offset of buf[0]
            buf = self._cache
            if base <= self.offset <= base + len(buf):
                p = self.offset - base
                eof = self._cache_eof
                text = self._cache_text
            else:
                base = self.offset
                buf = b""
                p = 0
                eof = False
                text = ""
            while True:
                if text is not None:
                    # ASCII without CR: the line ends at the next LF.
                    stop = text.find("\n", p)
                    found = stop >= 0
                    end = stop + 1
                else:
                    match = _EOL.search(buf, p)
                    found = match is not None and (
                        eof or match.end() < len(buf) or buf[match.start()] != _CR
                    )
                    if match is not None:
                        stop, end = match.span()
                if not found:
                    if not eof:
                        if len(buf) - p > MAX_LINE_BYTES:
                            raise self._too_long()
                        self._stream.seek(base + len(buf))
                        chunk = self._read(base + len(buf))
                        if not chunk:
                            eof = True
                        buf = buf[p:] + chunk
                        base += p
                        p = 0
                        text = buf.decode("ascii") if buf.isascii() and b"\r" not in buf else None
                        self._cache, self._cache_base, self._cache_eof = buf, base, eof
                        self._cache_text = text
                        continue
                    if p >= len(buf):
                        return
                    stop = end = len(buf)
                if stop - p > MAX_LINE_BYTES:
                    raise self._too_long()
                start = base + p
                line = text[p:stop] if text is not None else buf[p:stop].decode("utf-8", "replace")
                p = end
                self.offset = base + end
                self.lineno += 1
                if start < self._seen_to:
                    self.budget.charge(self.name, self.lineno)
                else:
                    self._seen_to = self.offset
                yield self.lineno, start, line
                if self._moved(base + p):
                    break
