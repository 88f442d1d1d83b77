"""O-word subroutines and control flow (LinuxCNC): sub/endsub/call/return, do/while,
while/endwhile, if/elseif/else/endif, repeat/endrepeat, break/continue.

Control flow works on the :class:`~cnctwin.nc.source.LineSource` being read: jumps back seek
to remembered byte offsets, jumps forward read ahead to the matching statement, so a program
is never held in memory. The interpreter hands each O-word statement to
:meth:`OWordControl.execute` and reads from the top of :attr:`OWordControl.sources`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Final

from cnctwin.errors import NCError
from cnctwin.nc.cursor import ProgramCursor
from cnctwin.nc.expressions import Parameters, read_value, read_value_once
from cnctwin.nc.lexer import OWord, read_oword, strip_comments
from cnctwin.nc.source import LineSource

__all__ = ["OWordControl", "MAX_CALL_DEPTH", "MAX_LOOP_ITERATIONS"]

#: Upper bound on the iterations of one O-word loop (and on a repeat count), against
#: runaway programs; a loop of a few lines reaches it in a few seconds.
MAX_LOOP_ITERATIONS = 100_000
#: Most subroutine calls open at once: LinuxCNC refuses a tenth nested call
#: ("Too many subroutine levels"), so cnctwin does too.
MAX_CALL_DEPTH: Final = 9


class OWordControl:
    """O-word statements: subroutines, loops and conditionals.

    Parameters
    ----------
    params
        The program's parameters (conditions, call arguments, ``#<_value>``).
    where
        The file and line being read: errors name it, and reading ahead moves its line.

    Attributes
    ----------
    sources
        The sources being read: the program, then the subroutine files called (the
        interpreter reads from the last one).
    """

    __slots__ = ("sources", "_params", "_where", "_frames", "_subs", "_handlers")

    def __init__(self, params: Parameters, where: ProgramCursor) -> None:
        self.sources: list[LineSource] = []
        self._params = params
        self._where = where
        # Open frames: ("call", label, source, offset, line), ("if", label, True),
        # ("do" | "while" | "repeat", label, offset, line, count).
        self._frames: list[tuple[Any, ...]] = []
        # Subroutine label -> (source, offset, line) of its body.
        self._subs: dict[str, tuple[LineSource, int, int]] = {}
        self._handlers = {
            "sub": self._sub,
            "call": self._call,
            "endsub": self._return,
            "return": self._return,
            "if": self._if,
            "elseif": self._else,
            "else": self._else,
            "endif": self._endif,
            "do": self._do,
            "while": self._while,
            "endwhile": self._endwhile,
            "repeat": self._repeat,
            "endrepeat": self._endrepeat,
            "break": self._break,
            "continue": self._continue,
        }

    def execute(self, ow: OWord, src: LineSource, line_start: int) -> bool:
        """Execute an O-word statement read from ``src`` on a line that starts at byte
        ``line_start``. Returns True if the source to read from changed (a call into, or
        a return from, a subroutine file).

        Raises
        ------
        NCError
            For a statement without its match, a runaway loop, a call too deep or to an
            unknown subroutine, and bad conditions or arguments.
        """
        handler = self._handlers.get(ow.keyword)
        if handler is None:  # pragma: no cover - the lexer accepts only the keywords above
            raise self._where.error(f"o-word keyword '{ow.keyword}' is not supported")
        return handler(ow, src, line_start)

    # ------------------------------------------------------------------ statements
    def _sub(self, ow: OWord, src: LineSource, line_start: int) -> bool:
        label = ow.label
        known = self._subs.get(label)
        if known is not None and known[0] is src and known[1] != src.offset:
            raise self._where.error(f"o{label} sub is defined twice")
        self._subs[label] = (src, src.offset, src.lineno)
        self._skip_to(src, label, ("endsub",))
        return False

    def _if(self, ow: OWord, src: LineSource, line_start: int) -> bool:
        if self._condition(ow):
            self._frames.append(("if", ow.label, True))
        else:
            self._branch(src, ow.label)
        return False

    def _else(self, ow: OWord, src: LineSource, line_start: int) -> bool:
        label = ow.label
        frame = self._top_frame("if", label, ow.keyword)
        if not frame[2]:
            raise self._where.error(f"o{label} {ow.keyword} without a matching o{label} if")
        self._skip_to(src, label, ("endif",))
        self._frames.pop()
        return False

    def _endif(self, ow: OWord, src: LineSource, line_start: int) -> bool:
        self._top_frame("if", ow.label, ow.keyword)
        self._frames.pop()
        return False

    def _do(self, ow: OWord, src: LineSource, line_start: int) -> bool:
        self._frames.append(("do", ow.label, src.offset, src.lineno, 0))
        return False

    def _while(self, ow: OWord, src: LineSource, line_start: int) -> bool:
        label = ow.label
        frames = self._frames
        if frames and frames[-1][0] == "do" and frames[-1][1] == label:
            if self._condition(ow):
                self._loop_back(src, frames[-1])
            else:
                frames.pop()
            return False
        if not (frames and frames[-1][0] == "while" and frames[-1][1] == label):
            # Remember where the while statement starts, to evaluate it again.
            frames.append(("while", label, line_start, src.lineno - 1, 0))
        if not self._condition(ow):
            frames.pop()
            self._skip_to(src, label, ("endwhile",))
        return False

    def _endwhile(self, ow: OWord, src: LineSource, line_start: int) -> bool:
        self._loop_back(src, self._top_frame("while", ow.label, ow.keyword))
        return False

    def _repeat(self, ow: OWord, src: LineSource, line_start: int) -> bool:
        label = ow.label
        count = self._argument(ow)
        if count != int(count) or not 0 <= count <= MAX_LOOP_ITERATIONS:
            raise self._where.error(
                f"o{label} repeat count {count:g} must be a whole number from 0 to "
                f"{MAX_LOOP_ITERATIONS}"
            )
        if count == 0:
            self._skip_to(src, label, ("endrepeat",))
        else:
            self._frames.append(("repeat", label, src.offset, src.lineno, int(count)))
        return False

    def _endrepeat(self, ow: OWord, src: LineSource, line_start: int) -> bool:
        frame = self._top_frame("repeat", ow.label, ow.keyword)
        remaining = frame[4] - 1
        self._frames.pop()
        if remaining > 0:
            self._frames.append((frame[0], frame[1], frame[2], frame[3], remaining))
            src.seek(frame[2], frame[3])
        return False

    def _break(self, ow: OWord, src: LineSource, line_start: int) -> bool:
        label = ow.label
        while self._frames:
            frame = self._frames.pop()
            if frame[1] == label and frame[0] in ("while", "do", "repeat"):
                end = {"while": ("endwhile",), "do": ("while",), "repeat": ("endrepeat",)}
                self._skip_to(src, label, end[frame[0]])
                return False
            if frame[0] == "call":
                break
        raise self._where.error(f"o{label} break outside an o{label} loop")

    def _continue(self, ow: OWord, src: LineSource, line_start: int) -> bool:
        label = ow.label
        for index in range(len(self._frames) - 1, -1, -1):
            frame = self._frames[index]
            if frame[1] == label and frame[0] in ("while", "do", "repeat"):
                del self._frames[index + 1 :]
                if frame[0] == "while":
                    self._loop_back(src, frame)
                    return False
                closing = ("endrepeat",) if frame[0] == "repeat" else ("while",)
                self._skip_to(src, label, closing, stop_before=True)
                return False
            if frame[0] == "call":
                break
        raise self._where.error(f"o{label} continue outside an o{label} loop")

    # ------------------------------------------------------------------ helpers
    def _top_frame(self, kind: str, label: str, keyword: str) -> tuple[Any, ...]:
        if not self._frames or self._frames[-1][0] != kind or self._frames[-1][1] != label:
            raise self._where.error(f"o{label} {keyword} without a matching o{label} {kind}")
        return self._frames[-1]

    def _loop_back(self, src: LineSource, frame: tuple[Any, ...]) -> None:
        count = frame[4] + 1
        if count > MAX_LOOP_ITERATIONS:
            raise self._where.error(
                f"o{frame[1]} loop ran {MAX_LOOP_ITERATIONS} times: stopped as a runaway loop"
            )
        self._frames[-1] = (frame[0], frame[1], frame[2], frame[3], count)
        src.seek(frame[2], frame[3])

    def _condition(self, ow: OWord) -> bool:
        return self._argument(ow) != 0.0

    def _argument(self, ow: OWord) -> float:
        text, start = ow.text, ow.args_pos
        if start >= len(text):
            raise self._where.error(f"o{ow.label} {ow.keyword} needs a [condition]")
        # Read from the argument's own text, so that the statements of every label with
        # this argument share its compiled reading; an error is read again in place (its
        # column, and a column its message names, count from the statement's start).
        try:
            value, end = read_value(text[start:], 0, self._params)
        except NCError:
            read_value_once(text, start, self._params)
            raise
        pos = start + end
        if pos != len(ow.text):
            raise self._where.error(
                f"unexpected text '{ow.text[pos:]}' after o{ow.label} {ow.keyword} [...]"
            )
        return value

    def _branch(self, src: LineSource, label: str) -> None:
        """The if (or elseif) condition was false: find the branch to run."""
        while True:
            ow = self._skip_to(src, label, ("elseif", "else", "endif"))
            if ow.keyword == "endif":
                return
            if ow.keyword == "else":
                self._frames.append(("if", label, True))
                return
            if self._condition(ow):
                self._frames.append(("if", label, True))
                return

    def _skip_to(
        self, src: LineSource, label: str, keywords: tuple[str, ...], stop_before: bool = False
    ) -> OWord:
        """Read forward to the O-word ``o<label> <keyword>``; return it."""
        start_line = self._where.line
        for lineno, start, raw in src:
            self._where.line = lineno
            low = raw.lower()
            if "o" not in low:
                continue
            if "(" in raw or ";" in raw:
                try:
                    text = "".join(strip_comments(raw).split()).lower()
                except NCError:
                    continue
            else:
                text = "".join(low.split())
            if not text.startswith("o"):
                continue
            ow = read_oword(text, self._params) if text[1:2] else None
            if ow is None or ow.label != label:
                continue
            if ow.keyword in keywords:
                if stop_before:
                    src.seek(start, lineno - 1)
                return ow
        self._where.line = start_line
        raise self._where.error(f"o{label}: no matching o{label} {' or '.join(keywords)} found")

    def _call(self, ow: OWord, src: LineSource, line_start: int) -> bool:
        label = ow.label
        return_to = (src.offset, src.lineno)
        args: list[float] = []
        pos = ow.args_pos
        text = ow.text
        while pos < len(text):
            if text[pos] != "[":
                raise self._where.error(
                    f"o{label} call arguments must be bracketed expressions like [1.5]"
                )
            value, pos = read_value(text, pos, self._params)
            args.append(value)
        if len(args) > 30:
            raise self._where.error(
                f"o{label} call has {len(args)} arguments; at most 30 are allowed"
            )
        if self._params.call_depth >= MAX_CALL_DEPTH:
            raise self._where.error(f"o{label} call nested deeper than {MAX_CALL_DEPTH} levels")
        target = self._subs.get(label)
        if target is None:
            target = self._find_sub(label, src)
        sub_src, offset, lineno = target
        self._frames.append(("call", label, src, return_to[0], return_to[1]))
        self._params.push_call(args)
        if sub_src is not src:
            self.sources.append(sub_src)
        sub_src.seek(offset, lineno)
        return sub_src is not src

    def _find_sub(self, label: str, src: LineSource) -> tuple[LineSource, int, int]:
        """Find a subroutine defined later in the file or in a file named after it."""
        here = (src.offset, src.lineno)
        line = self._where.line
        try:
            self._skip_to(src, label, ("sub",))
            found = (src, src.offset, src.lineno)
            self._subs[label] = found
            src.seek(*here)
            self._where.line = line
            return found
        except NCError:
            src.seek(*here)
            self._where.line = line
        if label.startswith("<"):
            name = label[1:-1]
            folder = Path(self._where.file).parent
            for candidate in (folder / f"{name}.ngc", folder / f"{name.upper()}.ngc"):
                if candidate.is_file():
                    sub_src = LineSource.from_path(candidate, src.max_bytes, src.budget)
                    for _lineno, _start, raw in sub_src:
                        text = "".join(strip_comments(raw).split()).lower()
                        if text.startswith(f"o{label}sub"):
                            found = (sub_src, sub_src.offset, sub_src.lineno)
                            self._subs[label] = found
                            return found
                    sub_src.close()
        raise self._where.error(f"o{label} call: no subroutine o{label} is defined")

    def _return(self, ow: OWord, src: LineSource, line_start: int) -> bool:
        while self._frames and self._frames[-1][0] != "call":
            self._frames.pop()
        if not self._frames:
            if ow.keyword == "endsub":
                raise self._where.error(f"o{ow.label} endsub without a matching o{ow.label} sub")
            raise self._where.error(f"o{ow.label} return outside a subroutine")
        if ow.args_pos < len(ow.text):
            self._params["_value"] = self._argument(ow)
        _, _, ret_src, offset, lineno = self._frames.pop()
        self._params.pop_call()
        ret_src.seek(offset, lineno)
        if ret_src is not src:
            self.sources.pop()
            return True
        return False
