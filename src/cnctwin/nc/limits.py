"""Bounds on NC input and on the work one program may ask for.

Every word value, every program and every amplifying construct (loops, canned-cycle
repeats and pecks) is checked against the bounds here before it is used, so that a
hostile or corrupted program ends in an :class:`~cnctwin.errors.NCError` within seconds
instead of overflowing, hanging or filling memory. The bounds are far beyond any real
machine or CAM output (see ``docs/nc.md``, *Input limits*, for the reasoning behind
each):

- lengths (X Y Z U W I J K R @ Q, tool diameters D): |v| <= 1e6 program units; a
  machine position beyond :data:`MAX_POSITION_MM` (1 km) is refused after offsets and
  inch conversion, so inch programs are bounded at about 39 370 in;
- angles (A B C ^): |v| <= 1e6 degrees;
- feeds F <= 1e9 (mm/min, in/min, per rev, or 1/min in inverse time, where a
  micrometre move at 1 m/min is already F1e6), speeds S <= 1e6 (rpm or m/min);
- dwell and other P values <= 1e6 (s, turns, tolerance); L <= 1e6 (canned-cycle
  repeats are bounded further by :data:`MAX_CYCLE_REPEATS`);
- tool numbers T and offset registers H <= 99 999; G <= 1000, M <= 10 000, N <= 1e12;
- a number literal has at most :data:`MAX_NUMBER_CHARS` characters.
"""

from __future__ import annotations

import math
from typing import Final

from cnctwin.errors import NCError

__all__ = [
    "MAX_CYCLE_REPEATS",
    "MAX_LINE_BYTES",
    "MAX_NUMBER_CHARS",
    "MAX_PECKS",
    "MAX_POSITION_MM",
    "MAX_PROGRAM_BYTES",
    "MAX_REPEATED_LINES",
    "MAX_SEGMENTS",
    "MAX_SEGMENTS_PER_BLOCK",
    "WORD_LIMITS",
    "check_number_text",
    "check_position",
    "check_word",
]

#: Largest magnitude of a machine position, mm (1 km: twenty times the travel of the
#: largest gantry mills).
MAX_POSITION_MM: Final = 1e6
#: Longest number literal, characters (sign, digits and point): a double has 17
#: significant digits, so 64 leave room for any padding a post-processor writes.
MAX_NUMBER_CHARS: Final = 64
#: Longest line, bytes (LinuxCNC reads at most 256 characters a line).
MAX_LINE_BYTES: Final = 65_536
#: Largest program file, bytes, by default (about ten million lines of CAM output).
MAX_PROGRAM_BYTES: Final = 256 * 1024 * 1024
#: Most motion segments one program may produce, by default (a ten-million-line
#: program; minutes of interpretation at the 60 000 segments/s of a loaded machine).
MAX_SEGMENTS: Final = 10_000_000
#: Most segments a single block may produce (canned-cycle repeats and pecks, splines).
MAX_SEGMENTS_PER_BLOCK: Final = 1_000_000
#: Most lines read again after O-word jumps back (loop iterations, subroutine calls),
#: by default: seconds of work (about 10 s on a loaded two-core machine).
MAX_REPEATED_LINES: Final = 1_000_000
#: Largest canned-cycle repeat count L (holes drilled by one block).
MAX_CYCLE_REPEATS: Final = 10_000
#: Most pecks of one G73/G83 hole.
MAX_PECKS: Final = 10_000

_LENGTH: Final = 1e6
_TOOL: Final = 99_999.0
#: Largest allowed magnitude of each word, in program units (mm or inch, degrees,
#: mm/min or in/min, rpm, s); any other letter has the length bound. G and M values are
#: then checked as codes by the lexer.
WORD_LIMITS: Final[dict[str, tuple[float, str]]] = {
    **{letter: (_LENGTH, "length") for letter in "xyzuwijkrq@d"},
    **{letter: (_LENGTH, "angle, degrees") for letter in "abc^"},
    "f": (1e9, "feed"),
    "s": (_LENGTH, "spindle speed"),
    "p": (_LENGTH, "P value"),
    "l": (_LENGTH, "L value"),
    "t": (_TOOL, "tool number"),
    "h": (_TOOL, "tool offset number"),
    "g": (1000.0, "G number"),
    "m": (10_000.0, "M number"),
    "n": (1e12, "line number"),
}
_DEFAULT_LIMIT: Final = (_LENGTH, "value")


def check_number_text(text: str, column: int | None = None) -> None:
    """Refuse a number literal longer than :data:`MAX_NUMBER_CHARS` characters.

    Parameters
    ----------
    text
        The literal as written.
    column
        1-based column of the literal in its line, if known.

    Raises
    ------
    NCError
        Naming the first characters of the literal and the limit.
    """
    if len(text) > MAX_NUMBER_CHARS:
        raise NCError(
            f"number '{text[:20]}...' has {len(text)} characters; at most "
            f"{MAX_NUMBER_CHARS} are allowed",
            column=column,
        )


def check_word(letter: str, value: float) -> None:
    """Refuse a word value that is not finite or beyond its bound in :data:`WORD_LIMITS`.

    Parameters
    ----------
    letter
        The word's lower-case letter (``@`` and ``^`` for polar words).
    value
        Its value in program units.

    Raises
    ------
    NCError
        Naming the word, its value and the valid range.
    """
    limit, what = WORD_LIMITS.get(letter, _DEFAULT_LIMIT)
    if not -limit <= value <= limit:  # also false for NaN
        raise NCError(
            f"word {letter.upper()}{value:.6g} is out of range ({what}): valid values are "
            f"finite and within +-{limit:g}"
        )


def check_position(axis: str, value_mm: float) -> None:
    """Refuse a machine position beyond :data:`MAX_POSITION_MM` (or not finite).

    Parameters
    ----------
    axis
        ``"X"``, ``"Y"`` or ``"Z"``.
    value_mm
        The position in machine coordinates, mm.

    Raises
    ------
    NCError
        Naming the axis, the position and the bound.
    """
    if not (math.isfinite(value_mm) and abs(value_mm) <= MAX_POSITION_MM):
        raise NCError(
            f"{axis} position {value_mm:.6g} mm is out of range: machine positions must lie "
            f"within +-{MAX_POSITION_MM:g} mm (after offsets and unit conversion)"
        )
