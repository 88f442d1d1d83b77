"""Two short runs recorded through the historian's API, for the run browser's tests."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

#: Run 1: 20,000 instants of 12.5 ms (250 s); force_x_n a sine with a spike and a NaN gap.
N1, DT_S, SPIKE, GAP = 20_000, 0.0125, 12_345, range(5_000, 5_010)


def force(i: np.ndarray | int) -> np.ndarray:
    """Run 1's force_x_n at instant i, N (before the spike and the gap)."""
    return 100.0 + 20.0 * np.sin(np.asarray(i) * 0.01)


def record(path: Path) -> tuple[int, int]:
    """Record run 1 (finished, with an event and a decision) and run 2 (stopped)."""
    from cnctwin.store import Historian

    with Historian.open(path) as h:
        first = h.start_run({"program": "pocket.nc", "endpoint": "opc.tcp://127.0.0.1:4840"})
        for i in range(N1):
            value = float(force(i))
            if i == SPIKE:
                value = 900.0
            if i in GAP:
                value = math.nan
            h.record_samples(first, i * DT_S, {"force_x_n": value, "spindle_rpm": 8000.0})
            if i % 10 == 0:
                h.record_prediction(first, i * DT_S, {"force_x_n": 101.0})
        h.record_event(first, 100.0, "anomaly", "force above the band", {"force_n": 900.0})
        h.record_decision(first, 100.0, "band", "stop", 1.0, "force 900 N > 150 N", True, 1.0)
        h.end_run(first, "finished", {"cycles": N1})
        second = h.start_run({"program": "slot.nc", "machine": "mill-2"})
        for i in range(400):
            h.record_samples(second, i * DT_S, {"force_x_n": 50.0 + i, "spindle_rpm": 6000.0})
        h.end_run(second, "stopped", {})
    return first, second


def expected_force() -> np.ndarray:
    """Run 1's force_x_n as recorded."""
    y = force(np.arange(N1)).astype(float)
    y[SPIKE] = 900.0
    y[list(GAP)] = np.nan
    return y
