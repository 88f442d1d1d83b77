"""Numba kernels of the zero-order approximation (see :mod:`cnctwin.dynamics.stability`)."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def tracked_eigenvalues(p: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """Eigenvalues of ``(F, 2, 2)`` complex matrices, ordered to follow each branch along F.

    The two roots of ``mu^2 - tr mu + det = 0`` at each sample are assigned to the branches of
    the previous sample by the nearer pairing, so that a lobe never jumps between branches.
    """
    count = p.shape[0]
    out = np.empty((count, 2), dtype=np.complex128)
    for f in range(count):
        trace = p[f, 0, 0] + p[f, 1, 1]
        det = p[f, 0, 0] * p[f, 1, 1] - p[f, 0, 1] * p[f, 1, 0]
        root = np.sqrt(trace * trace - 4.0 * det)
        first = 0.5 * (trace + root)
        second = 0.5 * (trace - root)
        if f > 0:
            keep = abs(first - out[f - 1, 0]) + abs(second - out[f - 1, 1])
            swap = abs(first - out[f - 1, 1]) + abs(second - out[f - 1, 0])
            if swap < keep:
                first, second = second, first
        out[f, 0] = first
        out[f, 1] = second
    return out


@njit(cache=True)
def envelope(
    grid: np.ndarray,
    frequency: np.ndarray,
    depth: np.ndarray,
    phase: np.ndarray,
    lobes: int,
    speed_per_rate: float,
) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover - compiled
    """Lowest lobe over a spindle-speed grid.

    Parameters
    ----------
    grid
        Increasing spindle speeds in rad/s.
    frequency
        ``(F,)`` chatter frequencies in rad/s.
    depth
        ``(F, E)`` limiting depth in m per frequency and eigenvalue branch, NaN where none.
    phase
        ``(F, E)`` phase ``epsilon`` in rad.
    lobes
        Lobes k = 0 .. lobes - 1.
    speed_per_rate
        ``Omega * tau``: 2 pi / N for milling, 2 pi for turning; lobe k of frequency w lies at
        ``Omega = speed_per_rate * w / (epsilon + 2 pi k)``.

    Returns
    -------
    tuple of numpy.ndarray
        Lowest depth in m (inf where no lobe covers the speed) and its chatter frequency in
        rad/s (NaN there), both shaped like ``grid``; consecutive samples of a branch are
        joined by straight lines in the (speed, depth) plane.
    """
    best = np.full(grid.size, np.inf)
    chatter = np.full(grid.size, np.nan)
    two_pi = 2.0 * np.pi
    for e in range(depth.shape[1]):
        for k in range(lobes):
            for f in range(frequency.size - 1):
                a1 = depth[f, e]
                a2 = depth[f + 1, e]
                if not (np.isfinite(a1) and np.isfinite(a2)):
                    continue
                s1 = speed_per_rate * frequency[f] / (phase[f, e] + two_pi * k)
                s2 = speed_per_rate * frequency[f + 1] / (phase[f + 1, e] + two_pi * k)
                low = min(s1, s2)
                high = max(s1, s2)
                start = np.searchsorted(grid, low)
                for g in range(start, grid.size):
                    speed = grid[g]
                    if speed > high:
                        break
                    t = 0.0 if high == low else (speed - s1) / (s2 - s1)
                    value = a1 + t * (a2 - a1)
                    if value < best[g]:
                        best[g] = value
                        chatter[g] = frequency[f] + t * (frequency[f + 1] - frequency[f])
    return best, chatter
