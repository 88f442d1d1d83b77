"""Reading LinuxCNC tool tables.

A tool table has one tool a line, as whitespace-separated words, then an optional
``;`` comment, e.g. ``T4 P4 Z0.7 D1.0 ;comment``. Words: ``T`` tool number (required),
``P`` pocket, ``X Y Z U V W`` offsets, ``A B C`` rotary offsets, ``D`` diameter,
``I J`` lathe front and back angles (degrees), ``Q`` lathe orientation (0-9).
Letters may be lower case. Blank and comment-only lines are skipped. An entry keeps
``Z`` (length offset), ``X`` (lathe X offset), ``D`` and ``Q``; the other words are checked
but not used.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Literal

from cnctwin.errors import DataError
from cnctwin.nc.setup import ToolEntry

__all__ = ["parse_tool_table", "read_tool_table"]

_MM_PER_INCH = 25.4
_INTEGER_WORDS = frozenset("TPQ")
_LENGTH_WORDS = frozenset("XYZUVWD")
_ANGLE_WORDS = frozenset("ABCIJ")
_VALID = "T P X Y Z A B C U V W D I J Q"


def read_tool_table(
    path: str | os.PathLike[str], *, units: Literal["mm", "inch"] = "mm"
) -> dict[int, ToolEntry]:
    """Read a LinuxCNC tool table file.

    Parameters
    ----------
    path
        The ``.tbl`` file (UTF-8 text).
    units
        Units of the file's lengths: ``"mm"`` or ``"inch"`` (converted to mm).

    Returns
    -------
    dict[int, ToolEntry]
        Entries by tool number, lengths in mm.

    Raises
    ------
    cnctwin.errors.DataError
        If the file cannot be read, or a line is bad (``"FILE:LINE: ..."`` naming the word).
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as err:
        raise DataError(f"{path}: cannot read tool table: {err.strerror}") from err
    except UnicodeDecodeError as err:
        raise DataError(f"{path}: tool table is not UTF-8 text (byte {err.start})") from err
    return parse_tool_table(text, units=units, source=str(path))


def parse_tool_table(
    text: str, *, units: Literal["mm", "inch"] = "mm", source: str = "<string>"
) -> dict[int, ToolEntry]:
    """Parse the text of a LinuxCNC tool table.

    Parameters
    ----------
    text
        The table, one tool a line.
    units
        Units of the lengths (``X Y Z U V W D``): ``"mm"`` or ``"inch"`` (converted to mm).
    source
        Name used in error messages.

    Returns
    -------
    dict[int, ToolEntry]
        Entries by tool number, lengths in mm.

    Raises
    ------
    cnctwin.errors.DataError
        ``"SOURCE:LINE: ..."`` for a bad line: an unknown or repeated word, a value that is
        not a number, a negative tool number, pocket or diameter, a missing ``T``, or a tool
        number given twice.
    """
    if units not in ("mm", "inch"):
        raise DataError(f"{source}: tool table units must be 'mm' or 'inch'; got {units!r}")
    scale = _MM_PER_INCH if units == "inch" else 1.0
    tools: dict[int, ToolEntry] = {}
    first_line: dict[int, int] = {}
    for number, raw in enumerate(text.splitlines(), 1):
        where = f"{source}:{number}"
        words = _parse_line(raw.split(";", 1)[0], where)
        if not words:
            continue
        if "T" not in words:
            raise DataError(f"{where}: no T word; every tool line starts like 'T4 P4'")
        tool = int(words["T"])
        if tool in first_line:
            raise DataError(f"{where}: tool T{tool} is already defined on line {first_line[tool]}")
        first_line[tool] = number
        tools[tool] = ToolEntry(
            number=tool,
            length_mm=words.get("Z", 0.0) * scale,
            x_offset_mm=words.get("X", 0.0) * scale,
            diameter_mm=words.get("D", 0.0) * scale,
            orientation=int(words.get("Q", 0)),
        )
    return tools


def _parse_line(body: str, where: str) -> dict[str, float]:
    """Words of one line (comment removed) by upper-case letter."""
    words: dict[str, float] = {}
    for token in body.split():
        letter, digits = token[0].upper(), token[1:]
        if letter not in _INTEGER_WORDS | _LENGTH_WORDS | _ANGLE_WORDS:
            raise DataError(f"{where}: unknown word {token!r}; valid letters: {_VALID}")
        if letter in words:
            raise DataError(f"{where}: word {letter} appears twice ({token!r})")
        words[letter] = _value(letter, digits, token, where)
    return words


def _value(letter: str, digits: str, token: str, where: str) -> float:
    if letter in _INTEGER_WORDS:
        try:
            whole = int(digits)
        except ValueError:
            raise DataError(f"{where}: {letter} needs a whole number; got {token!r}") from None
        if whole < 0 or (letter == "Q" and whole > 9):
            valid = "0 to 9" if letter == "Q" else ">= 0"
            raise DataError(f"{where}: {letter} must be {valid}; got {token!r}")
        return whole
    try:
        value = float(digits)
    except ValueError:
        raise DataError(f"{where}: {letter} needs a number; got {token!r}") from None
    if not math.isfinite(value):
        raise DataError(f"{where}: {letter} must be finite; got {token!r}")
    if letter == "D" and value < 0:
        raise DataError(f"{where}: diameter D must be >= 0; got {token!r}")
    return value
