"""What flows through one twin cycle: the state every stage reads and enriches."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["CycleState", "TwinEvent"]


@dataclass(frozen=True, slots=True)
class TwinEvent:
    """Something the runtime noticed (connection lost, restored, anomaly, program end).

    Attributes
    ----------
    kind
        Short machine-readable kind, e.g. ``"connection_lost"``.
    message
        One line for people.
    t_s
        ``time.monotonic()`` when it happened, s.
    data
        Figures that go with it (units in the keys).
    """

    kind: str
    message: str
    t_s: float
    data: dict[str, Any] = field(default_factory=dict)


@dataclass(slots=True)
class CycleState:
    """The state of one cycle, built up stage by stage (docs/twin.md).

    Attributes
    ----------
    index
        Cycle number from 0.
    deadline_s
        Scheduled start of the cycle, ``time.monotonic()`` s.
    time_s
        The twin's clock for rules, cooldowns and rate limits, s: ``time.monotonic()`` at the
        cycle's start in real time; ``index * cycle_s`` when cycles run back to back
        (lockstep tests), so hold times and cooldowns mean the same machine time.
    connected
        Whether the read of this cycle reached the machine.
    received_s
        When the reading arrived, monotonic s (NaN without a reading).
    new_sample
        The reading is a new, current sample (:mod:`cnctwin.twin.freshness`). Without one
        the cycle computes nothing from it and records no frame.
    stale
        The reading is older than ``[twin] max_sample_age_s``: the machine counts as lost.
    sample_age_s
        Age of the reading's newest value, s (NaN without a reading).
    last_sample_s
        Receive time of the last new, current sample, monotonic s (NaN before the first):
        where a gap in the machine's data starts.
    path_break
        The position moved where it could not have moved continuously and the twin takes
        it: the cut starts a new path there (no material removed along the jump).
    measured
        Signals read from the machine, canonical names (:data:`cnctwin.thread.SIGNALS`);
        invalid values are left out.
    rejected
        Signals of the reading that are invalid for this sample (garbage, out of the
        machine's range, an implausible jump), name -> reason.
    position_mm
        The twin's tool tip, machine frame, mm (None before the first reading).
    tool
        Tool number in the spindle (0: none).
    line
        Program line executing.
    dt_machine_s
        Machine time since the previous cycle's reading, s.
    engagement
        The dexel engagement of this cycle's cut (:class:`cnctwin.geometry.Engagement`), or None.
    filtered
        Measured signals after their filters.
    features
        Windowed features, ``"<signal>_<feature>"`` -> value.
    predicted
        Predictions of the physics and models (units in the names).
    commands
        Commands the rules asked for this cycle (objects of :mod:`cnctwin.control`).
    decisions
        Decisions taken this cycle, each with its reason.
    events
        Events of this cycle.
    """

    index: int
    deadline_s: float
    time_s: float = 0.0
    connected: bool = False
    received_s: float = float("nan")
    new_sample: bool = False
    stale: bool = False
    sample_age_s: float = float("nan")
    last_sample_s: float = float("nan")
    path_break: bool = False
    measured: dict[str, float] = field(default_factory=dict)
    rejected: dict[str, str] = field(default_factory=dict)
    position_mm: NDArray[np.float64] | None = None
    tool: int = 0
    line: int = 0
    dt_machine_s: float = 0.0
    engagement: Any = None
    filtered: dict[str, float] = field(default_factory=dict)
    features: dict[str, float] = field(default_factory=dict)
    predicted: dict[str, float] = field(default_factory=dict)
    commands: list[Any] = field(default_factory=list)
    decisions: list[Any] = field(default_factory=list)
    events: list[TwinEvent] = field(default_factory=list)

    def signals(self) -> dict[str, float]:
        """Every named value a rule may test: measured, filtered, features, predictions.

        Later sources override earlier ones on a clash; a filtered signal is named
        ``filtered_<signal>``. Every name is an identifier, as rule expressions need.
        """
        values = dict(self.measured)
        values.update({f"filtered_{k}": v for k, v in self.filtered.items()})
        values.update(self.features)
        values.update(self.predicted)
        return values

    def value(self, name: str) -> float:
        """The value :meth:`signals` would give ``name`` (same precedence), without building
        the whole mapping; NaN when the twin has none this cycle."""
        for source in (self.predicted, self.features):
            if name in source:
                return source[name]
        if name.startswith("filtered_") and name[9:] in self.filtered:
            return self.filtered[name[9:]]
        return self.measured.get(name, math.nan)
