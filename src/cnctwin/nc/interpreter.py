"""RS274/ISO 6983 interpreter: NC program text to motion segments in machine coordinates.

The interpreter follows the RS274NGC language as LinuxCNC implements it (modal groups,
order of execution within a block, parameters, expressions, O-word subroutines and
control flow) and accepts the Fanuc/Haas, grbl and Sinumerik basics that real CAM posts
emit. Everything it does not implement is rejected with an :class:`~cnctwin.errors.NCError`
that names the construct and the line. The list is in ``docs/nc.md``.

Segments are produced lazily: a program of any length is interpreted in constant memory.

This module reads lines and dispatches them: plain G0/G1 and G2/G3 lines take raw-line fast
paths that skip the lexer; other lines are lexed (of an O-word statement without comments,
only the statement is read) and handed to the O-word control
(:mod:`cnctwin.nc.owords`) or the block executor (:mod:`cnctwin.nc.executor`), which acts
through the modal state (:mod:`~cnctwin.nc.modal`), offsets (:mod:`~cnctwin.nc.offsets`),
tool state (:mod:`~cnctwin.nc.tool_state`), drilling cycles
(:mod:`~cnctwin.nc.canned_cycles`) and motion (:mod:`~cnctwin.nc.motion`). Reading in bulk
(:meth:`Interpreter.run_file_bulk`), long runs of such plain lines are taken as one piece by
:mod:`cnctwin.nc.runs`.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path
from typing import Final

from cnctwin.errors import NCError
from cnctwin.nc.cursor import ProgramCursor
from cnctwin.nc.executor import BlockExecutor
from cnctwin.nc.expressions import Parameters
from cnctwin.nc.lexer import lex_block, read_oword, squeeze
from cnctwin.nc.limits import MAX_NUMBER_CHARS, WORD_LIMITS
from cnctwin.nc.owords import OWordControl
from cnctwin.nc.runs import MoveRun, move_run
from cnctwin.nc.segments import Plane, Segment
from cnctwin.nc.setup import NCSetup
from cnctwin.nc.source import LineSource, RepeatBudget

__all__ = ["Interpreter", "interpret_file", "interpret_text"]

_NUM: Final = r"\s*([-+]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+))\s*"
#: A raw line of only an optional N word, an optional G0/G1 (G00, G01, ...), X, Y, Z and
#: F words in that order; group 1 is the G-code's digit.
_XYZ_LINE: Final = re.compile(
    rf"\s*(?:[nN][0-9]+\s*)?(?:[gG]0*([01])(?![0-9.])\s*)?"
    rf"(?:[xX]{_NUM})?(?:[yY]{_NUM})?(?:[zZ]{_NUM})?(?:[fF]{_NUM})?"
)
#: A raw line of only an optional N word, an optional G2/G3 (G02, G03, ...) and X, Y, Z,
#: I, J, K words in that order; group 1 is the G-code's digit.
_ARC_LINE: Final = re.compile(
    rf"\s*(?:[nN][0-9]+\s*)?(?:[gG]0*([23])(?![0-9.])\s*)?"
    rf"(?:[xX]{_NUM})?(?:[yY]{_NUM})?(?:[zZ]{_NUM})?"
    rf"(?:[iI]{_NUM})?(?:[jJ]{_NUM})?(?:[kK]{_NUM})?"
)
_ARC_LETTERS: Final = "xyzijk"
#: The bound of a length word (X Y Z I J K), program units.
_LENGTH_WORD_LIMIT: Final = WORD_LIMITS["x"][0]
#: The bound of an F word, program units per minute.
_FEED_WORD_LIMIT: Final = WORD_LIMITS["f"][0]
#: What :meth:`Interpreter._block` asks of the line loop: go on, or read the new source.
_NEXT, _SWITCH = 0, 1
#: The first letters of a line that may be an O-word statement read in :meth:`Interpreter._block`.
_O_LETTERS: Final = ("o", "O")
#: Lines without a look for a run of moves after a look that found none, at most.
_MAX_BACKOFF: Final = 4096


class Interpreter:
    """Interpret NC programs into :class:`~cnctwin.nc.segments.Segment` objects.

    Parameters
    ----------
    setup
        Tool table, lathe flag, initial work offsets, reference points (mm).

    Attributes
    ----------
    lines_read
        Lines read so far (every line, including those skipped by control flow).
    warnings
        ``"FILE:LINE: message"`` for everything accepted but worth a look.
    messages
        Texts of ``(MSG, ...)`` comments, in order.
    tools_used
        Tool numbers loaded by the program, in order of first use.
    params
        The program's parameters.

    Examples
    --------
    >>> from cnctwin.nc.interpreter import interpret_text
    >>> [s.end_mm for s in interpret_text("G21 G90\\nG0 X10 Y5\\nG1 Z-1 F100\\nM2")]
    [(10.0, 5.0, 0.0), (10.0, 5.0, -1.0)]
    """

    def __init__(self, setup: NCSetup | None = None) -> None:
        self.setup = setup if setup is not None else NCSetup()
        self.lines_read = 0
        self.params = Parameters()
        self._cursor = ProgramCursor()
        self._executor = BlockExecutor(self.setup, self._cursor, self.params)
        self._owords = OWordControl(self.params, self._cursor)
        self.warnings = self._cursor.warnings
        self.messages = self._executor.messages
        self.tools_used = self._executor.tools.used
        self._started = False
        self._budget = RepeatBudget(self.setup.max_repeated_lines)
        self._segments_left = self.setup.max_segments
        # Runs (bulk reading only): not looked for before line _next_look of a source.
        self._next_look = 0
        self._backoff = 0

    @property
    def units(self) -> str | None:
        """Units the program first selected, ``"mm"`` or ``"inch"``; ``None`` if it never
        selects any (then it runs in mm)."""
        return self._executor.modal.units

    # ------------------------------------------------------------------ entry points
    def run_file(self, path: str | Path) -> Iterator[Segment]:
        """Interpret a program file lazily.

        Parameters
        ----------
        path
            NC program file (``.ngc``, ``.nc``, ``.tap``, ``.gcode``, ``.mpf``, ...).

        Yields
        ------
        Segment
            Motion segments in program order.

        Raises
        ------
        NCError
            ``"FILE:LINE: message"`` for anything the interpreter cannot honour.
        OSError
            If the file cannot be opened.
        """
        setup = self.setup
        source = LineSource.from_path(path, setup.max_program_bytes, self._budget)
        return self._run(source)  # type: ignore[return-value]

    def run_text(self, text: str, name: str = "<string>") -> Iterator[Segment]:
        """Interpret program text held in memory; see :meth:`run_file`."""
        return self._run(LineSource.from_text(text, name, self._budget))  # type: ignore[return-value]

    def run_file_bulk(self, path: str | Path) -> Iterator[Segment | MoveRun]:
        """As :meth:`run_file`, but long runs of plain ``G0``/``G1`` and ``G2``/``G3`` lines
        come as one :class:`~cnctwin.nc.runs.MoveRun` each, for consumers that take runs such as
        :func:`~cnctwin.nc.summary.summarize`; their segments equal those of
        :meth:`run_file`."""
        setup = self.setup
        source = LineSource.from_path(path, setup.max_program_bytes, self._budget)
        return self._run(source, bulk=True)

    def run_text_bulk(self, text: str, name: str = "<string>") -> Iterator[Segment | MoveRun]:
        """As :meth:`run_text`, with runs; see :meth:`run_file_bulk`."""
        return self._run(LineSource.from_text(text, name, self._budget), bulk=True)

    # ------------------------------------------------------------------ main loop
    def _run(self, source: LineSource, bulk: bool = False) -> Iterator[Segment | MoveRun]:
        """Read the program and the subroutine files it calls, yielding segments (and, if
        ``bulk``, runs of moves).

        One loop for every line, with the raw-line fast paths inline: this is the hot path.
        """
        cursor = self._cursor
        executor = self._executor
        modal = executor.modal
        motion = executor.motion
        move = motion.xyz_move
        out = motion.out
        sources = self._owords.sources
        sources.append(source)
        try:
            while sources and not executor.ended:
                src = sources[-1]
                cursor.file = src.name
                finished = True
                main = len(sources) == 1 and src is source
                for lineno, start, raw in src:
                    cursor.line = lineno
                    if main and lineno > self.lines_read:
                        self.lines_read = lineno
                    # "[", "#" and "o" never occur in a line a fast path takes: a line of
                    # expressions or an O-word goes straight to the lexer.
                    if (
                        motion.comp is None
                        and "[" not in raw
                        and "#" not in raw
                        and "o" not in raw
                        and "O" not in raw
                    ):
                        plain = _XYZ_LINE.fullmatch(raw) if len(raw) <= MAX_NUMBER_CHARS else None
                        if plain is not None:
                            # Fastest path: a line of only (N) (G0/G1) X Y Z (F) words, in
                            # that order.
                            g, gx, gy, gz, gf = plain.groups()
                            code = modal.motion if g is None else 10 if g == "1" else 0
                            moves = not (gx is None and gy is None and gz is None)
                            if g is None and gf is None and not moves and (code == 10 or code == 0):
                                continue
                            feed = 0.0 if gf is None else float(gf)
                            if moves and (code == 10 or code == 0) and feed <= _FEED_WORD_LIMIT:
                                modal.motion = code
                                self._started = True
                                try:
                                    if gf is not None:
                                        modal.set_feed(feed)
                                    move(
                                        code,
                                        None if gx is None else float(gx),
                                        None if gy is None else float(gy),
                                        None if gz is None else float(gz),
                                        gf is not None,
                                    )
                                except NCError as err:
                                    if g is None and gf is None:
                                        raise cursor.locate(err) from None
                                    # A G or F line is read again below: its words' own
                                    # checks come first there, as for any block.
                                else:
                                    self._segments_left -= 1
                                    if self._segments_left < 0:
                                        raise self._too_many_segments()
                                    yield out.pop()
                                    if bulk and lineno >= self._next_look:
                                        run = self._run_after(src, main)
                                        if run is not None:
                                            yield run
                                    continue
                        else:
                            arc = _arc_words(raw, modal.motion)
                            if arc is not None:
                                # Fast path: a line of only (N) (G2/G3) X Y Z I J K words.
                                self._started = True
                                code, words = arc
                                modal.motion = code
                                try:
                                    modal.require_feed("f" in words)
                                    motion.arc(code == 30, words)
                                except NCError as err:
                                    raise cursor.locate(err) from None
                                self._segments_left -= 1
                                if self._segments_left < 0:
                                    raise self._too_many_segments()
                                yield out.pop()
                                if bulk and lineno >= self._next_look:
                                    run = self._run_after(src, main)
                                    if run is not None:
                                        yield run
                                continue
                    if self._block(raw, src, start) == _SWITCH:
                        finished = False
                        break
                    if out:
                        self._segments_left -= len(out)
                        if self._segments_left < 0:
                            raise self._too_many_segments()
                        if len(out) == 1:
                            yield out.pop()
                        else:
                            yield from out
                            out.clear()
                    if executor.ended:
                        break
                if finished and sources and sources[-1] is src:
                    if len(sources) > 1:
                        raise cursor.error(
                            "end of subroutine file reached without 'endsub' or 'return'"
                        )
                    sources.pop()
            yield from self._end()
        finally:
            for src in sources:
                src.close()
            source.close()

    def _run_after(self, src: LineSource, main: bool) -> MoveRun | None:
        """The run of plain straight moves and arcs that follows in ``src``, taken: the
        source, the position, the modes and the cursor move past it. ``None`` if there is
        none (or the modes do not allow one); then none is looked for again for a while,
        longer after each look that finds none."""
        motion = self._executor.motion
        modal = self._executor.modal
        state = modal.state
        run: MoveRun | None
        data = src.ahead()
        if not data or not motion.plain_absolute:
            run, lines = None, 1
        else:
            run, lines, size = move_run(
                data,
                file=src.name,
                first_line=src.lineno + 1,
                start_mm=(motion.pos[0], motion.pos[1], motion.pos[2]),
                offsets_mm=self._executor.offsets.total,
                factor=modal.factor,
                motion=modal.motion,
                state=state,
                arcs=state.plane == Plane.XY and not modal.arc_absolute,
                spindle_rpm=state.programmed_speed if state.spindle_direction else 0.0,
                abc_deg=motion.abc,
                feed_limit=_FEED_WORD_LIMIT,
                length_limit=_LENGTH_WORD_LIMIT,
                max_moves=self._segments_left,
            )
        if run is None:
            self._backoff = min(2 * self._backoff + 1, _MAX_BACKOFF)
            self._next_look = src.lineno + lines + self._backoff
            return None
        self._backoff = 0
        src.skip(size, lines)
        self._segments_left -= lines
        motion.pos = run.end_mm[-1].tolist()
        modal.motion = int(run.motion[-1])
        modal.state = run.end_state
        self._cursor.line = src.lineno
        if main:
            self.lines_read = src.lineno
        return run

    def _block(self, raw: str, src: LineSource, start: int) -> int:
        """Lex and execute a line that no fast path took (``start``: its byte offset).
        Returns :data:`_SWITCH` when an O-word call or return changed the source."""
        executor = self._executor
        try:
            if "#5" in raw or "#<_" in raw:
                # Only lines that mention them refresh the system parameters (it costs a
                # few microseconds).
                executor.sync_parameters()
            if raw[:1] in _O_LETTERS and "(" not in raw and ";" not in raw:
                # An O-word statement without comments: read without a block.
                statement = read_oword(squeeze(raw), self.params)
                if statement is not None:
                    self._started = True
                    return _SWITCH if self._owords.execute(statement, src, start) else _NEXT
            block = lex_block(raw, self.params)
            if block is None:
                if self._started and raw.strip() == "%":
                    # The closing tape mark ends the program.
                    executor.ended = True
                return _NEXT
            self._started = True
            if block.oword is not None:
                return _SWITCH if self._owords.execute(block.oword, src, start) else _NEXT
            executor.execute(block)
        except NCError as err:
            raise self._cursor.locate(err) from None
        return _NEXT

    def _end(self) -> Iterator[Segment]:
        """The end of the program: warnings, and the moves cutter compensation held back."""
        cursor = self._cursor
        if not self._started:
            cursor.warn("the program is empty: no block to run")
        elif not self._executor.ended:
            cursor.warn(
                "the program ends without M2, M30 or a closing '%' "
                "(LinuxCNC stops with an error there)"
            )
        motion = self._executor.motion
        motion.finish_comp()
        out = motion.out
        if out:
            self._segments_left -= len(out)
            if self._segments_left < 0:
                raise self._too_many_segments()
            yield from out
            out.clear()

    def _too_many_segments(self) -> NCError:
        limit = self.setup.max_segments
        return self._cursor.error(
            f"the program produces more than {limit} motion segments: stopped as runaway "
            "work (raise the limit with --max-segments or NCSetup.max_segments for a "
            "program meant to be this long)"
        )


def _arc_words(raw: str, motion: int | None) -> tuple[int, dict[str, float]] | None:
    """``(motion code, words)`` of a raw line that is a plain arc block (see
    :data:`_ARC_LINE`) under the modal ``motion``; ``None`` for any other line, and for
    one whose words need the lexer's checks (a number too long or out of range)."""
    found = _ARC_LINE.fullmatch(raw)
    if found is None:
        return None
    digit = found.group(1)
    code = motion if digit is None else 20 if digit == "2" else 30
    if code != 20 and code != 30:
        return None
    words: dict[str, float] = {}
    for letter, text in zip(_ARC_LETTERS, found.groups()[1:], strict=True):
        if text is not None:
            if len(text) > MAX_NUMBER_CHARS:
                return None
            value = float(text)
            if not -_LENGTH_WORD_LIMIT <= value <= _LENGTH_WORD_LIMIT:
                return None
            words[letter] = value
    return (code, words) if words else None


def interpret_file(path: str | Path, setup: NCSetup | None = None) -> Iterator[Segment]:
    """Interpret an NC file lazily; see :class:`Interpreter`."""
    return Interpreter(setup).run_file(path)


def interpret_text(
    text: str, setup: NCSetup | None = None, name: str = "<string>"
) -> Iterator[Segment]:
    """Interpret NC program text lazily; see :class:`Interpreter`."""
    return Interpreter(setup).run_text(text, name)
