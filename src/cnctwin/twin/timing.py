"""Cycle and stage timing of the twin runtime: percentiles over a bounded history, and the
overload detector that says when the cycle cannot keep its period."""

from __future__ import annotations

from collections import deque
from typing import Literal

import numpy as np

from cnctwin.errors import InputError

__all__ = ["OverloadMonitor", "TimingSeries"]


class TimingSeries:
    """Durations of one timed thing (a stage, a whole cycle), kept for percentiles.

    Parameters
    ----------
    capacity
        How many of the latest durations to keep (>= 1); the count covers all of them.
    """

    def __init__(self, capacity: int = 100_000) -> None:
        self._values: deque[float] = deque(maxlen=capacity)
        self.count = 0
        self.max_s = 0.0

    def add(self, duration_s: float) -> None:
        """Add one duration, s."""
        self._values.append(duration_s)
        self.count += 1
        self.max_s = max(self.max_s, duration_s)

    def percentile_ms(self, q: float) -> float:
        """The ``q``-th percentile (0-100) of the kept durations, ms; 0 when empty."""
        if not self._values:
            return 0.0
        return float(np.percentile(np.fromiter(self._values, float), q)) * 1e3

    def recent_percentile_ms(self, q: float, n: int = 400) -> float:
        """The ``q``-th percentile (0-100) of the last ``n`` durations, ms; 0 when empty."""
        if not self._values:
            return 0.0
        k = min(n, len(self._values))
        recent = [self._values[-i] for i in range(1, k + 1)]
        return float(np.percentile(recent, q)) * 1e3

    def summary(self) -> dict[str, float]:
        """``p50_ms``, ``p99_ms``, ``max_ms`` and ``count``."""
        return {
            "p50_ms": self.percentile_ms(50.0),
            "p99_ms": self.percentile_ms(99.0),
            "max_ms": self.max_s * 1e3,
            "count": float(self.count),
        }


class OverloadMonitor:
    """Whether the cycle keeps its period, from the overruns of the last cycles.

    The twin is *overloaded* from the cycle at which at least ``enter_fraction`` of the last
    ``window`` cycles overran (a full window is needed), until at most ``exit_fraction`` of
    them did. The two thresholds keep it from flapping. While overloaded, one more optional
    stage is shed every ``window`` cycles that the overrun fraction stays at or above
    ``enter_fraction`` (the level counts the stages shed; see docs/twin.md).

    Parameters
    ----------
    window
        Cycles the overrun fraction is taken over (>= 2).
    enter_fraction, exit_fraction
        Thresholds of the overrun fraction, 0 <= exit < enter <= 1.
    levels
        Most stages there are to shed (0: report only).
    """

    def __init__(
        self, window: int, enter_fraction: float, exit_fraction: float, levels: int = 0
    ) -> None:
        if not 0.0 <= exit_fraction < enter_fraction <= 1.0 or window < 2:
            raise InputError(
                f"overload window={window}, enter={enter_fraction}, exit={exit_fraction}; "
                "give window >= 2 and 0 <= exit < enter <= 1"
            )
        self.window = window
        self.enter_fraction = enter_fraction
        self.exit_fraction = exit_fraction
        self.levels = levels
        self.overloaded = False
        self.level = 0
        self.episodes = 0
        self.overloaded_cycles = 0
        self._overruns: deque[bool] = deque(maxlen=window)
        self._count = 0
        self._since_shed = 0

    @property
    def fraction(self) -> float:
        """Overrun fraction of the kept cycles (0 when none)."""
        return self._count / len(self._overruns) if self._overruns else 0.0

    def update(self, overran: bool) -> Literal["entered", "shed", "cleared"] | None:
        """Add one cycle; say what changed: overload ``"entered"`` (level 1 when there is
        something to shed), one more stage ``"shed"``, overload ``"cleared"``, or ``None``."""
        if len(self._overruns) == self.window and self._overruns[0]:
            self._count -= 1
        self._overruns.append(overran)
        self._count += int(overran)
        full = len(self._overruns) == self.window
        fraction = self.fraction
        if not self.overloaded:
            if full and fraction >= self.enter_fraction:
                self.overloaded = True
                self.episodes += 1
                self.overloaded_cycles += 1
                self.level = min(1, self.levels)
                self._since_shed = 0
                return "entered"
            return None
        self.overloaded_cycles += 1
        if fraction <= self.exit_fraction:
            self.overloaded = False
            self.level = 0
            return "cleared"
        self._since_shed += 1
        if self._since_shed >= self.window and fraction >= self.enter_fraction:
            self._since_shed = 0
            if self.level < self.levels:
                self.level += 1
                return "shed"
        return None
