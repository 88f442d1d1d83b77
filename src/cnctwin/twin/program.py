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
from collections.abc import Mapping
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
        self._by_line: dict[int, tuple[int, Vec3]] = {}
        if program is None and text is None:
            return
        interpreter = Interpreter(config.nc_setup())
        try:
            segments = (
                interpreter.run_file(Path(program))
                if program is not None
                else interpreter.run_text(text or "", "program")
            )
            for segment in segments:
                state = segment.state
                dx, dy, dz = state.tool_offset_mm
                self._by_line[segment.line] = (state.tool, (dx, dy, dz))
        except NCError as err:
            if program is not None and err.file == "<string>":
                raise NCError(err.message, str(program), err.line, err.column) from None
            raise

    @property
    def lines(self) -> Mapping[int, tuple[int, Vec3]]:
        """Line -> (tool, tool offset in mm) of every line that moves."""
        return self._by_line

    def offset_mm(self, line: int, tool: int) -> Vec3:
        """Tool offset in effect at ``line`` with ``tool`` in the spindle, mm.

        The program's offset for that line when it is known and its tool matches; otherwise
        the tool's configured length along Z (G43 assumed).
        """
        known = self._by_line.get(line)
        if known is not None and known[0] == tool:
            return known[1]
        return self._by_tool.get(tool, (0.0, 0.0, 0.0))
