"""What the interpreter needs to know about the machine before it reads a program.

This is a plain, validated-elsewhere description (the TOML configuration in
:mod:`cnctwin.config` builds one with :meth:`cnctwin.config.MachiningConfig.nc_setup`).
Lengths are in mm.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from cnctwin.nc.limits import MAX_PROGRAM_BYTES, MAX_REPEATED_LINES, MAX_SEGMENTS
from cnctwin.nc.segments import Vec3

__all__ = ["DEFAULT_RAPID_MM_MIN", "NCSetup", "ToolEntry"]

#: Rapid traverse rate in mm/min of a machine that is not configured (the default of the
#: configuration's ``[machine] rapid_mm_min``).
DEFAULT_RAPID_MM_MIN = 10_000.0


@dataclass(frozen=True, slots=True)
class ToolEntry:
    """One tool-table entry.

    Attributes
    ----------
    number
        Tool number (T word), >= 0.
    length_mm
        Tool length offset along Z in mm, applied by G43 (H word, default the tool's own).
    x_offset_mm
        Lathe X offset in mm (radius value), applied by G43 / T0101-style offsets.
    diameter_mm
        Cutter diameter in mm; its half is the cutter radius compensation (D word).
    orientation
        Lathe tool orientation 0-9 (LinuxCNC's Q): which imaginary tip point is
        programmed; 0 for mill tools (the cutter's centre is compensated).
    """

    number: int
    length_mm: float = 0.0
    x_offset_mm: float = 0.0
    diameter_mm: float = 0.0
    orientation: int = 0


@dataclass(frozen=True, slots=True)
class NCSetup:
    """Machine set-up seen by the interpreter.

    Attributes
    ----------
    tools
        Tool table by tool number.
    lathe
        True for a lathe (XZ plane default G18, diameter mode G7 available, Fanuc-lathe
        meanings of G98/G99 as feed modes and G50 as spindle clamp).
    work_offsets_mm
        Initial work offsets by coordinate system number 1 (G54) to 9 (G59.3), in mm.
    g28_home_mm, g30_home_mm
        Machine positions of the G28 and G30 reference points in mm.
    initial_position_mm
        Machine position of the controlled point when the program starts, in mm.
    max_spindle_rpm
        Highest spindle speed of the machine in rpm; limits constant surface speed (G96).
    tool_change_on_t
        A T word loads the tool at once, without M6 (grbl, CAMotics).
    max_segments
        Most motion segments one program may produce (work guard; see ``docs/nc.md``).
    max_program_bytes
        Largest program file read, bytes.
    max_repeated_lines
        Most lines O-word loops and subroutine calls may execute again.
    """

    tools: dict[int, ToolEntry] = field(default_factory=dict)
    lathe: bool = False
    work_offsets_mm: dict[int, Vec3] = field(default_factory=dict)
    g28_home_mm: Vec3 = (0.0, 0.0, 0.0)
    g30_home_mm: Vec3 = (0.0, 0.0, 0.0)
    initial_position_mm: Vec3 = (0.0, 0.0, 0.0)
    max_spindle_rpm: float = math.inf
    tool_change_on_t: bool = False
    max_segments: int = MAX_SEGMENTS
    max_program_bytes: int = MAX_PROGRAM_BYTES
    max_repeated_lines: int = MAX_REPEATED_LINES
