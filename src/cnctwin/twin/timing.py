"""Cycle and stage timing of the twin runtime: percentiles over a bounded history."""

from __future__ import annotations

from collections import deque

import numpy as np

__all__ = ["TimingSeries"]


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
