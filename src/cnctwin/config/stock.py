"""The ``[stock]`` section: the raw workpiece."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, ValidationInfo, field_validator
from pydantic_core import PydanticCustomError

from cnctwin.config.base import Section, Vec3Mm

__all__ = ["BoxStock"]


class BoxStock(Section):
    """An axis-aligned block of stock.

    Attributes
    ----------
    kind
        ``"box"``.
    min_mm, max_mm
        Opposite corners in machine coordinates, mm, within +-100,000; ``max_mm`` exceeds
        ``min_mm`` in x, y and z. The stock's dexel rays must fit the work limit
        (:mod:`cnctwin.memory`).
    """

    kind: Literal["box"] = "box"
    min_mm: Vec3Mm = (0.0, 0.0, -50.0)
    max_mm: Vec3Mm = Field(default=(100.0, 100.0, 0.0), validate_default=True)

    @field_validator("max_mm")
    @classmethod
    def _above_min(cls, value: Vec3Mm, info: ValidationInfo) -> Vec3Mm:
        low = info.data.get("min_mm")
        if low is not None:
            for axis, hi, lo in zip("xyz", value, low, strict=True):
                if hi <= lo:
                    raise PydanticCustomError(
                        "stock_order",
                        "{axis} must be greater than min_mm's {axis} ({lo})",
                        {"axis": axis, "lo": lo},
                    )
        return value
