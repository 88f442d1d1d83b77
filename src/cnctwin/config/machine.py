"""The ``[machine]`` section: kind, rapid rate, axis travel, reference points and work offsets."""

from __future__ import annotations

from typing import Literal

from pydantic import ConfigDict, Field, ValidationInfo, field_validator
from pydantic_core import PydanticCustomError

from cnctwin.config.base import CoordinateMm, Section, Vec3Mm
from cnctwin.config.spindle import SpindleConfig
from cnctwin.nc import DEFAULT_RAPID_MM_MIN

__all__ = [
    "MAX_FEED_MM_MIN",
    "MAX_SPINDLE_RPM",
    "AxesConfig",
    "AxisConfig",
    "MachineConfig",
    "WorkOffsets",
]

#: Fastest feed or rapid rate a configuration accepts, mm/min (1 km/min).
MAX_FEED_MM_MIN = 1e6
#: Fastest spindle speed a configuration accepts, rpm (high-speed air-bearing spindles reach
#: about 200,000 rpm).
MAX_SPINDLE_RPM = 200_000.0


class AxisConfig(Section):
    """Travel and dynamic limits of one linear axis.

    Attributes
    ----------
    min_mm, max_mm
        Travel limits in machine coordinates, mm, within +-100,000 mm; ``max_mm`` must exceed
        ``min_mm``.
    max_velocity_mm_min
        Maximum axis velocity in mm/min, 1 to 1,000,000 (1 km/min; linear-motor axes reach
        about 200 m/min; below 1 mm/min a program's moves would take days per millimetre).
    max_accel_mm_s2
        Maximum axis acceleration in mm/s^2, 1 to 1,000,000 (about 100 g).
    """

    min_mm: CoordinateMm = -500.0
    max_mm: CoordinateMm = Field(default=500.0, validate_default=True)
    max_velocity_mm_min: float = Field(default=10_000.0, ge=1, le=MAX_FEED_MM_MIN)
    max_accel_mm_s2: float = Field(default=1_000.0, ge=1, le=1e6)

    @field_validator("max_mm")
    @classmethod
    def _above_min(cls, value: float, info: ValidationInfo) -> float:
        low = info.data.get("min_mm")
        if low is not None and value <= low:
            raise PydanticCustomError(
                "travel_order", "must be greater than min_mm ({min_mm})", {"min_mm": low}
            )
        return value


class AxesConfig(Section):
    """The linear axes X, Y and Z."""

    x: AxisConfig = Field(default_factory=AxisConfig)
    y: AxisConfig = Field(default_factory=AxisConfig)
    z: AxisConfig = Field(default_factory=AxisConfig)


class WorkOffsets(Section):
    """Initial work offsets (program origins in machine coordinates, mm), G54 to G59.3.

    Keys are the G-codes in lower case (``g54``; quote the dotted ones: ``"g59.1"``);
    a coordinate system that is not given starts at the machine origin.
    """

    model_config = ConfigDict(populate_by_name=False)

    g54: Vec3Mm | None = None
    g55: Vec3Mm | None = None
    g56: Vec3Mm | None = None
    g57: Vec3Mm | None = None
    g58: Vec3Mm | None = None
    g59: Vec3Mm | None = None
    g59_1: Vec3Mm | None = Field(default=None, alias="g59.1")
    g59_2: Vec3Mm | None = Field(default=None, alias="g59.2")
    g59_3: Vec3Mm | None = Field(default=None, alias="g59.3")

    def by_system(self) -> dict[int, Vec3Mm]:
        """The offsets that are set, by coordinate system number (1 = G54 ... 9 = G59.3), in mm."""
        offsets = (getattr(self, name) for name in type(self).model_fields)
        return {number: value for number, value in enumerate(offsets, 1) if value is not None}


class MachineConfig(Section):
    """The machine tool.

    Attributes
    ----------
    name
        A name for reports.
    kind
        ``"mill"`` or ``"lathe"`` (a lathe interprets programs with lathe conventions).
    rapid_mm_min
        Rapid traverse rate in mm/min, used for rapid-move times; 1 to 1,000,000.
    max_spindle_rpm
        Highest spindle speed in rpm, which limits constant surface speed (G96), 1 to
        200,000; ``None`` for no limit.
    axes
        Limits of the X, Y and Z axes.
    g28_home_mm, g30_home_mm
        Machine positions of the G28 and G30 reference points in mm.
    work_offsets
        Initial work offsets G54 to G59.3 in mm.
    tool_change_on_t
        A T word loads the tool at once, without M6 (grbl and CAMotics do this).
    spindle
        The spindle drive (preset, optional motor/controller parameters, S1 rating).
    """

    name: str = "cnctwin machine"
    kind: Literal["mill", "lathe"] = "mill"
    rapid_mm_min: float = Field(default=DEFAULT_RAPID_MM_MIN, ge=1, le=MAX_FEED_MM_MIN)
    max_spindle_rpm: float | None = Field(default=None, ge=1, le=MAX_SPINDLE_RPM)
    axes: AxesConfig = Field(default_factory=AxesConfig)
    g28_home_mm: Vec3Mm = (0.0, 0.0, 0.0)
    g30_home_mm: Vec3Mm = (0.0, 0.0, 0.0)
    work_offsets: WorkOffsets = Field(default_factory=WorkOffsets)
    tool_change_on_t: bool = False
    spindle: SpindleConfig = Field(default_factory=SpindleConfig)
