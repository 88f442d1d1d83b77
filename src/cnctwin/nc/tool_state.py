"""Tool state: the tool table as the program changes it, the selected tool (T), tool
changes (M6, M61, Fanuc lathe T0101), tool length offsets (G43, G43.1, G43.2, G49) and
tool-table writes (G10 L1, L10, L11). Lengths in mm.
"""

from __future__ import annotations

from collections.abc import Sequence

from cnctwin.nc.cursor import ProgramCursor
from cnctwin.nc.setup import NCSetup, ToolEntry

__all__ = ["ToolState"]


class ToolState:
    """Tools known to the program, the selected one, and those loaded so far.

    Parameters
    ----------
    setup
        The tool table, the lathe flag (T0101 words) and whether a T word loads the tool
        at once (grbl, CAMotics).
    where
        Where errors and warnings are reported.

    Attributes
    ----------
    table
        Tool table by tool number (G10 L1/L10/L11 change it).
    selected
        The tool the last T word selected, to be loaded by M6.
    used
        Tool numbers loaded, in order of first use (tool 0, the empty spindle, excluded).
    """

    __slots__ = ("table", "selected", "used", "_where", "_lathe", "_change_on_t")

    def __init__(self, setup: NCSetup, where: ProgramCursor) -> None:
        self.table: dict[int, ToolEntry] = dict(setup.tools)
        self.selected = 0
        self.used: list[int] = []
        self._where = where
        self._lathe = setup.lathe
        self._change_on_t = setup.tool_change_on_t

    def select(self, value: float) -> tuple[bool, int | None]:
        """T word. Returns whether the selected tool is loaded at once, and the offset
        register to apply at once (Fanuc lathe ``T0101``: tool 01, register 01) or ``None``.

        Raises
        ------
        NCError
            For a T word that is not a non-negative integer.
        """
        if value < 0 or value != int(value):
            raise self._where.error(f"tool number T{value:g} must be a non-negative integer")
        number = int(value)
        if self._lathe and number >= 100:
            tool, register = divmod(number, 100)
            self.selected = tool
            return True, register
        self.selected = number
        return self._change_on_t, None

    def load(self, tool: int) -> int:
        """Load ``tool`` into the spindle (M6 loads :attr:`selected`); returns it."""
        if tool not in self.used and tool != 0:
            self.used.append(tool)
        return tool

    def load_without_change(self, q_word: float | None) -> int:
        """M61 Q: make tool Q the current tool without a tool change (LinuxCNC); returns it.

        Raises
        ------
        NCError
            For a missing Q word or one that is not a non-negative integer.
        """
        if q_word is None or q_word < 0 or q_word != int(q_word):
            q = "no Q word" if q_word is None else f"Q{q_word:g}"
            raise self._where.error(f"M61 needs Q<tool number>, a non-negative integer; got {q}")
        return self.load(int(q_word))

    def entry(self, number: int, consequence: str) -> ToolEntry:
        """Tool-table entry, or an empty one with a warning (naming ``consequence``) when
        the table lacks it."""
        entry = self.table.get(number)
        if entry is None:
            entry = ToolEntry(number)
            if number != 0:
                self._where.warn(
                    f"tool {number} is not in the tool table: {consequence} "
                    "(add it to the configuration's [[tools]] or tool_table)"
                )
        return entry

    def register_offset(self, register: int, t_word: int) -> list[float]:
        """Tool offset vector (x, y, z) in mm of a Fanuc lathe offset register, applied by
        the T word ``t_word`` (e.g. 101 for T0101)."""
        entry = self.entry(register, f"T{t_word:04d} applies a zero offset")
        return [entry.x_offset_mm, 0.0, entry.length_mm]

    def length_offset(
        self,
        code: int,
        words: dict[str, float],
        tool: int,
        factor: float,
        current: Sequence[float],
    ) -> list[float]:
        """Tool offset vector (x, y, z) in mm after G43 (``code`` 430: tool H, default the
        current ``tool``), G43.1 (431: X Y Z words, program units, ``factor`` mm each),
        G43.2 (432: add tool H's offsets to ``current``) or G49 (490: zero).

        Raises
        ------
        NCError
            For an H word that is not a non-negative integer, or G43.2 without a known tool.
        """
        if code == 490:
            return [0.0, 0.0, 0.0]
        if code == 430:
            number = words.get("h", float(tool))
            if number != int(number) or number < 0:
                raise self._where.error(f"G43 H{number:g}: H must be a non-negative integer")
            entry = self.entry(int(number), "G43 applies a zero length offset")
            return [entry.x_offset_mm, 0.0, entry.length_mm]
        if code == 431:
            return [
                words.get("x", 0.0) * factor,
                words.get("y", 0.0) * factor,
                words.get("z", 0.0) * factor,
            ]
        extra = self.table.get(int(words.get("h", -1.0)))
        if extra is None:
            raise self._where.error("G43.2 needs H<tool> with a tool in the tool table")
        return [current[0] + extra.x_offset_mm, current[1], current[2] + extra.length_mm]

    def set_entry(
        self,
        l_word: int,
        number: int,
        words: dict[str, float],
        factor: float,
        position: Sequence[float],
        origin: Sequence[float],
        g92: Sequence[float],
    ) -> None:
        """G10 L1 (set tool ``number``'s Z length, X offset, R radius from the words),
        L10 or L11 (set them so that the machine ``position`` (mm) reads the Z/X words in
        the frame of ``origin`` and ``g92`` (mm): the current system and G92 offset for L10,
        G59.3 and no offset for L11). Words in program units, ``factor`` mm each."""
        entry = self.table.get(number, ToolEntry(number))
        length, xoff, diameter = entry.length_mm, entry.x_offset_mm, entry.diameter_mm
        if "r" in words:
            diameter = 2.0 * words["r"] * factor
        if l_word == 1:
            if "z" in words:
                length = words["z"] * factor
            if "x" in words:
                xoff = words["x"] * factor
        else:
            if "z" in words:
                length = position[2] - origin[2] - g92[2] - words["z"] * factor
            if "x" in words:
                xoff = position[0] - origin[0] - g92[0] - words["x"] * factor
        self.table[number] = ToolEntry(number, length, xoff, diameter)
