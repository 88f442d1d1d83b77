"""The ``[[tools]]`` entries: cutter geometry and offsets of each tool."""

from __future__ import annotations

import math
from typing import Literal

from pydantic import Field, ValidationInfo, field_validator
from pydantic_core import PydanticCustomError

from cnctwin.config.base import Section
from cnctwin.nc.setup import ToolEntry

__all__ = ["ToolConfig"]


class ToolConfig(Section):
    """One cutting tool.

    Attributes
    ----------
    number
        Tool number (the T word), >= 0.
    kind
        ``"flat"`` end mill, ``"ball"`` nose or ``"bull"`` nose (corner radius).
    diameter_mm
        Cutter diameter in mm, > 0.
    corner_radius_mm
        Corner radius in mm: 0 for ``flat`` (the default), ``diameter_mm / 2`` for ``ball``
        (the default), and required, strictly between 0 and ``diameter_mm / 2``, for ``bull``.
    flutes
        Number of flutes (teeth), >= 1.
    helix_deg
        Helix angle in degrees, 0 <= helix_deg < 90.
    flute_length_mm
        Length of the fluted part in mm, if known.
    length_mm
        Tool length offset along Z in mm (applied by G43).
    x_offset_mm
        Lathe X offset in mm.
    orientation
        Lathe tool orientation 0-9 (LinuxCNC's Q: which imaginary tip point is programmed);
        0 for mill tools.
    """

    number: int = Field(ge=0)
    kind: Literal["flat", "ball", "bull"] = "flat"
    diameter_mm: float = Field(gt=0)
    corner_radius_mm: float | None = Field(default=None, ge=0, validate_default=True)
    flutes: int = Field(default=2, ge=1)
    helix_deg: float = Field(default=30.0, ge=0, lt=90)
    flute_length_mm: float | None = Field(default=None, gt=0)
    length_mm: float = 0.0
    x_offset_mm: float = 0.0
    orientation: int = Field(default=0, ge=0, le=9)

    @field_validator("corner_radius_mm")
    @classmethod
    def _corner_fits_kind(cls, value: float | None, info: ValidationInfo) -> float | None:
        kind = info.data.get("kind")
        diameter = info.data.get("diameter_mm")
        if kind is None or diameter is None:
            return value  # kind or diameter is itself invalid and reported
        half = diameter / 2.0
        if kind == "flat":
            if value:
                raise PydanticCustomError(
                    "corner_radius",
                    "must be 0 for kind 'flat' (use kind 'bull' for a corner radius)",
                )
            return 0.0
        if kind == "ball":
            if value is not None and not math.isclose(value, half, rel_tol=1e-9, abs_tol=1e-12):
                raise PydanticCustomError(
                    "corner_radius",
                    "must be diameter_mm/2 ({half}) for kind 'ball'",
                    {"half": half},
                )
            return half
        if value is None or not 0.0 < value < half:
            raise PydanticCustomError(
                "corner_radius",
                "must be given for kind 'bull', greater than 0 and less than "
                "diameter_mm/2 ({half})",
                {"half": half},
            )
        return value

    def tool_entry(self) -> ToolEntry:
        """The interpreter's view of this tool: number, offsets and diameter in mm, orientation."""
        return ToolEntry(
            number=self.number,
            length_mm=self.length_mm,
            x_offset_mm=self.x_offset_mm,
            diameter_mm=self.diameter_mm,
            orientation=self.orientation,
        )
