"""Arc and spline geometry of the interpreter: centres from R or I/J/K words, LinuxCNC's
end-radius test, turn counts, and the chords of G5.1 quadratic splines.

Positions are machine coordinates in mm, as lists or tuples (x, y, z); ``i0``, ``i1`` are
the indices of the plane's first and second axes (:data:`~cnctwin.nc.segments.PLANE_AXES`).
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from typing import Final

from cnctwin.errors import NCError

__all__ = [
    "ARC_END_TOLERANCE_INCH",
    "ARC_END_TOLERANCE_MM",
    "ARC_RADIUS_LIMIT_FACTOR",
    "ARC_RADIUS_TOLERANCE_MM",
    "ARC_RADIUS_TOLERANCE_REL",
    "MM_PER_INCH",
    "SPLINE_TOLERANCE_MM",
    "arc_end_refused",
    "arc_turns",
    "center_from_radius",
    "spline_points",
]

MM_PER_INCH: Final = 25.4
#: Largest amount by which an R-format arc's radius may fall short of half its chord, mm.
ARC_RADIUS_TOLERANCE_MM: Final = 0.005
#: LinuxCNC's test of an I/J/K arc's end radius (measured with its rs274): refused when the
#: end radius differs from the start radius by more than the absolute tolerance and by more
#: than ARC_RADIUS_TOLERANCE_REL of the larger radius, or by more than
#: ARC_RADIUS_LIMIT_FACTOR times the absolute tolerance. The absolute tolerance is in program
#: units: 0.028284 mm under G21, 0.0028284 in (0.0718 mm) under G20.
ARC_END_TOLERANCE_MM: Final = 0.028284
ARC_END_TOLERANCE_INCH: Final = 0.0028284
ARC_RADIUS_TOLERANCE_REL: Final = 0.001
ARC_RADIUS_LIMIT_FACTOR: Final = 100.0
#: Chord tolerance of the line segments that approximate G5.1 splines, mm.
SPLINE_TOLERANCE_MM: Final = 0.001


def arc_turns(p_word: float | None, ccw: bool) -> int:
    """Signed turn count of an arc (``turns`` of :class:`~cnctwin.nc.segments.Segment`):
    the P word (1 if absent), positive for G3 (``ccw``), negative for G2.

    Raises
    ------
    NCError
        Unlocated, for a P word that is not a positive integer.
    """
    if p_word is None:
        return 1 if ccw else -1
    if abs(p_word - round(p_word)) < 1e-9:
        p_word = float(round(p_word))
    if p_word < 1 or p_word != int(p_word):
        raise NCError(f"arc turn count P{p_word:g} must be a positive integer")
    return int(p_word) * (1 if ccw else -1)


def center_from_radius(
    radius_mm: float,
    start: Sequence[float],
    end: Sequence[float],
    i0: int,
    i1: int,
    ccw: bool,
    factor: float,
) -> list[float]:
    """Centre (mm) of an R-format arc from ``start`` to ``end``.

    ``radius_mm`` < 0 asks for the arc of more than 180 degrees; ``factor`` (mm per
    program unit) only scales the numbers in the error message. A radius short of half
    the chord by at most :data:`ARC_RADIUS_TOLERANCE_MM` is taken as half the chord.

    Raises
    ------
    NCError
        Unlocated, for a full circle (start = end) or a radius too small for the chord.
    """
    du = end[i0] - start[i0]
    dv = end[i1] - start[i1]
    chord = math.hypot(du, dv)
    if chord < 1e-9:
        raise NCError("full circle with R format: the centre is undefined; use I/J/K offsets")
    half = chord / 2.0
    r = abs(radius_mm)
    if r < half:
        if half - r > ARC_RADIUS_TOLERANCE_MM:
            raise NCError(
                f"arc radius R{radius_mm / factor:g} is smaller than half the distance "
                f"to the end point ({half / factor:.4f}): no such arc"
            )
        r = half
    h = math.sqrt(max(r * r - half * half, 0.0))
    # Left normal of the chord; CCW arcs of less than 180 deg have their centre on the left.
    nu, nv = -dv / chord, du / chord
    side = 1.0 if ccw else -1.0
    if radius_mm < 0:
        side = -side
    center = list(start)
    center[i0] = start[i0] + du / 2.0 + side * h * nu
    center[i1] = start[i1] + dv / 2.0 + side * h * nv
    return center


def arc_end_refused(r0_mm: float, r1_mm: float, units: str) -> bool:
    """Whether LinuxCNC refuses an arc whose start and end radii (mm) are ``r0_mm``, ``r1_mm``.

    ``units``: the program's units (``"mm"`` or ``"inch"``), which set the absolute tolerance.
    """
    tolerance = ARC_END_TOLERANCE_INCH * MM_PER_INCH if units == "inch" else ARC_END_TOLERANCE_MM
    error = abs(r1_mm - r0_mm)
    if error > ARC_RADIUS_LIMIT_FACTOR * tolerance:
        return True
    return error > tolerance and error > ARC_RADIUS_TOLERANCE_REL * max(r0_mm, r1_mm)


def spline_points(
    start: Sequence[float], control: tuple[float, float], end: Sequence[float]
) -> Iterator[list[float]]:
    """Chord end points (mm) of a G5.1 quadratic B-spline in the XY plane.

    The spline (a quadratic Bezier curve) runs from ``start`` past the XY ``control`` point
    to ``end``; Z moves linearly. It is split into n chords whose deviation
    ``|P0 - 2 P1 + P2| / (8 n^2)`` stays below :data:`SPLINE_TOLERANCE_MM`.
    """
    ax = start[0] - 2 * control[0] + end[0]
    ay = start[1] - 2 * control[1] + end[1]
    bend = math.hypot(ax, ay)
    n = max(1, math.ceil(math.sqrt(bend / (8.0 * SPLINE_TOLERANCE_MM))))
    for k in range(1, n + 1):
        t = k / n
        u = 1.0 - t
        yield [
            u * u * start[0] + 2 * u * t * control[0] + t * t * end[0],
            u * u * start[1] + 2 * u * t * control[1] + t * t * end[1],
            start[2] + (end[2] - start[2]) * t,
        ]
