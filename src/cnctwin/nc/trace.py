"""Canonical move traces, comparable with LinuxCNC's interpreter output.

LinuxCNC's interpreter reports motion as canonical machining calls in the program frame
(machine position minus work and tool offsets) and in the program's units:
``STRAIGHT_TRAVERSE(x, y, z, a, b, c)``, ``STRAIGHT_FEED(...)``,
``ARC_FEED(first_end, second_end, first_centre, second_centre, rotation, normal_end, a, b, c)``
and ``DWELL(seconds)``. :func:`canonical_moves` turns segments into those calls, so that a
trace of cnctwin can be compared number by number with one of LinuxCNC; :func:`format_trace`
prints them one a line, and :func:`trace_text` prints runs of moves read in bulk
(:class:`~cnctwin.nc.runs.MoveRun`) as well, all lines of a run at once with numpy.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from typing import Any, Final

from cnctwin.errors import InputError
from cnctwin.nc.arcs import MM_PER_INCH
from cnctwin.nc.runs import MoveRun
from cnctwin.nc.segments import PLANE_AXES, MachineState, MotionKind, Segment, Vec3

__all__ = ["CanonicalMove", "canonical_moves", "format_trace", "trace_text"]

#: How every number of a call is printed (LinuxCNC prints four decimals).
_NUMBER: Final = "%.4f"
_THREE: Final = ", ".join([_NUMBER] * 3)
#: Each call's text as a ``%`` format of its numbers before the rotary axes (the arc's
#: rotation an integer), and then of those axes (a dwell has none).
_CALLS: Final = {
    "STRAIGHT_TRAVERSE": f"STRAIGHT_TRAVERSE({_THREE}, %s)",
    "STRAIGHT_FEED": f"STRAIGHT_FEED({_THREE}, %s)",
    "ARC_FEED": f"ARC_FEED({_NUMBER}, {_NUMBER}, {_NUMBER}, {_NUMBER}, %d, {_NUMBER}, %s)",
    "DWELL": f"DWELL({_NUMBER})",
}
#: A trace line: the source line, the call, the line end.
_LINES: Final = {name: f"%d {call}\n" for name, call in _CALLS.items()}


@dataclass(frozen=True, slots=True)
class CanonicalMove:
    """One canonical call.

    Attributes
    ----------
    name
        ``STRAIGHT_TRAVERSE``, ``STRAIGHT_FEED``, ``ARC_FEED`` or ``DWELL``.
    values
        The call's arguments, lengths in the program's units in the program frame,
        rotary axes in degrees, dwell in s, arc rotation as a signed turn count.
    line
        Source line of the segment.
    """

    name: str
    values: tuple[float, ...]
    line: int

    def format(self) -> str:
        """The call as text, e.g. ``STRAIGHT_FEED(1.0000, 2.0000, ...)``."""
        if self.name == "DWELL":
            return _CALLS[self.name] % self.values
        return _CALLS[self.name] % (*self.values[:-3], _THREE % self.values[-3:])


def _is_program_frame(frame: str) -> bool:
    if frame not in ("program", "machine"):
        raise InputError(f"frame must be 'program' or 'machine', not {frame!r}")
    return frame == "program"


def _unit_scale(state: MachineState) -> float:
    """Program units per mm: a trace in the program frame is in the program's units."""
    return 1.0 / MM_PER_INCH if state.units == "inch" else 1.0


def _call(seg: Segment, program: bool) -> tuple[str, tuple[float, ...], Vec3 | None]:
    """The canonical call of one segment: its name, its arguments before the rotary axes,
    and those axes (degrees; ``None`` for a dwell). See :class:`CanonicalMove`."""
    state = seg.state
    kind = seg.kind
    if kind == MotionKind.DWELL:
        return "DWELL", (seg.dwell_s,), None
    if program:
        scale = _unit_scale(state)
        e = state.to_program(seg.end_mm)
    else:
        scale = 1.0
        e = seg.end_mm
    end = e if scale == 1.0 else (e[0] * scale, e[1] * scale, e[2] * scale)
    if kind == MotionKind.ARC and seg.center_mm is not None:
        first, second, normal = PLANE_AXES[state.plane]
        c = state.to_program(seg.center_mm) if program else seg.center_mm
        centre = c if scale == 1.0 else (c[0] * scale, c[1] * scale, c[2] * scale)
        values = (end[first], end[second], centre[first], centre[second], float(seg.turns))
        return "ARC_FEED", (*values, end[normal]), seg.end_abc_deg
    name = "STRAIGHT_TRAVERSE" if kind == MotionKind.RAPID else "STRAIGHT_FEED"
    return name, end, seg.end_abc_deg


def canonical_moves(segments: Iterable[Segment], frame: str = "program") -> Iterator[CanonicalMove]:
    """Canonical calls for a stream of segments.

    Parameters
    ----------
    segments
        Segments from the interpreter.
    frame
        ``"program"``: program frame and units, as LinuxCNC prints them;
        ``"machine"``: machine coordinates of the controlled point in mm.

    Yields
    ------
    CanonicalMove
    """
    program = _is_program_frame(frame)
    for seg in segments:
        name, values, abc = _call(seg, program)
        yield CanonicalMove(name, values if abc is None else (*values, *abc), seg.line)


def format_trace(segments: Iterable[Segment], frame: str = "program") -> Iterator[str]:
    """Lines ``"<source line> <canonical call>"`` for a stream of segments.

    Parameters
    ----------
    segments
        Segments from the interpreter.
    frame
        ``"program"`` (LinuxCNC-comparable) or ``"machine"`` (mm, machine coordinates).

    Yields
    ------
    str
    """
    for line in trace_text(segments, frame):
        yield line[:-1]


def trace_text(items: Iterable[Segment | MoveRun], frame: str = "program") -> Iterator[str]:
    """The lines of :func:`format_trace`, each ending in ``"\\n"``, for segments and runs of
    moves read in bulk (:meth:`~cnctwin.nc.interpreter.Interpreter.run_file_bulk`): a run's
    lines come as one string, equal to those of its segments.

    Parameters
    ----------
    items
        Segments and runs from the interpreter.
    frame
        ``"program"`` (LinuxCNC-comparable) or ``"machine"`` (mm, machine coordinates).

    Yields
    ------
    str
        One or more complete lines.
    """
    program = _is_program_frame(frame)
    last_abc: Vec3 | None = None
    abc_text = ""  # the rotary axes printed: mostly the same from line to line
    for item in items:
        if isinstance(item, MoveRun):
            yield _run_text(item, program)
            continue
        name, values, abc = _call(item, program)
        if abc is None:
            yield _LINES[name] % (item.line, *values)
            continue
        if abc is not last_abc:
            last_abc = abc
            abc_text = _THREE % abc
        yield _LINES[name] % (item.line, *values, abc_text)


def _run_text(run: MoveRun, program: bool) -> str:
    """The trace lines of a run, with the numbers :func:`_call` gives its segments: the same
    floating-point operations on numpy columns, printed by :func:`_lines_text`.

    A run is in the XY plane and never rotated (:mod:`cnctwin.nc.runs`), so the program
    frame is ``MachineState.to_program`` without its rotation: machine minus work, tool and
    axis offsets, in that order, then times the unit scale.
    """
    import numpy as np  # imported already: the run was read with it

    state = run.state
    end = run.end_mm
    centre = run.center_mm
    if program:
        scale = _unit_scale(state)
        for shift in (state.work_offset_mm, state.tool_offset_mm, state.axis_offset_mm):
            end = end - np.array(shift)
            centre = centre - np.array(shift)
        end = end * scale
        centre = centre * scale
    kind = run.motion // 10  # 0 to 3: G0 to G3
    arc = kind >= 2
    numbers = np.empty((len(end), 5))
    numbers[:, 0:2] = end[:, :2]
    numbers[:, 2] = np.where(arc, centre[:, 0], end[:, 2])
    numbers[:, 3] = centre[:, 1]
    numbers[:, 4] = end[:, 2]
    # Per kind, the text before the line's first number, then after each number: the
    # call's format with the run's rotary axes and the arc's rotation filled in.
    abc = _THREE % run.abc_deg
    calls = [_CALLS[name].replace("%d", turns).replace("%s", abc) for name, turns in _RUN_CALLS]
    texts = [f" {call}\n".split(_NUMBER) for call in calls]
    return _lines_text(np, run.first_line, kind, texts, numbers)


#: A run's calls by motion code // 10 (G0 to G3), with the arc's rotation (G2 clockwise).
_RUN_CALLS: Final = (
    ("STRAIGHT_TRAVERSE", ""),
    ("STRAIGHT_FEED", ""),
    ("ARC_FEED", "-1"),
    ("ARC_FEED", "1"),
)

#: Widest number :func:`_lines_text` prints itself: below 2**52 ten-thousandths, so that
#: ``rint`` of the scaled value is an exact integer (about 4.5e11 mm or inch).
_FIXED_LIMIT: Final = 2.0**52
_ZERO: Final = 48  # b"0"


def _lines_text(np: Any, first_line: int, kind: Any, texts: list[list[str]], numbers: Any) -> str:
    """Lines ``"<line> <text 0><number 0><text 1><number 1>...<last text>"`` for
    consecutive source lines from ``first_line``, each number printed as ``"%.4f"`` does.

    ``texts[k]`` are the constant pieces of a line of kind ``k``: the first before its
    first number, then one after each number (a line of kind ``k`` has
    ``len(texts[k]) - 1`` numbers); ``kind`` (n,) is each line's kind and ``numbers``
    (n, m) its numbers, the first of each row printed.
    The text is put together as bytes in fixed-width fields, zero bytes where a field is
    shorter, and the zeros dropped: numpy, no call per number.

    The digits are those of ``rint(|value| * 10000)``, which are ``"%.4f"``'s (the
    correctly rounded digits of the exact binary value) unless the product lies within
    its rounding error of a half: there, and for numbers too wide or not finite, the lines
    are printed with Python's ``%`` instead.
    """
    n, m = numbers.shape
    counts = np.array([len(row) - 1 for row in texts])[kind]
    used = np.arange(m) < counts[:, None]
    values = np.where(used, numbers, 0.0)
    magnitude = np.abs(values) * 10000.0
    near_half = np.abs(magnitude - np.floor(magnitude) - 0.5) <= 2.0 * np.spacing(magnitude)
    if not np.all(magnitude < _FIXED_LIMIT) or np.any(near_half):
        return _lines_text_python(first_line, kind, texts, numbers)
    scaled = np.rint(magnitude).astype(np.int64)
    fraction = scaled % 10000
    decimals = [(fraction // 10 ** (3 - k) % 10 + _ZERO).astype(np.uint8) for k in range(4)]
    point = np.full((n, m, 1), ord("."), dtype=np.uint8)
    whole = _digits(np, scaled // 10000, np.signbit(values))
    fields = np.concatenate([whole, point, np.stack(decimals, axis=-1)], axis=-1)
    fields[~used] = 0
    table = _text_table(np, texts)
    pieces = [_digits(np, np.arange(first_line, first_line + n)), table[kind, 0]]
    for j in range(m):
        pieces += [fields[:, j], table[kind, j + 1]]
    block = np.concatenate(pieces, axis=-1).ravel()
    text: bytes = block[block != 0].tobytes()
    return text.decode("ascii")


def _digits(np: Any, values: Any, negative: Any = None) -> Any:
    """Decimal digits of non-negative integers (numpy int64, any shape), right-aligned in
    bytes along a new last axis, zero bytes before, with ``"-"`` before those where
    ``negative`` is true."""
    widest = int(values.max(initial=0))
    width = len(str(widest)) + 1  # one more for a sign
    out = np.zeros((*values.shape, width), dtype=np.uint8)
    power = 1
    for k in range(width - 1):
        digit = (values // power % 10 + _ZERO).astype(np.uint8)
        out[..., width - 1 - k] = np.where((values >= power) | (k == 0), digit, 0)
        power *= 10
    if negative is not None:
        length = np.count_nonzero(out, axis=-1)
        minus = np.where(negative, ord("-"), 0).astype(np.uint8)
        np.put_along_axis(out, (width - 1 - length)[..., None], minus[..., None], axis=-1)
    return out


def _text_table(np: Any, texts: list[list[str]]) -> Any:
    """(kinds, pieces, width) bytes of the constant pieces, zero bytes after each and for
    pieces a kind does not have."""
    width = max(len(t) for row in texts for t in row)
    table = np.zeros((len(texts), max(len(row) for row in texts), width), dtype=np.uint8)
    for k, row in enumerate(texts):
        for j, text in enumerate(row):
            table[k, j, : len(text)] = np.frombuffer(text.encode("ascii"), dtype=np.uint8)
    return table


def _lines_text_python(first_line: int, kind: Any, texts: list[list[str]], numbers: Any) -> str:
    """As :func:`_lines_text`, each number formatted by Python's ``%``."""
    formats = [f"%d{row[0]}" + "".join([f"{_NUMBER}{t}" for t in row[1:]]) for row in texts]
    kinds = kind.tolist()
    flat: list[float] = []
    for line, k, row in zip(
        range(first_line, first_line + len(kinds)), kinds, numbers.tolist(), strict=True
    ):
        flat += (line, *row[: len(texts[k]) - 1])
    return "".join([formats[k] for k in kinds]) % tuple(flat)
