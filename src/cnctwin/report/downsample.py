"""Min/max downsampling of a time series per pixel bucket, for plots of long records.

A window ``[t0, t1]`` is split into ``buckets`` equal time buckets; each bucket that holds
samples gives two points, its smallest and its largest value, at the times they occurred, in
time order. Drawn as a line, the result covers exactly the vertical extent the full series
covers in each bucket (one bucket per pixel column), so no spike is lost however far out the
view is zoomed. A window holding at most ``2 * buckets`` samples comes back whole.

NaN (a signal invalid or not recorded at an instant) is kept as a gap: a bucket whose
samples are all NaN gives one NaN point at its first sample's time, so a line breaks there.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from cnctwin.errors import InputError

__all__ = ["MAX_BUCKETS", "Downsampled", "minmax_buckets"]

#: Most buckets one call may ask for (a very wide screen has ~8000 pixel columns).
MAX_BUCKETS = 20_000


@dataclass(frozen=True, slots=True)
class Downsampled:
    """A window of a series after :func:`minmax_buckets`.

    Attributes
    ----------
    t, y
        The points, in time order: time in the series' unit (s for the historian), value in
        the signal's unit; NaN in ``y`` marks a gap.
    samples
        How many samples of the full series lie in the window.
    raw
        True when every sample in the window is returned (no bucketing was needed).
    """

    t: NDArray[np.float64]
    y: NDArray[np.float64]
    samples: int
    raw: bool


def minmax_buckets(t: ArrayLike, y: ArrayLike, t0: float, t1: float, buckets: int) -> Downsampled:
    """The min and max of ``y`` per time bucket of ``[t0, t1]``.

    Parameters
    ----------
    t
        Sample times, non-decreasing (s).
    y
        Values at those times, same length (any unit; NaN for a missing value).
    t0, t1
        The window, ``t0 <= t1`` (same unit as ``t``).
    buckets
        Number of buckets, ``1 <= buckets <= MAX_BUCKETS`` (the plot's width in pixels).

    Returns
    -------
    Downsampled
        At most ``2 * buckets`` points.

    Raises
    ------
    InputError
        On arrays of different lengths, a window that is not finite and ordered, or a bucket
        count out of range.
    """
    times = np.asarray(t, dtype=np.float64)
    values = np.asarray(y, dtype=np.float64)
    if times.shape != values.shape or times.ndim != 1:
        raise InputError(f"t and y must be 1-D of one length; got {times.shape} and {values.shape}")
    if not (np.isfinite(t0) and np.isfinite(t1) and t0 <= t1):
        raise InputError(f"window [{t0}, {t1}]: give finite t0 <= t1")
    if not 1 <= buckets <= MAX_BUCKETS:
        raise InputError(f"buckets={buckets}; give 1 <= buckets <= {MAX_BUCKETS}")
    lo = int(np.searchsorted(times, t0, side="left"))
    hi = int(np.searchsorted(times, t1, side="right"))
    window_t, window_y = times[lo:hi], values[lo:hi]
    n = int(window_t.size)
    if n <= 2 * buckets:
        return Downsampled(window_t.copy(), window_y.copy(), n, True)
    scale = buckets / (t1 - t0) if t1 > t0 else 0.0  # t0 == t1: every sample at one time
    index = np.minimum(((window_t - t0) * scale).astype(np.int64), buckets - 1)
    finite = np.isfinite(window_y)
    # Within each bucket, order the samples by value, NaN last (lexsort is stable, so an
    # all-NaN bucket keeps its samples in time order): the first is the minimum, the last
    # finite one the maximum.
    order = np.lexsort((np.where(finite, window_y, np.inf), ~finite, index))
    sorted_bucket = index[order]
    starts = np.flatnonzero(np.r_[True, sorted_bucket[1:] != sorted_bucket[:-1]])
    n_finite = np.add.reduceat(finite[order].astype(np.int64), starts)
    has = n_finite > 0
    first = order[starts[has]]
    last = order[starts[has] + n_finite[has] - 1]
    gaps = order[starts[~has]]
    keep = np.unique(np.concatenate([first, last, gaps]))
    return Downsampled(window_t[keep], window_y[keep], n, False)
