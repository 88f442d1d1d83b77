"""The ``[material]`` section: the workpiece material."""

from __future__ import annotations

from pydantic import Field

from cnctwin.config.base import Section

__all__ = ["MaterialConfig"]


class MaterialConfig(Section):
    """Workpiece material.

    Attributes
    ----------
    name
        Material name, e.g. ``"aluminium 7075-T6"``.
    density_kg_m3
        Density in kg/m^3, if known: 10 (foams) to 25,000 (osmium is 22,590).
    hardness_hb
        Brinell hardness (HB), if known: > 0 and <= 1000 (hardened steels are below 700).
    """

    name: str = "unspecified"
    density_kg_m3: float | None = Field(default=None, ge=10, le=25_000)
    hardness_hb: float | None = Field(default=None, gt=0, le=1000)
