"""Runs of plain straight moves, read in bulk: many consecutive ``G0``/``G1`` lines at once.

CAM output is mostly long runs of lines such as ``G1 X12.5 Y-3.25``. The interpreter hands
the bytes that follow such a line to :func:`straight_run`, which takes the longest run of
complete lines of only an optional N word, an optional G0/G1, X, Y, Z and F words (at least
one of X, Y, Z), in that order (the lines the interpreter's per-line fast path takes, see
``_XYZ_LINE`` in :mod:`cnctwin.nc.interpreter`), and computes the machine positions and feeds
of the whole run with numpy. :func:`cnctwin.nc.summary.summarize` sums a run without making
a segment per line; :meth:`StraightRun.segments` gives the segments the line-by-line path
gives. Every number is computed with the same floating-point operations in the same order as
on the line-by-line path, so the results are equal to the bit (``tests/nc/test_runs.py``).

A run ends before the first line that is not such a line, that the line-by-line path would
refuse or treat otherwise (a number too long, F <= 0 or beyond its bound, a feed move
without a feed rate, a position beyond :data:`~cnctwin.nc.limits.MAX_POSITION_MM`) or that
would pass the segment limit: that line goes the general way and meets its error there.
Lengths are in mm, feeds in mm/min.

numpy is imported on the first call, so reading a short program does not import it.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

from cnctwin.nc.limits import MAX_NUMBER_CHARS, MAX_POSITION_MM
from cnctwin.nc.segments import MachineState, MotionKind, Segment, Vec3

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import NDArray

__all__ = ["MIN_RUN_LINES", "StraightRun", "straight_run"]

#: Fewer lines than this are not worth a run (numpy's fixed cost per call).
MIN_RUN_LINES = 32
#: Bytes looked at first; the window grows fourfold while every line in it belongs.
_FIRST_WINDOW = 4096

# Byte classes.
_BAD, _LETTER, _NUMBER, _BLANK, _EOL = 0, 1, 2, 3, 4
_LETTERS = b"GgNnXxYyZzFf"
#: The letters of a line, in order, as the per-line fast path accepts them.
_LINE_LETTERS = re.compile(rb"(?:[nN]?[gG]?(?:[xX][yY]?[zZ]?|[yY][zZ]?|[zZ])[fF]?\n)*")
#: bytes.translate tables: keep only letters and line ends; letters to blanks.
_ALL_BYTES = bytes(range(256))
_NOT_LETTERS = bytes(b for b in _ALL_BYTES if b not in _LETTERS + b"\n")
_np: Any = None
_CLASSES: Any = None
_POW10: Any = None


def _numpy() -> Any:
    """numpy, imported on first use, and the byte class table."""
    global _np, _CLASSES, _POW10
    if _np is None:
        import numpy

        classes = numpy.full(256, _BAD, dtype=numpy.uint8)
        for b in _LETTERS:
            classes[b] = _LETTER
        for b in b"0123456789.+-":
            classes[b] = _NUMBER
        for b in b" \t\r":
            classes[b] = _BLANK
        classes[ord("\n")] = _EOL
        powers = [1.0]
        for _ in range(22):
            powers.append(powers[-1] * 10.0)  # exact up to 1e22
        _np, _CLASSES, _POW10 = numpy, classes, numpy.array(powers)
    return _np


@dataclass(frozen=True, slots=True, eq=False)
class StraightRun:
    """Consecutive straight moves (``G0``/``G1``) of consecutive lines, in one state but
    the feed.

    Attributes
    ----------
    file
        Source file name.
    first_line
        1-based line of the first move; move ``i`` is on line ``first_line + i``.
    start_mm
        Machine position (x, y, z) of the controlled point before the run, mm.
    end_mm
        (n, 3) machine positions after each move, mm.
    rapid
        (n,) True for G0 moves.
    feed_mm_min
        (n,) path feed of each move, mm/min (0 for rapids).
    programmed_feed
        (n,) the F in force at each move, program units per minute.
    state
        The modal state before the run; each move's is this one with its
        ``programmed_feed``.
    spindle_rpm
        Spindle speed during the run, rpm.
    abc_deg
        Rotary axes A, B, C during the run, degrees.
    """

    file: str
    first_line: int
    start_mm: Vec3
    end_mm: NDArray[np.float64]
    rapid: NDArray[np.bool_]
    feed_mm_min: NDArray[np.float64]
    programmed_feed: NDArray[np.float64]
    state: MachineState
    spindle_rpm: float
    abc_deg: Vec3

    def __len__(self) -> int:
        return len(self.rapid)

    @property
    def last_line(self) -> int:
        """1-based line of the last move."""
        return self.first_line + len(self.rapid) - 1

    @property
    def end_state(self) -> MachineState:
        """The modal state after the run."""
        return self._state(float(self.programmed_feed[-1]), self.state)

    def _state(self, feed: float, state: MachineState) -> MachineState:
        # As ModalState.set_feed: a new state only when the feed differs.
        return state if feed == state.programmed_feed else replace(state, programmed_feed=feed)

    def segments(self) -> Iterator[Segment]:
        """The segments of the run, equal to those the line-by-line path makes."""
        state = self.state
        start = self.start_mm
        line = self.first_line
        abc, rpm, file = self.abc_deg, self.spindle_rpm, self.file
        rapid, linear = MotionKind.RAPID, MotionKind.LINEAR
        for end, fast, feed, programmed in zip(
            map(tuple, self.end_mm.tolist()),
            self.rapid.tolist(),
            self.feed_mm_min.tolist(),
            self.programmed_feed.tolist(),
            strict=True,
        ):
            state = self._state(programmed, state)
            yield Segment(
                rapid if fast else linear,
                line,
                start,
                end,
                feed,
                rpm,
                state,
                None,
                0,
                0.0,
                abc,
                abc,
                file,
            )
            start = end
            line += 1


def _valid_prefix(data: bytes) -> int:
    """Bytes of the longest prefix of complete lines of ``data`` whose characters and word
    structure are those of a plain straight-move line (numbers not yet converted)."""
    np = _numpy()
    a = np.frombuffer(data, dtype=np.uint8)
    cls = _CLASSES[a]
    ends = np.flatnonzero(a == 10)
    if len(ends) == 0:
        return 0
    starts = np.empty_like(ends)
    starts[0] = 0
    starts[1:] = ends[:-1] + 1
    bad_at = len(a)
    # A CR only before its LF (a lone CR ends a line of its own).
    cr = np.flatnonzero(a[:-1] == 13)
    cr = cr[a[cr + 1] != 10]
    if len(cr):
        bad_at = int(cr[0])
    # Each letter is followed, after blanks, by a number; each number follows, after
    # blanks, a letter; N and G numbers follow their letter directly.
    solid = np.flatnonzero(cls != _BLANK)
    seq = cls[solid]
    after = np.empty_like(seq)
    after[:-1] = seq[1:]
    after[-1] = _EOL
    before = np.empty_like(seq)
    before[1:] = seq[:-1]
    before[0] = _EOL
    adjacent_before = np.empty(len(solid), dtype=bool)
    adjacent_before[1:] = solid[1:] - 1 == solid[:-1]
    adjacent_before[0] = False
    number = seq == _NUMBER
    starts_number = number & ~((before == _NUMBER) & adjacent_before)
    letters = seq == _LETTER
    lower = a[solid] | 0x20
    direct = (lower == ord("n")) | (lower == ord("g"))
    adjacent_after = np.empty(len(solid), dtype=bool)
    adjacent_after[:-1] = adjacent_before[1:]
    adjacent_after[-1] = False
    wrong = (
        (seq == _BAD)
        | (letters & (after != _NUMBER))
        | (starts_number & (before != _LETTER))
        | (letters & direct & ~adjacent_after)
    )
    first = np.argmax(wrong) if len(wrong) else 0
    if len(wrong) and wrong[first]:
        bad_at = min(bad_at, int(solid[first]))
    # No line longer than the per-line fast path takes (CR LF excluded).
    length = ends - starts - (a[np.maximum(ends - 1, 0)] == 13)
    too_long = np.flatnonzero(length > MAX_NUMBER_CHARS)
    if len(too_long):
        bad_at = min(bad_at, int(starts[too_long[0]]))
    # Lines: those before the one holding the first wrong byte, in the right word order.
    lines = int(np.searchsorted(ends, bad_at))
    if lines == 0:
        return 0
    head = data[: int(ends[lines - 1]) + 1]
    order = head.translate(None, _NOT_LETTERS)
    matched = _LINE_LETTERS.match(order)
    good = order.count(b"\n", 0, matched.end()) if matched is not None else 0
    return int(ends[good - 1]) + 1 if good else 0


def straight_run(
    data: bytes,
    *,
    file: str,
    first_line: int,
    start_mm: Vec3,
    offsets_mm: list[float],
    factor: float,
    motion: int | None,
    state: MachineState,
    spindle_rpm: float,
    abc_deg: Vec3,
    feed_limit: float,
    max_moves: int,
) -> tuple[StraightRun | None, int, int]:
    """The run of plain straight moves at the start of ``data``.

    Parameters
    ----------
    data
        Bytes of the program from the start of a line (complete lines only are used).
    file, first_line
        Source name and the 1-based line ``data`` starts.
    start_mm
        Machine position before the run, mm.
    offsets_mm
        Total offset (x, y, z, ...) added to absolute program positions, mm.
    factor
        mm per program unit.
    motion
        The modal motion code (0 for G0, 10 for G1) before the run.
    state
        The modal state before the run: absolute distances, feed per minute, no cutter
        compensation, rotation, diameter mode or constant surface speed (the caller checks).
    spindle_rpm, abc_deg
        Spindle speed (rpm) and rotary axes (degrees) during the run.
    feed_limit
        Largest F word accepted, program units per minute.
    max_moves
        Most moves the run may hold (the segments left before the segment limit).

    Returns
    -------
    run, lines, bytes
        The run (``None`` when fewer than :data:`MIN_RUN_LINES` lines qualify) and the
        lines and bytes it takes; ``lines`` also counts, when there is no run, the lines
        looked at that would not have made one.
    """
    np = _numpy()
    window = _FIRST_WINDOW
    while True:
        part = data[:window]
        cut = part.rfind(b"\n") + 1
        size = _valid_prefix(part[:cut])
        if size < cut or window >= len(data):
            break
        window *= 4
    head = data[:size]
    n = head.count(b"\n")
    if n < MIN_RUN_LINES:
        return None, max(n, 1), 0
    values, which, line_of, plain, limit = _numbers(np, head, n)
    # N and G numbers: digits only; G0 or G1.
    for letter in b"ng":
        at = np.flatnonzero(which == letter)
        if len(at) == 0:
            continue
        fits = plain[at]
        if letter == ord("g"):
            fits &= (values[at] == 0.0) | (values[at] == 1.0)
        if not fits.all():
            limit = min(limit, int(line_of[at[np.argmin(fits)]]))
    # Motion codes, carried forward from the modal one.
    index = np.arange(1, n + 1)
    g = which == ord("g")
    codes = np.empty(n + 1)
    codes[0] = -1.0 if motion not in (0, 10) else motion
    g_lines = line_of[g]
    codes[g_lines + 1] = values[g] * 10.0
    codes = _carry(np, codes, g_lines, index)
    if codes[0] < 0:  # no motion mode before the first G word: the general way
        limit = 0
    # Feeds: F > 0 and within its bound; a feed move needs a feed rate.
    f = which == ord("f")
    f_lines = line_of[f]
    feeds_given = values[f]
    wrong_feed = f_lines[(feeds_given <= 0.0) | (feeds_given > feed_limit)]
    if len(wrong_feed):
        limit = min(limit, int(wrong_feed[0]))
    programmed = np.empty(n + 1)
    programmed[0] = state.programmed_feed
    programmed[f_lines + 1] = feeds_given
    programmed = _carry(np, programmed, f_lines, index)
    unfed = np.flatnonzero((codes == 10.0) & ~(programmed > 0.0))
    if len(unfed):
        limit = min(limit, int(unfed[0]))
    # Positions: program value * factor + offset, absent axes where they were.
    ends = np.empty((n, 3))
    for axis, letter in enumerate(b"xyz"):
        mask = which == letter
        lines = line_of[mask]
        column = np.empty(n + 1)
        column[0] = start_mm[axis]
        column[lines + 1] = values[mask] * factor + offsets_mm[axis]
        ends[:, axis] = _carry(np, column, lines, index)
    outside = np.flatnonzero(~(np.abs(ends) <= MAX_POSITION_MM).all(axis=1))
    if len(outside):
        limit = min(limit, int(outside[0]))
    limit = min(limit, max_moves)
    if limit < MIN_RUN_LINES:
        return None, max(limit, 1), 0
    rapid = codes[:limit] == 0.0
    programmed = programmed[:limit]
    run = StraightRun(
        file=file,
        first_line=first_line,
        start_mm=start_mm,
        end_mm=ends[:limit],
        rapid=rapid,
        feed_mm_min=np.where(rapid, 0.0, programmed * factor),
        programmed_feed=programmed,
        state=state,
        spindle_rpm=spindle_rpm,
        abc_deg=abc_deg,
    )
    taken = int(np.flatnonzero(np.frombuffer(head, dtype=np.uint8) == 10)[limit - 1]) + 1
    return run, limit, taken


def _numbers(np: Any, head: bytes, n: int) -> tuple[Any, Any, Any, Any, int]:
    """The numbers of the ``n`` lines ``head`` (checked by :func:`_valid_prefix`), in order:
    their values, letters (lower case), 0-based lines, whether each is digits only, and the
    first line holding a number this parser does not take (``n`` if none).

    A number of at most 15 digits (an integer m below 2**53) with k <= 15 digits after its
    point is m / 10**k: both exact doubles, so the one rounded division gives the double
    nearest the decimal value, which is what ``float()`` gives (Clinger's fast path). Longer
    numbers, two points or a sign not in front end the run (the general way reads them).
    """
    a = np.frombuffer(head, dtype=np.uint8)
    cls = _CLASSES[a]
    number = cls == _NUMBER
    previous = np.empty_like(number)
    previous[0] = False
    previous[1:] = number[:-1]
    following = np.empty_like(number)
    following[-1] = False
    following[:-1] = number[1:]
    firsts = np.flatnonzero(number & ~previous)
    lasts = np.flatnonzero(number & ~following)
    count = len(firsts)
    inside = np.flatnonzero(number)
    token = np.cumsum(number & ~previous)[inside] - 1
    c = a[inside]
    digit = (c >= 48) & (c <= 57)
    dot = c == 46
    sign = ~digit & ~dot
    digits = np.bincount(token[digit], minlength=count)
    dots = np.bincount(token[dot], minlength=count)
    signs = np.bincount(token[sign], minlength=count)
    lead = a[firsts]
    negative = lead == 45
    signed = negative | (lead == 43)
    dot_at = np.full(count, -1, dtype=np.intp)
    dot_at[token[dot]] = inside[dot]
    has_dot = dots > 0
    fraction = np.where(has_dot, lasts - dot_at, 0)
    good = (digits >= 1) & (digits <= 15) & (dots <= 1) & (signs == signed)
    # Each digit's place: digits after it in its number.
    where = inside[digit]
    owner = token[digit]
    place = lasts[owner] - where - (has_dot[owner] & (dot_at[owner] > where))
    np.minimum(place, 22, out=place)
    mantissa = np.bincount(owner, weights=(c[digit] - 48) * _POW10[place], minlength=count)
    values = mantissa / _POW10[np.minimum(fraction, 22)]
    np.negative(values, out=values, where=negative)
    line_ends = np.flatnonzero(a == 10)
    line_of = np.searchsorted(line_ends, firsts)
    letters = np.flatnonzero(cls == _LETTER)
    which = a[letters] | 0x20
    wrong = np.flatnonzero(~good)
    limit = int(line_of[wrong[0]]) if len(wrong) else n
    return values, which, line_of, good & ~signed & ~has_dot, limit


def _carry(np: Any, column: Any, given: Any, index: Any) -> Any:
    """``column[1:]`` with each row not in ``given`` (0-based rows) holding the last given
    value before it (``column[0]`` if none)."""
    source = np.zeros(len(index), dtype=np.intp)
    source[given] = index[given]
    np.maximum.accumulate(source, out=source)
    return column[source]
