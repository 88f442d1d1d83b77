"""The ``[simulation]`` section: resolution of the cut simulation."""

from __future__ import annotations

from pydantic import Field

from cnctwin.config.base import Section

__all__ = [
    "MAX_CYCLE_MS",
    "MAX_DENSITY_PER_MM",
    "MIN_CYCLE_MS",
    "MIN_DENSITY_PER_MM",
    "SimulationConfig",
]

#: Range of the dexel density, 1/mm: a pitch of 10 mm to 10 um (finer than any tool's
#: cusp of interest, coarser than float32 resolution on a metre-sized stock).
MIN_DENSITY_PER_MM = 0.1
MAX_DENSITY_PER_MM = 100.0
#: Range of the simulation's cycle time, ms: 0.1 ms (faster than any CNC's interpolation
#: cycle, 0.25-1 ms) to 1 s.
MIN_CYCLE_MS = 0.1
MAX_CYCLE_MS = 1000.0


class SimulationConfig(Section):
    """How finely the cut is simulated (``cnctwin simulate``).

    Attributes
    ----------
    density_per_mm
        Dexels per mm of the tri-dexel stock, 0.1 to 100 (a pitch of 10 mm to 10 um; Heide
        2025's optimum: 10). The stock's rays must also fit the work limit
        (:mod:`cnctwin.memory`).
    cycle_ms
        Cycle time between two tool positions, ms, 0.1 to 1000 (the twin's cycle: 12.5). The
        program's positions must also fit the work limit.
    """

    density_per_mm: float = Field(default=10.0, ge=MIN_DENSITY_PER_MM, le=MAX_DENSITY_PER_MM)
    cycle_ms: float = Field(default=12.5, ge=MIN_CYCLE_MS, le=MAX_CYCLE_MS)
