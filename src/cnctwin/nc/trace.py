"""Canonical move traces, comparable with LinuxCNC's interpreter output.

LinuxCNC's interpreter reports motion as canonical machining calls in the program frame
(machine position minus work and tool offsets) and in the program's units:
``STRAIGHT_TRAVERSE(x, y, z, a, b, c)``, ``STRAIGHT_FEED(...)``,
``ARC_FEED(first_end, second_end, first_centre, second_centre, rotation, normal_end, a, b, c)``
and ``DWELL(seconds)``. :func:`canonical_moves` turns segments into those calls, so that a
trace of cnctwin can be compared number by number with one of LinuxCNC.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass

from cnctwin.errors import InputError
from cnctwin.nc.segments import PLANE_AXES, MotionKind, Segment

__all__ = ["CanonicalMove", "canonical_moves", "format_trace"]

_MM_PER_INCH = 25.4


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
        if self.name == "ARC_FEED":
            parts = [f"{v:.4f}" for v in self.values]
            parts[4] = str(int(self.values[4]))
            return f"ARC_FEED({', '.join(parts)})"
        return f"{self.name}({', '.join(f'{v:.4f}' for v in self.values)})"


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
    if frame not in ("program", "machine"):
        raise InputError(f"frame must be 'program' or 'machine', not {frame!r}")
    program = frame == "program"
    for seg in segments:
        state = seg.state
        if program:
            scale = 1.0 / _MM_PER_INCH if state.units == "inch" else 1.0
            e = state.to_program(seg.end_mm)
        else:
            scale = 1.0
            e = seg.end_mm
        end = (e[0] * scale, e[1] * scale, e[2] * scale)
        abc = seg.end_abc_deg
        kind = seg.kind
        if kind == MotionKind.DWELL:
            yield CanonicalMove("DWELL", (seg.dwell_s,), seg.line)
        elif kind == MotionKind.ARC and seg.center_mm is not None:
            first, second, normal = PLANE_AXES[state.plane]
            c = state.to_program(seg.center_mm) if program else seg.center_mm
            centre = (c[0] * scale, c[1] * scale, c[2] * scale)
            yield CanonicalMove(
                "ARC_FEED",
                (
                    end[first],
                    end[second],
                    centre[first],
                    centre[second],
                    float(seg.turns),
                    end[normal],
                    abc[0],
                    abc[1],
                    abc[2],
                ),
                seg.line,
            )
        else:
            name = "STRAIGHT_TRAVERSE" if kind == MotionKind.RAPID else "STRAIGHT_FEED"
            yield CanonicalMove(name, (*end, *abc), seg.line)


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
    for move in canonical_moves(segments, frame):
        yield f"{move.line} {move.format()}"
