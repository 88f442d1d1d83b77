"""The root of a cnctwin configuration file and its translation for the NC interpreter."""

from __future__ import annotations

import logging
import math
from pathlib import Path
from typing import Literal

from pydantic import Field, ValidationInfo, field_validator
from pydantic_core import PydanticCustomError

from cnctwin.config.base import Section, resolve_file
from cnctwin.config.machine import MachineConfig
from cnctwin.config.material import MaterialConfig
from cnctwin.config.simulation import SimulationConfig
from cnctwin.config.stock import BoxStock
from cnctwin.config.tools import ToolConfig
from cnctwin.nc import NCSetup, read_tool_table

__all__ = ["MachiningConfig"]

logger = logging.getLogger(__name__)


class MachiningConfig(Section):
    """A whole configuration; every section has defaults, so an empty file is valid.

    Attributes
    ----------
    machine
        The machine tool.
    tools
        Tools given in the file (``[[tools]]``).
    tool_table
        A LinuxCNC tool table file; a relative path is relative to the configuration file
        (to the working directory for a configuration built in code).
    tool_table_units
        Units of the tool table's lengths, ``"mm"`` or ``"inch"``.
    stock
        The raw workpiece.
    material
        The workpiece material.
    simulation
        Resolution of the cut simulation (dexel density, cycle time).
    """

    machine: MachineConfig = Field(default_factory=MachineConfig)
    tools: list[ToolConfig] = Field(default_factory=list)
    tool_table: Path | None = None
    tool_table_units: Literal["mm", "inch"] = "mm"
    stock: BoxStock = Field(default_factory=BoxStock)
    material: MaterialConfig = Field(default_factory=MaterialConfig)
    simulation: SimulationConfig = Field(default_factory=SimulationConfig)

    @field_validator("tools")
    @classmethod
    def _unique_numbers(cls, tools: list[ToolConfig]) -> list[ToolConfig]:
        first: dict[int, int] = {}
        for index, tool in enumerate(tools):
            if tool.number in first:
                raise PydanticCustomError(
                    "duplicate_tool",
                    "tool number {number} is given twice, in tools[{a}] and tools[{b}]",
                    {"number": tool.number, "a": first[tool.number], "b": index},
                )
            first[tool.number] = index
        return tools

    @field_validator("tool_table")
    @classmethod
    def _resolve_table(cls, value: Path | None, info: ValidationInfo) -> Path | None:
        return resolve_file(value, info)

    def nc_setup(self) -> NCSetup:
        """The interpreter's set-up: tools, lathe flag, work offsets, reference points, spindle.

        Tools come from ``tool_table`` first; a ``[[tools]]`` entry with the same number
        replaces the table's entry.

        Returns
        -------
        NCSetup
            Lengths in mm.

        Raises
        ------
        cnctwin.errors.DataError
            If the tool table cannot be read or has a bad line.
        """
        tools = (
            read_tool_table(self.tool_table, units=self.tool_table_units)
            if self.tool_table is not None
            else {}
        )
        for tool in self.tools:
            if tool.number in tools:
                logger.debug("tool %d from [[tools]] replaces the tool table's entry", tool.number)
            tools[tool.number] = tool.tool_entry()
        machine = self.machine
        return NCSetup(
            tools=tools,
            lathe=machine.kind == "lathe",
            work_offsets_mm=machine.work_offsets.by_system(),
            g28_home_mm=machine.g28_home_mm,
            g30_home_mm=machine.g30_home_mm,
            max_spindle_rpm=(
                machine.max_spindle_rpm if machine.max_spindle_rpm is not None else math.inf
            ),
            tool_change_on_t=machine.tool_change_on_t,
        )
