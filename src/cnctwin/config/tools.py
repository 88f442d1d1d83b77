"""The ``[[tools]]`` entries: cutter geometry and offsets of each tool."""

from __future__ import annotations

import math
from typing import Literal

from pydantic import Field, ValidationInfo, field_validator
from pydantic_core import PydanticCustomError

from cnctwin.config.base import Section
from cnctwin.nc import ToolEntry

__all__ = [
    "CutterKind",
    "DEFAULT_POINT_ANGLE_DEG",
    "MAX_FLUTES",
    "MAX_TOOL_DIAMETER_MM",
    "MAX_TOOL_LENGTH_MM",
    "MIN_TOOL_DIAMETER_MM",
    "ToolConfig",
]

#: Smallest and largest cutter diameter, mm: 10 um micro end mills to 1 m face mills.
MIN_TOOL_DIAMETER_MM = 0.01
MAX_TOOL_DIAMETER_MM = 1000.0
#: Most flutes (teeth) of a cutter: above the densest face mills; it bounds per-tooth arrays.
MAX_FLUTES = 100
#: Largest fluted length and tool length offset magnitude, mm (long drills, extensions).
MAX_TOOL_LENGTH_MM = 2000.0

#: Cutter shapes: ``"flat"`` end mill, ``"ball"`` nose, ``"bull"`` nose (with a corner radius),
#: ``"conical"`` (a V-bit, pointed), ``"snub"`` nose (a cone with a flat tip), ``"drill"`` (a twist
#: drill: a cone of its point angle, cutting along its axis) or ``"tap"`` (a cutting tap of a
#: thread pitch). The one list of kinds, for the configuration and for
#: :class:`cnctwin.geometry.Cutter`.
CutterKind = Literal["flat", "ball", "bull", "conical", "snub", "drill", "tap"]
_CONES = ("conical", "snub")
#: Point angle of a drill when the configuration names none, degrees (the common twist drill).
DEFAULT_POINT_ANGLE_DEG = 118.0


def _only_for(error: str, kinds: tuple[str, ...], kind: str) -> PydanticCustomError:
    """The error for a key given on a tool kind it does not belong to (``kinds`` hold it)."""
    named = [f"'{k}'" for k in kinds]
    allowed = named[0] if len(named) == 1 else f"{', '.join(named[:-1])} or {named[-1]}"
    return PydanticCustomError(
        error,
        "is only for kind {allowed}; remove it for kind '{kind}'",
        {"allowed": allowed, "kind": kind},
    )


class ToolConfig(Section):
    """One cutting tool.

    Attributes
    ----------
    number
        Tool number (the T word), 0 to 99,999.
    kind
        ``"flat"`` end mill, ``"ball"`` nose, ``"bull"`` nose (corner radius), ``"conical"``
        (V-bit), ``"snub"`` nose (cone with a flat tip), ``"drill"`` (twist drill) or ``"tap"``
        (cutting tap): :data:`CutterKind`. A drill's or a tap's forces are those of
        :mod:`cnctwin.mechanics.drilling` (docs/drilling.md).
    diameter_mm
        Cutter diameter in mm, 0.01 to 1000.
    corner_radius_mm
        Corner radius in mm: 0 for ``flat``, ``conical``, ``snub``, ``drill`` and ``tap`` (the
        default),
        ``diameter_mm / 2`` for ``ball`` (the default), and required, strictly between 0 and
        ``diameter_mm / 2``, for ``bull``.
    tip_diameter_mm
        Diameter of a snub nose's flat tip in mm: required for ``snub``, strictly between 0 and
        ``diameter_mm``; 0 (the default) for every other kind.
    flutes
        Number of flutes (teeth), an integer 1 to 100; a drill's cutting lips (2 for a twist
        drill).
    helix_deg
        Helix angle in degrees, 0 to 89.
    flute_length_mm
        Length of the fluted part in mm, if known: 0.01 to 2000.
    tip_angle_deg
        Included angle of the cone of a ``conical`` or ``snub`` tool in degrees, in (0, 180)
        (90 for a common V-bit); none (the default): the cone spans the whole fluted length, as
        CAMotics models these tools. A ``drill``'s point angle, in (0, 180); none: 118
        (:data:`DEFAULT_POINT_ANGLE_DEG`). Not allowed for the other kinds.
    web_mm
        Width of a drill's chisel edge (the web at the point) in mm, 0 (the default: a split
        point or an indexable drill, no chisel edge) up to less than ``diameter_mm``; typically
        0.1 to 0.2 times the diameter for a conventional twist drill. Only for ``drill``.
    pitch_mm
        Thread pitch of a ``tap`` in mm, required for a tap, greater than 0 and less than
        ``diameter_mm / 2``; not allowed for the other kinds.
    length_mm
        Tool length offset along Z in mm (applied by G43), within +-2000.
    x_offset_mm
        Lathe X offset in mm, within +-2000.
    orientation
        Lathe tool orientation 0-9 (LinuxCNC's Q: which imaginary tip point is programmed);
        0 for mill tools.
    """

    number: int = Field(ge=0, le=99_999)
    kind: CutterKind = "flat"
    diameter_mm: float = Field(ge=MIN_TOOL_DIAMETER_MM, le=MAX_TOOL_DIAMETER_MM)
    corner_radius_mm: float | None = Field(default=None, ge=0, validate_default=True)
    tip_diameter_mm: float | None = Field(default=None, ge=0, validate_default=True)
    flutes: int = Field(default=2, ge=1, le=MAX_FLUTES)
    helix_deg: float = Field(default=30.0, ge=0, le=89)
    flute_length_mm: float | None = Field(default=None, ge=0.01, le=MAX_TOOL_LENGTH_MM)
    tip_angle_deg: float | None = Field(default=None, gt=0, lt=180, validate_default=True)
    web_mm: float = Field(default=0.0, ge=0)
    pitch_mm: float | None = Field(default=None, gt=0, validate_default=True)
    length_mm: float = Field(default=0.0, ge=-MAX_TOOL_LENGTH_MM, le=MAX_TOOL_LENGTH_MM)
    x_offset_mm: float = Field(default=0.0, ge=-MAX_TOOL_LENGTH_MM, le=MAX_TOOL_LENGTH_MM)
    orientation: int = Field(default=0, ge=0, le=9)

    @field_validator("corner_radius_mm")
    @classmethod
    def _corner_fits_kind(cls, value: float | None, info: ValidationInfo) -> float | None:
        kind = info.data.get("kind")
        diameter = info.data.get("diameter_mm")
        if kind is None or diameter is None:
            return value  # kind or diameter is itself invalid and reported
        half: float = diameter / 2.0
        if kind in ("flat", "drill", "tap") or kind in _CONES:
            if value:
                raise PydanticCustomError(
                    "corner_radius",
                    "must be 0 for kind '{kind}' (use kind 'bull' for a corner radius)",
                    {"kind": kind},
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

    @field_validator("tip_diameter_mm")
    @classmethod
    def _tip_fits_kind(cls, value: float | None, info: ValidationInfo) -> float | None:
        kind = info.data.get("kind")
        diameter = info.data.get("diameter_mm")
        if kind is None or diameter is None:
            return value  # kind or diameter is itself invalid and reported
        if kind != "snub":
            if value:
                raise PydanticCustomError(
                    "tip_diameter",
                    "must be 0 for kind '{kind}' (use kind 'snub' for a flat tip)",
                    {"kind": kind},
                )
            return 0.0
        if value is None or not 0.0 < value < diameter:
            raise PydanticCustomError(
                "tip_diameter",
                "must be given for kind 'snub', greater than 0 and less than "
                "diameter_mm ({diameter})",
                {"diameter": diameter},
            )
        return value

    @field_validator("tip_angle_deg")
    @classmethod
    def _angle_fits_kind(cls, value: float | None, info: ValidationInfo) -> float | None:
        kind = info.data.get("kind")
        if kind == "drill":
            return DEFAULT_POINT_ANGLE_DEG if value is None else value
        if value is not None and kind is not None and kind not in _CONES:
            raise _only_for("tip_angle", (*_CONES, "drill"), kind)
        return value

    @field_validator("web_mm")
    @classmethod
    def _web_fits_kind(cls, value: float, info: ValidationInfo) -> float:
        kind = info.data.get("kind")
        diameter = info.data.get("diameter_mm")
        if kind is None or diameter is None:
            return value  # kind or diameter is itself invalid and reported
        if kind != "drill" and value:
            raise _only_for("web", ("drill",), kind)
        if value >= diameter:
            raise PydanticCustomError(
                "web",
                "must be less than diameter_mm ({diameter}): the chisel edge lies inside the drill",
                {"diameter": diameter},
            )
        return value

    @field_validator("pitch_mm")
    @classmethod
    def _pitch_fits_kind(cls, value: float | None, info: ValidationInfo) -> float | None:
        kind = info.data.get("kind")
        diameter = info.data.get("diameter_mm")
        if kind is None or diameter is None:
            return value  # kind or diameter is itself invalid and reported
        if kind != "tap":
            if value is not None:
                raise _only_for("pitch", ("tap",), kind)
            return None
        if value is None or not value < 0.5 * diameter:
            raise PydanticCustomError(
                "pitch",
                "must be given for kind 'tap', greater than 0 and less than diameter_mm/2 "
                "({half}), e.g. 1.5 for an M10 tap",
                {"half": 0.5 * diameter},
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
