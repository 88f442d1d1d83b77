"""The ``[simulation]`` section: resolution of the cut simulation."""

from __future__ import annotations

from pydantic import Field

from cnctwin.config.base import Section

__all__ = ["SimulationConfig"]


class SimulationConfig(Section):
    """How finely the cut is simulated (``cnctwin simulate``).

    Attributes
    ----------
    density_per_mm
        Dexels per mm of the tri-dexel stock, > 0 (Heide 2025's optimum: 10).
    cycle_ms
        Cycle time between two tool positions, ms, > 0 (the twin's cycle: 12.5).
    """

    density_per_mm: float = Field(default=10.0, gt=0, le=100)
    cycle_ms: float = Field(default=12.5, gt=0, le=1000)
