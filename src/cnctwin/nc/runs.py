"""Runs of plain moves read in bulk: many consecutive ``G0``/``G1`` and ``G2``/``G3`` lines
at once.

CAM output is mostly long runs of lines such as ``G1 X12.5 Y-3.25``, often with arcs such as
``G3 X4 Y2 I1 J0`` between them. The interpreter hands the bytes that follow such a line to
:func:`move_run`, which takes the longest run of complete lines of only an optional N word,
an optional G0/G1, X, Y, Z and F words (at least one of X, Y, Z), in that order, or of an
optional N word, an optional G2/G3, X, Y, Z, I, J words (I or J at least; XY plane), in any
mix: lines the interpreter's per-line fast paths take (``_XYZ_LINE`` and ``_ARC_LINE`` in
:mod:`cnctwin.nc.interpreter`). It checks them with numpy over the bytes, reads their
numbers with numpy to the values ``float()`` gives (:func:`_numbers`) and computes the machine
positions, feeds and arc centres of the whole run. :func:`cnctwin.nc.summary.summarize`
sums a run without making a segment per line; ``segments()`` gives the segments the
line-by-line path gives. Every number is that of the line-by-line path (Motion.xyz_move,
Motion.arc, ``arc_sweep_rad``) to the bit: the same floating-point operations in the same
order, or, for the words' values, ``math.hypot`` and ``math.atan2``, operations that give
the same bits (:func:`_numbers`, :func:`xy_hypot`, :func:`xy_atan2`);
``tests/nc/test_bulk_runs.py`` compares both ways.

A run ends before the first line that is not such a line, that the line-by-line path would
refuse or treat otherwise (a line over :data:`~cnctwin.nc.limits.MAX_NUMBER_CHARS`
characters, F <= 0 or beyond its bound, a feed move without a feed rate, a position beyond
:data:`~cnctwin.nc.limits.MAX_POSITION_MM`, an arc whose end radius LinuxCNC refuses) or that
would pass the segment limit: that line goes the general way and meets its error there.
Lengths are in mm, feeds in mm/min, angles in rad.

numpy is imported only when a run may follow (32 lines of the right characters, each with a
letter such a line needs: X, Y, Z, I or J), so reading a short program does not import it.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from cnctwin.nc.arcs import (
    ARC_END_TOLERANCE_INCH,
    ARC_END_TOLERANCE_MM,
    ARC_RADIUS_LIMIT_FACTOR,
    ARC_RADIUS_TOLERANCE_REL,
    MM_PER_INCH,
)
from cnctwin.nc.limits import MAX_NUMBER_CHARS, MAX_POSITION_MM
from cnctwin.nc.segments import MachineState, MotionKind, Segment, Vec3

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import NDArray

__all__ = [
    "MIN_RUN_LINES",
    "MoveRun",
    "arc_sweeps",
    "map_floats",
    "move_run",
    "rows",
    "xy_atan2",
    "xy_hypot",
]

#: Fewer lines than this are not worth a run (numpy's fixed cost per call).
MIN_RUN_LINES = 32
#: Bytes looked at first; the window grows fourfold while every line in it belongs.
_FIRST_WINDOW = 4096

# Byte classes: N and G (their number follows directly), other letters, number characters,
# blanks, CR, LF.
_BAD, _LETTER_NG, _LETTER, _NUMBER, _BLANK, _CR, _EOL = range(7)
_ALL_BYTES = bytes(range(256))
_TWO_PI = 2.0 * math.pi
#: Most digits of a G word a run takes (zeros in front of its number included).
_G_DIGITS = 8
#: Most digits of a number read by :func:`_numbers` as an integer over a power of ten:
#: below 2**53 and 10**22, so both are exact doubles and their quotient, rounded once, is
#: the correctly rounded value of the text, as ``float()`` gives it (Clinger 1990).
_EXACT_DIGITS = 15
_np: Any = None
_WRONG_PAIRS: Any = None
_NUMBER_BYTES: Any = None
_POWERS_OF_TEN: Any = None


class _Grammar:
    """The lines of one kind of run: their letters, word order and G words."""

    def __init__(
        self, letters: bytes, order: bytes, g_numbers: tuple[int, ...], needed: bytes
    ) -> None:
        self.letters = letters + letters.lower()
        #: Finds one of the letters every such line has.
        self.needed = re.compile(b"[" + needed + needed.lower() + b"]")
        #: The letters of a line, in order, as the per-line fast path accepts them.
        self.order = re.compile(order)
        #: bytes.translate table: keep only letters and line ends.
        self.not_letters = bytes(b for b in _ALL_BYTES if b not in self.letters + b"\n")
        #: Every byte such a line may hold, but its LF.
        self.alphabet = self.letters + b"0123456789.+- \t\r"
        #: The numbers of the G words taken (digits only, at most :data:`_G_DIGITS`).
        self.g_numbers = g_numbers
        self.classes: Any = None

    def byte_classes(self, np: Any) -> Any:
        """The class of each byte value (numpy array)."""
        if self.classes is None:
            classes = np.full(256, _BAD, dtype=np.uint8)
            for b in self.letters:
                classes[b] = _LETTER_NG if b in b"GgNn" else _LETTER
            for b in b"0123456789.+-":
                classes[b] = _NUMBER
            for b in b" \t":
                classes[b] = _BLANK
            classes[ord("\r")] = _CR
            classes[ord("\n")] = _EOL
            self.classes = classes
        return self.classes


#: Straight moves, (N) (G0/G1) X Y Z (F) with one of X Y Z at least, and arcs in the XY
#: plane, (N) (G2/G3) X Y Z I J with one of I J at least.
_MOVES = _Grammar(
    b"GNXYZFIJ",
    # (Written so that the regular expression need not backtrack: X Y Z words, then F or
    # I J words or neither; or I J words alone.)
    rb"[nN]?[gG]?(?:(?:[xX][yY]?[zZ]?|[yY][zZ]?|[zZ])(?:[iI][jJ]?|[jJ]|[fF])?|[iI][jJ]?|[jJ])",
    (0, 1, 2, 3),
    b"XYZIJ",
)


def _wrong_pair(before: int, after: int, apart: bool) -> bool:
    """Whether non-blank bytes of classes ``before`` then ``after`` (``apart``: blanks
    between them) cannot follow each other in a plain straight-move line."""
    if _BAD in (before, after):
        return True
    if before in (_LETTER_NG, _LETTER):
        return after != _NUMBER or (before == _LETTER_NG and apart)
    if before == _NUMBER:
        return after == _NUMBER and apart  # "X1 5"
    if before == _CR:
        return after != _EOL or apart
    return after == _NUMBER  # a number at the start of a line


def _numpy() -> Any:
    """numpy, imported on first use."""
    global _np, _WRONG_PAIRS, _NUMBER_BYTES, _POWERS_OF_TEN
    if _np is None:
        import numpy

        _NUMBER_BYTES = numpy.zeros(256, dtype=bool)
        _NUMBER_BYTES[list(b"0123456789.+-")] = True
        _POWERS_OF_TEN = 10.0 ** numpy.arange(_EXACT_DIGITS + 1)
        _WRONG_PAIRS = numpy.array(
            [_wrong_pair(k // 14, k // 2 % 7, bool(k % 2)) for k in range(98)], dtype=bool
        )
        _np = numpy
    return _np


@dataclass(frozen=True, slots=True, eq=False)
class MoveRun:
    """Consecutive plain moves of consecutive lines: straight moves (``G0``/``G1``) and arcs
    (``G2``/``G3`` with I, J centres, XY plane) in any order, in one state but the feed.

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
    motion
        (n,) motion code of each move (G-code key: 0, 10, 20 or 30 for G0 to G3).
    center_mm
        (n, 3) arc centres, mm (a centre's Z is its arc's start Z); a straight move's row
        is its start point and is not used.
    radius_mm
        (n,) arc radii at the start point, mm (``math.hypot`` of the start's XY offset from
        the centre); a straight move's is 0 and is not used.
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
    motion: NDArray[np.int64]
    center_mm: NDArray[np.float64]
    radius_mm: NDArray[np.float64]
    feed_mm_min: NDArray[np.float64]
    programmed_feed: NDArray[np.float64]
    state: MachineState
    spindle_rpm: float
    abc_deg: Vec3

    def __len__(self) -> int:
        return len(self.end_mm)

    @property
    def last_line(self) -> int:
        """1-based line of the last move."""
        return self.first_line + len(self.end_mm) - 1

    @property
    def end_state(self) -> MachineState:
        """The modal state after the run."""
        return self._state(float(self.programmed_feed[-1]), self.state)

    def _state(self, feed: float, state: MachineState) -> MachineState:
        # As ModalState.set_feed: a new state only when the feed differs.
        return state if feed == state.programmed_feed else state.with_feed(feed)

    def segments(self) -> Iterator[Segment]:
        """The segments of the run, equal to those the line-by-line path makes."""
        state = self.state
        start = self.start_mm
        line = self.first_line
        abc, rpm, file = self.abc_deg, self.spindle_rpm, self.file
        kinds = {0: MotionKind.RAPID, 10: MotionKind.LINEAR, 20: MotionKind.ARC, 30: MotionKind.ARC}
        for end, center, code, feed, programmed in zip(
            map(tuple, self.end_mm.tolist()),
            map(tuple, self.center_mm.tolist()),
            self.motion.tolist(),
            self.feed_mm_min.tolist(),
            self.programmed_feed.tolist(),
            strict=True,
        ):
            state = self._state(programmed, state)
            yield Segment(
                kinds[code],
                line,
                start,
                end,
                feed,
                rpm,
                state,
                center if code >= 20 else None,
                (1 if code == 30 else -1) if code >= 20 else 0,
                0.0,
                abc,
                abc,
                file,
            )
            start = end
            line += 1


def arc_sweeps(
    start: Any, end: Any, center: Any, turns: Any, radius: Any = None
) -> tuple[Any, Any, Any]:
    """:func:`~cnctwin.nc.segments.arc_sweep_rad` of many XY-plane arcs of one turn at
    most (``turns`` +-1): (n, 3) start, end and centre points (mm, numpy) to radius (mm),
    start angle and sweep (rad), each (n,), with the same numbers as the one-arc function
    (``math.atan2`` through :func:`xy_atan2`, ``math.hypot`` through :func:`xy_hypot`,
    Python's ``%``). ``radius`` (mm, (n,)), if given, is the ``math.hypot`` of the start's
    offset from the centre, already computed.

    numpy's ``mod`` is Python's float ``%`` (``fmod``, then the divisor added when the signs
    differ), bit for bit."""
    np = _numpy()
    u0 = start[:, 0] - center[:, 0]
    v0 = start[:, 1] - center[:, 1]
    a0 = xy_atan2(v0, u0)
    a1 = xy_atan2(end[:, 1] - center[:, 1], end[:, 0] - center[:, 0])
    if radius is None:
        radius = xy_hypot(u0, v0)
    ccw = np.mod(a1 - a0, _TWO_PI)
    cw = _TWO_PI - ccw
    ccw[(ccw <= 1e-12) | (ccw >= _TWO_PI - 1e-12)] = _TWO_PI
    cw[(cw <= 1e-12) | (cw >= _TWO_PI - 1e-12)] = _TWO_PI
    sweep = np.where(turns > 0, ccw + 0.0, -(cw + 0.0))
    return radius, a0, sweep


def xy_hypot(u: Any, v: Any) -> Any:
    """``math.hypot(u[i], v[i])`` of two (n,) numpy arrays (mm), bit for bit, as a numpy
    array. Where ``u`` or ``v`` is +-0.0 it is the other's ``abs`` (``math.hypot`` of a
    number and a zero is its ``abs`` to the bit: a scaling by a power of two, an exact
    square and a correctly rounded root), with no call per item; elsewhere one
    ``math.hypot`` call per item (numpy's ``hypot`` differs from it in the last bit for
    some arguments)."""
    np = _numpy()
    out = np.abs(np.where(u == 0.0, v, u))
    general = np.flatnonzero((u != 0.0) & (v != 0.0))
    if len(general):
        general = rows(general, len(out))
        out[general] = map_floats(math.hypot, u[general].tolist(), v[general].tolist())
    return out


def xy_atan2(v: Any, u: Any) -> Any:
    """``math.atan2(v[i], u[i])`` of two (n,) numpy arrays, bit for bit, as a numpy array
    of angles (rad). With no call per item: where ``v`` is +-0.0 (and ``u`` is not NaN),
    +-0.0 when ``u``'s sign bit is clear, else +-pi, the sign ``v``'s (CPython's own branch
    of ``math.atan2``, before the C library's ``atan2``); where ``u`` is +-0.0 and ``v`` is
    not zero nor NaN, +-pi/2 (C99 F.9.1.4, exact in the C library; tests check it).
    Elsewhere one ``math.atan2`` call per item (numpy's ``arctan2`` differs from it in the
    last bit for some arguments)."""
    np = _numpy()
    out = np.copysign(np.where(np.signbit(u), math.pi, 0.0), v)
    upright = (u == 0.0) & (np.abs(v) > 0.0)
    out[upright] = np.copysign(math.pi / 2, v[upright])
    general = np.flatnonzero(~(((v == 0.0) & (u == u)) | upright))
    if len(general):
        general = rows(general, len(out))
        out[general] = map_floats(math.atan2, v[general].tolist(), u[general].tolist())
    return out


def map_floats(function: Callable[..., float], first: Sequence[Any], *rest: Iterable[Any]) -> Any:
    """``function`` applied to the items of ``first`` and ``rest`` in parallel (as
    :func:`map`, one call per item of ``first``), as a numpy array of floats."""
    return _numpy().fromiter(map(function, first, *rest), dtype=float, count=len(first))


def _valid_prefix(grammar: _Grammar, data: bytes) -> int:
    """Bytes of the longest prefix of complete lines of ``data`` whose characters and word
    structure are those of ``grammar`` (numbers not yet converted)."""
    np = _numpy()
    a = np.frombuffer(data, dtype=np.uint8)
    cls = grammar.byte_classes(np)[a]
    ends = np.flatnonzero(a == 10)
    if len(ends) == 0:
        return 0
    starts = np.empty_like(ends)
    starts[0] = 0
    starts[1:] = ends[:-1] + 1
    # Each pair of non-blank bytes in a row, with whether blanks are between them (the
    # first byte follows a virtual line end).
    solid = np.flatnonzero(cls != _BLANK)
    seq = cls[solid]
    code = np.empty(len(solid), dtype=np.uint8)
    code[0] = _EOL * 14 + seq[0] * 2 + (solid[0] != 0)
    code[1:] = seq[:-1] * 14
    code[1:] += seq[1:] * 2
    code[1:] += np.diff(solid) != 1
    wrong = _WRONG_PAIRS[code]
    first = int(np.argmax(wrong))
    bad_at = int(solid[first]) if wrong[first] else len(a)
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
    # Each line's letters; a run has few distinct ones, each checked once.
    shapes = head.translate(None, grammar.not_letters)[:-1].split(b"\n")
    wrong_shapes = {shape for shape in set(shapes) if not grammar.order.fullmatch(shape)}
    good = (
        lines
        if not wrong_shapes
        else next(i for i, shape in enumerate(shapes) if shape in wrong_shapes)
    )
    return int(ends[good - 1]) + 1 if good else 0


def move_run(
    data: bytes,
    *,
    file: str,
    first_line: int,
    start_mm: Vec3,
    offsets_mm: list[float],
    factor: float,
    motion: int | None,
    state: MachineState,
    arcs: bool,
    spindle_rpm: float,
    abc_deg: Vec3,
    feed_limit: float,
    length_limit: float,
    max_moves: int,
) -> tuple[MoveRun | None, int, int]:
    """The run of plain straight moves and arcs at the start of ``data``.

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
        The modal motion code (0, 10, 20 or 30 for G0 to G3) before the run.
    state
        The modal state before the run: absolute distances, feed per minute, no cutter
        compensation, rotation, diameter mode or constant surface speed (the caller checks).
    arcs
        Whether arcs may be in the run: XY plane, incremental arc centres (else the run
        ends before the first arc).
    spindle_rpm, abc_deg
        Spindle speed (rpm) and rotary axes (degrees) during the run.
    feed_limit
        Largest F word accepted, program units per minute.
    length_limit
        Largest word of an arc line accepted (X, Y, Z, I, J), program units.
    max_moves
        Most moves the run may hold (the segments left before the segment limit).

    Returns
    -------
    run, lines, bytes
        The run (``None`` when fewer than :data:`MIN_RUN_LINES` lines qualify) and the
        lines and bytes it takes; ``lines`` also counts, when there is no run, the lines
        looked at that would not have made one.

    Each line is a straight move if it has no I or J word, else an arc: its motion code
    (its G word's or the one carried from the line before) must be G0/G1, or G2/G3. Arc
    centres and the end-radius test are those of :meth:`~cnctwin.nc.motion.Motion.arc`.
    """
    words = _words(_MOVES, data)
    if isinstance(words, int):
        return None, words, 0
    np = _numpy()
    head, n, values, which, line_of, limit = words
    index = np.arange(1, n + 1)
    codes = _codes(np, motion, values, which, line_of, index)
    if codes[0] < 0:  # no motion mode before the first G word: the general way
        limit = 0
    on_arc = np.zeros(n, dtype=bool)
    on_arc[line_of[(which == ord("i")) | (which == ord("j"))]] = True
    wrong = np.flatnonzero((on_arc != (codes >= 20.0)) | (on_arc & (not arcs)))
    if len(wrong):
        limit = min(limit, int(wrong[0]))
    wrong = line_of[on_arc[line_of] & ~(np.abs(values) <= length_limit)]
    if len(wrong):
        limit = min(limit, int(wrong[0]))
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
    unfed = np.flatnonzero((codes > 0.0) & ~(programmed > 0.0))
    if len(unfed):
        limit = min(limit, int(unfed[0]))
    ends = _positions(np, values, which, line_of, index, start_mm, offsets_mm, factor)
    starts = np.empty_like(ends)
    starts[0] = start_mm
    starts[1:] = ends[:-1]
    centers = starts.copy()
    radii = np.zeros(n)
    inside = (np.abs(ends) <= MAX_POSITION_MM).all(axis=1)
    arc_lines = np.flatnonzero(on_arc)
    if len(arc_lines):
        arc_rows = rows(arc_lines, n)
        for axis, letter in enumerate(b"ij"):
            mask = which == letter
            offset = np.zeros(n)
            offset[line_of[mask]] = values[mask] * factor
            centers[:, axis] = starts[:, axis] + offset
        arc_starts, arc_ends, arc_centers = starts[arc_rows], ends[arc_rows], centers[arc_rows]
        r0 = xy_hypot(arc_starts[:, 0] - arc_centers[:, 0], arc_starts[:, 1] - arc_centers[:, 1])
        r1 = xy_hypot(arc_ends[:, 0] - arc_centers[:, 0], arc_ends[:, 1] - arc_centers[:, 1])
        radii[arc_rows] = r0
        tolerance = (
            ARC_END_TOLERANCE_INCH * MM_PER_INCH if state.units == "inch" else ARC_END_TOLERANCE_MM
        )
        error = np.abs(r1 - r0)
        refused = (error > ARC_RADIUS_LIMIT_FACTOR * tolerance) | (
            (error > tolerance) & (error > ARC_RADIUS_TOLERANCE_REL * np.maximum(r0, r1))
        )
        inside[arc_rows] &= (np.abs(arc_centers) <= MAX_POSITION_MM).all(axis=1)
        wrong = arc_lines[refused | ~(r0 > 0.0)]
        if len(wrong):
            limit = min(limit, int(wrong[0]))
    outside = np.flatnonzero(~inside)
    if len(outside):
        limit = min(limit, int(outside[0]))
    limit = min(limit, max_moves)
    if limit < MIN_RUN_LINES:
        return None, max(limit, 1), 0
    codes = codes[:limit]
    programmed = programmed[:limit]
    run = MoveRun(
        file=file,
        first_line=first_line,
        start_mm=start_mm,
        end_mm=ends[:limit],
        motion=codes.astype(np.int64),
        center_mm=centers[:limit],
        radius_mm=radii[:limit],
        feed_mm_min=np.where(codes == 0.0, 0.0, programmed * factor),
        programmed_feed=programmed,
        state=state,
        spindle_rpm=spindle_rpm,
        abc_deg=abc_deg,
    )
    return run, limit, _line_end(np, head, limit)


def _words(grammar: _Grammar, data: bytes) -> tuple[bytes, int, Any, Any, Any, int] | int:
    """The longest run of lines of ``grammar`` at the start of ``data``: its bytes, its
    line count, the values of its words (``float`` of their text, as on the line-by-line
    path), their letters (lower case) and 0-based lines, and the lines before the first
    with an N or G word the fast path would not take. Only the lines looked at, if fewer
    than :data:`MIN_RUN_LINES` or a number that is none (such as ``1.2.3``)."""
    # Too few lines, or within the first lines a character no such line has or a line
    # without a letter each has (a G1 line among arcs), make no run: numpy is not even
    # imported.
    first = data[: MIN_RUN_LINES * (MAX_NUMBER_CHARS + 2)].split(b"\n", MIN_RUN_LINES)
    if (
        len(first) <= MIN_RUN_LINES
        or b"".join(first[:-1]).translate(None, grammar.alphabet)
        or not all(map(grammar.needed.search, first[:-1]))
    ):
        return 1
    np = _numpy()
    # Each window is checked from the end of the last, all of whose lines belong.
    size = 0
    window = _FIRST_WINDOW
    while True:
        part = data[size:window]
        cut = part.rfind(b"\n") + 1
        good = _valid_prefix(grammar, part[:cut])
        size += good
        if good < cut or window >= len(data):
            break
        window *= 4
    head = data[:size]
    n = head.count(b"\n")
    if n < MIN_RUN_LINES:
        return max(n, 1)
    layout = head.translate(None, grammar.not_letters)
    which = np.frombuffer(layout.replace(b"\n", b""), dtype=np.uint8) | 0x20
    per_line = np.diff(np.flatnonzero(np.frombuffer(layout, dtype=np.uint8) == 10), prepend=-1)
    line_of = np.repeat(np.arange(n), per_line - 1)
    limit = n
    values, digits_only, refused, digits = _numbers(head)
    # G words: those of the grammar (their G number as value), digits only; N words: digits
    # only (value 0); the other words: float() of their text (none if float() refuses one).
    g_at = np.flatnonzero(which == ord("g"))
    g_fits = (
        digits_only[g_at] & (digits[g_at] <= _G_DIGITS) & np.isin(values[g_at], grammar.g_numbers)
    )
    n_at = np.flatnonzero(which == ord("n"))
    values[n_at] = 0.0
    for at, fits in ((g_at, g_fits), (n_at, digits_only[n_at])):
        if not fits.all():
            limit = min(limit, int(line_of[at[np.argmin(fits)]]))
    if refused[(which != ord("g")) & (which != ord("n"))].any():
        return n
    return head, n, values, which, line_of, limit


def rows(at: Any, n: int) -> Any:
    """Index of the rows ``at`` (sorted, distinct numpy indices) of ``n`` rows: a slice of
    all of them when ``at`` holds them all (indexing with it copies nothing), else ``at``."""
    return slice(None) if len(at) == n else at


def _numbers(head: bytes) -> tuple[Any, Any, Any, Any]:
    """The numbers of the words of ``head`` (complete lines whose characters and word
    order :func:`_valid_prefix` accepted: each word's number follows its letter, and a
    number is one piece of the characters ``0-9 . + -``), in order, each (n,) numpy:
    ``float()`` of its text (where that accepts it), whether it is digits only, whether
    ``float()`` refuses it (a sign not in front, two dots, no digit) and its digits.

    A number of at most :data:`_EXACT_DIGITS` digits is its digits as an integer divided
    by ten to the power of its digits after the dot, negated after a minus (``-0`` gives
    -0.0, as ``float()``): the correctly rounded quotient of two exact doubles is the
    correctly rounded value of the text (Clinger, "How to read floating point numbers
    accurately", PLDI 1990). A longer number is read by ``float()``. The digits are read
    column by column (the first characters of all numbers, then the second, ...)."""
    np = _numpy()
    a = np.frombuffer(head, dtype=np.uint8)
    number = _NUMBER_BYTES[a]
    # Each number starts and ends where a byte of one and one of none meet (the lines
    # start with a letter or a blank and end with LF).
    edges = np.flatnonzero(number[1:] != number[:-1]) + 1
    starts, ends = edges[0::2], edges[1::2]
    length = ends - starts
    count = len(starts)
    integer = np.zeros(count, dtype=np.int64)
    after_dot = np.zeros(count, dtype=np.int64)
    digits = np.zeros(count, dtype=np.int64)
    dotted = np.zeros(count, dtype=bool)
    refused = np.zeros(count, dtype=bool)
    for column in range(int(length.max(initial=0))):
        inside = length > column
        char = a[np.minimum(starts + column, len(a) - 1)]
        digit = char - np.uint8(48)
        is_digit = (digit <= 9) & inside
        integer = np.where(is_digit, integer * 10 + digit, integer)
        digits += is_digit
        after_dot += is_digit & dotted
        dot = (char == 46) & inside
        refused |= dot & dotted
        dotted |= dot
        if column:
            refused |= ((char == 43) | (char == 45)) & inside
    refused |= digits == 0
    values = integer / _POWERS_OF_TEN[np.minimum(after_dot, _EXACT_DIGITS)]
    np.negative(values, out=values, where=a[starts] == 45)
    for i in np.flatnonzero((digits > _EXACT_DIGITS) & ~refused).tolist():
        values[i] = float(head[starts[i] : ends[i]])
    return values, digits == length, refused, digits


def _codes(
    np: Any,
    motion: int | None,
    values: Any,
    which: Any,
    line_of: Any,
    index: Any,
) -> Any:
    """The motion code (G-code key, 10 * G number) of each line, carried forward from the
    modal ``motion``; -1 before the first G word if ``motion`` is not G0 to G3."""
    g = which == ord("g")
    codes = np.empty(len(index) + 1)
    codes[0] = motion if motion in (0, 10, 20, 30) else -1.0
    g_lines = line_of[g]
    codes[g_lines + 1] = values[g] * 10.0
    return _carry(np, codes, g_lines, index)


def _positions(
    np: Any,
    values: Any,
    which: Any,
    line_of: Any,
    index: Any,
    start_mm: Vec3,
    offsets_mm: list[float],
    factor: float,
) -> Any:
    """(n, 3) machine positions, mm: X, Y, Z words * ``factor`` + offset (as
    :meth:`~cnctwin.nc.motion.Motion.xyz_move` and ``target``), absent axes where they were."""
    ends = np.empty((len(index), 3))
    for axis, letter in enumerate(b"xyz"):
        mask = which == letter
        lines = line_of[mask]
        column = np.empty(len(index) + 1)
        column[0] = start_mm[axis]
        column[lines + 1] = values[mask] * factor + offsets_mm[axis]
        ends[:, axis] = _carry(np, column, lines, index)
    return ends


def _line_end(np: Any, head: bytes, lines: int) -> int:
    """Bytes of the first ``lines`` lines of ``head``."""
    return int(np.flatnonzero(np.frombuffer(head, dtype=np.uint8) == 10)[lines - 1]) + 1


def _carry(np: Any, column: Any, given: Any, index: Any) -> Any:
    """``column[1:]`` with each row not in ``given`` (0-based rows) holding the last given
    value before it (``column[0]`` if none)."""
    source = np.zeros(len(index), dtype=np.intp)
    source[given] = index[given]
    np.maximum.accumulate(source, out=source)
    return column[source]
