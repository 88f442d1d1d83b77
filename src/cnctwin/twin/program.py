"""The twin's own reading of the NC program: what each line means for the tool position.

A machine reports the position of its *controlled point* (the tool tip moved by the tool
length offset, as :mod:`cnctwin.virtual.machine` and real controls do); to cut its stock the
twin needs the tool tip. It interprets the program itself (:class:`cnctwin.nc.interpreter.
Interpreter`) and keeps, per program line, the tool and the tool offset in effect, so the
machine's ``program_line`` tells it which offset to take off the axes. Without a program the
twin assumes the length compensation of the tool in the spindle (G43 with its own length).
"""

from __future__ import annotations

import os
from array import array
from pathlib import Path

from cnctwin.config import MachiningConfig
from cnctwin.errors import NCError
from cnctwin.nc import Interpreter

__all__ = ["ProgramMap"]

Vec3 = tuple[float, float, float]


class ProgramMap:
    """Tool and tool offset (mm) by program line, or by tool without a program.

    Parameters
    ----------
    config
        Tools and machine set-up (the interpreter's).
    program
        The NC file the machine runs, or ``None``.
    text
        The program's text instead of a file (for the packaged demo).

    Raises
    ------
    cnctwin.errors.NCError
        On an error in the program (file, line and column named).
    """

    def __init__(
        self,
        config: MachiningConfig,
        program: str | os.PathLike[str] | None = None,
        *,
        text: str | None = None,
    ) -> None:
        self._by_tool: dict[int, Vec3] = {
            tool.number: (0.0, 0.0, tool.length_mm) for tool in config.tools
        }
        # Per line, 1 + the index in _states of the state of its last move (0: no move):
        # 4 bytes a line and one entry per distinct state, not a dict entry per line.
        self._state_of_line = array("I")
        self._states: list[tuple[int, Vec3]] = []
        if program is None and text is None:
            return
        interpreter = Interpreter(config.nc_setup())
        codes: dict[tuple[int, Vec3], int] = {}
        index = self._state_of_line
        try:
            segments = (
                interpreter.run_file(Path(program))
                if program is not None
                else interpreter.run_text(text or "", "program")
            )
            for segment in segments:
                state = segment.state
                dx, dy, dz = state.tool_offset_mm
                entry = (state.tool, (dx, dy, dz))
                code = codes.get(entry)
                if code is None:
                    self._states.append(entry)
                    code = codes[entry] = len(self._states)
                line = segment.line
                if line >= len(index):  # grown by doubling: lines come mostly in order
                    grow = max(line + 1, 2 * len(index)) - len(index)
                    index.frombytes(bytes(index.itemsize * grow))
                index[line] = code
        except NCError as err:
            if program is not None and err.file == "<string>":
                raise NCError(err.message, str(program), err.line, err.column) from None
            raise

    def offset_mm(self, line: int, tool: int) -> Vec3:
        """Tool offset in effect at ``line`` with ``tool`` in the spindle, mm.

        The program's offset for that line when it is known and its tool matches; otherwise
        the tool's configured length along Z (G43 assumed).
        """
        index = self._state_of_line
        code = index[line] if 0 <= line < len(index) else 0
        if code:
            known_tool, offset = self._states[code - 1]
            if known_tool == tool:
                return offset
        return self._by_tool.get(tool, (0.0, 0.0, 0.0))
