"""The common base of every configuration section."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict

__all__ = ["Section", "Vec3Mm"]

#: A point or vector (x, y, z) in mm, written in TOML as ``[x, y, z]``.
Vec3Mm = tuple[float, float, float]


class Section(BaseModel):
    """A configuration table: unknown keys, NaN and infinities are errors; values are frozen."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)
