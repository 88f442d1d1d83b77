"""A run's overview: per signal, the min and max of each of :data:`OVERVIEW_BUCKETS` equal
time buckets over the whole run, so a plot of a whole run needs no decoding of its frames.

The historian computes it when a run is closed (:meth:`Historian.end_run`), or, for a run
closed before overviews existed, the first time one is asked for, and stores it in
``hist_overview`` (docs/historian.md). A fine bucket keeps, for each signal, its number of
finite values, its smallest value with the time of the earliest instant holding it and its
largest value with the time of the latest instant holding it; per run and kind it keeps each
bucket's number of instants, its first instant's time (where a gap is drawn) and the range
of the ``seq`` of its instants, so a window of the run is read from those frames alone
(:meth:`RunOverview.seq_range`).

:meth:`RunOverview.envelope` merges whole fine buckets into ``buckets`` plot buckets (each
``OVERVIEW_BUCKETS / buckets`` fine buckets, give or take one): every plot bucket then gives
exactly what :func:`cnctwin.report.minmax_buckets` would give from the raw values for that
bucket's time span — its min and its max at the times they occurred, or one NaN point for a
bucket with instants but no finite value — so no spike is lost. Only the bucket edges differ
from equal division of the window: they fall on fine-bucket edges (at most 1/4096 of the run
away from the equal ones), and :attr:`Envelope.edges` says where they are.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["OVERVIEW_BUCKETS", "Envelope", "RunOverview", "compute_overview"]

#: Fine buckets of an overview (a plot of up to 4096 pixel columns is drawn from it).
OVERVIEW_BUCKETS = 4096

_F8 = np.dtype("<f8")
#: Arrays of one signal's fine buckets, in their stored order.
_SIGNAL_FIELDS = ("finite", "y_min", "t_min", "y_max", "t_max")


@dataclass(frozen=True, slots=True)
class Envelope:
    """A whole run's signal as min/max points per plot bucket.

    Attributes
    ----------
    t, y
        The points in time order: time s, value in the signal's unit (NaN marks a gap).
    edges
        The plot buckets' edges, s (``buckets + 1`` values from the run's first instant to
        its last).
    samples
        Instants of the run (of the signal's kind).
    """

    t: NDArray[np.float64]
    y: NDArray[np.float64]
    edges: NDArray[np.float64]
    samples: int


@dataclass(frozen=True, slots=True)
class RunOverview:
    """The overview of one kind (measured or predicted) of a run: see the module notes.

    Attributes
    ----------
    t_first, t_last
        Times of the run's first and last instant of this kind, s.
    frames
        Instants.
    count, first_t, seq_lo, seq_hi
        Per fine bucket: instants, the time of the first one (s; NaN when empty) and the
        smallest and largest ``seq`` among them (NaN when empty; float64, exact to 2**53).
    signals
        Per signal name: ``{"finite", "y_min", "t_min", "y_max", "t_max"}`` arrays per fine
        bucket (times s, values in the signal's unit; NaN where a bucket has no finite value).
    """

    t_first: float
    t_last: float
    frames: int
    count: NDArray[np.float64]
    first_t: NDArray[np.float64]
    seq_lo: NDArray[np.float64]
    seq_hi: NDArray[np.float64]
    signals: dict[str, dict[str, NDArray[np.float64]]]

    @property
    def buckets(self) -> int:
        """Fine buckets."""
        return int(self.count.size)

    def header_blob(self) -> bytes:
        """``count``, ``first_t``, ``seq_lo``, ``seq_hi``, little-endian float64 (stored)."""
        arrays = [self.count, self.first_t, self.seq_lo, self.seq_hi]
        return np.concatenate(arrays).astype(_F8).tobytes()

    def signal_blob(self, name: str) -> bytes:
        """One signal's arrays in :data:`_SIGNAL_FIELDS` order, little-endian float64."""
        arrays = self.signals[name]
        return np.concatenate([arrays[f] for f in _SIGNAL_FIELDS]).astype(_F8).tobytes()

    @classmethod
    def from_blobs(
        cls,
        buckets: int,
        t_first: float,
        t_last: float,
        frames: int,
        header: bytes,
        signals: dict[str, bytes],
    ) -> RunOverview:
        """The overview from its stored blobs (:meth:`header_blob`, :meth:`signal_blob`)."""
        n = int(buckets)
        count, first_t, seq_lo, seq_hi = np.frombuffer(header, dtype=_F8).reshape(4, n)
        parsed = {
            name: dict(
                zip(_SIGNAL_FIELDS, np.frombuffer(blob, dtype=_F8).reshape(-1, n), strict=True)
            )
            for name, blob in signals.items()
        }
        return cls(
            float(t_first), float(t_last), int(frames), count, first_t, seq_lo, seq_hi, parsed
        )

    def seq_range(self, t0: float, t1: float) -> tuple[int, int]:
        """The smallest and largest ``seq`` of the instants with ``t0 <= time <= t1`` could
        have (their fine buckets'); ``(0, -1)`` when none can be there."""
        span = self.t_last - self.t_first
        if self.frames == 0 or t1 < self.t_first or t0 > self.t_last:
            return 0, -1
        scale = self.buckets / span if span > 0 else 0.0
        ends = np.clip(np.array([t0, t1]) - self.t_first, 0.0, span) * scale
        lo, hi = np.minimum(ends.astype(np.int64), self.buckets - 1)
        if not np.isfinite(self.seq_lo[lo : hi + 1]).any():
            return 0, -1
        return int(np.nanmin(self.seq_lo[lo : hi + 1])), int(np.nanmax(self.seq_hi[lo : hi + 1]))

    def edges_of(self, buckets: int) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
        """Fine-bucket index where each of ``buckets`` plot buckets starts (and the end), and
        those edges in s."""
        fine = self.buckets
        starts = (np.arange(buckets + 1, dtype=np.int64) * fine + buckets - 1) // buckets
        span = self.t_last - self.t_first
        edges = np.asarray(self.t_first + starts * (span / fine), dtype=np.float64)
        return starts, edges

    def envelope(self, name: str, buckets: int) -> Envelope:
        """Signal ``name`` as min/max points per plot bucket, ``1 <= buckets <= self.buckets``.

        Raises
        ------
        KeyError
            For a signal the overview does not hold.
        ValueError
            For ``buckets`` out of range.
        """
        fine = self.buckets
        if not 1 <= buckets <= fine:
            raise ValueError(f"buckets={buckets}; the overview has {fine}")
        arrays = self.signals[name]
        starts, edges = self.edges_of(buckets)
        group = np.repeat(np.arange(buckets), np.diff(starts))
        has_instants = np.add.reduceat(self.count, starts[:-1]) > 0
        finite = arrays["finite"] > 0
        y_min = np.where(finite, arrays["y_min"], np.inf)
        y_max = np.where(finite, arrays["y_max"], -np.inf)
        low = np.minimum.reduceat(y_min, starts[:-1])
        high = np.maximum.reduceat(y_max, starts[:-1])
        index = np.arange(fine)
        # The earliest fine bucket holding the group's minimum, the latest holding its
        # maximum (the earliest/latest instant among equal extremes, as minmax_buckets).
        at_min = np.minimum.reduceat(np.where(y_min == low[group], index, fine), starts[:-1])
        at_max = np.maximum.reduceat(np.where(y_max == high[group], index, -1), starts[:-1])
        with_values = np.isfinite(low)
        gaps = has_instants & ~with_values
        first_gap = np.minimum.reduceat(np.where(self.count > 0, index, fine), starts[:-1])[gaps]
        t = np.concatenate(
            [
                arrays["t_min"][at_min[with_values]],
                arrays["t_max"][at_max[with_values]],
                self.first_t[first_gap],
            ]
        )
        y = np.concatenate([low[with_values], high[with_values], np.full(first_gap.size, np.nan)])
        # Time order; a bucket whose min and max are one instant gives it once.
        order = np.lexsort((np.nan_to_num(y, nan=-np.inf), t))
        t, y = t[order], y[order]
        same = np.r_[False, (t[1:] == t[:-1]) & (y[1:] == y[:-1])]
        return Envelope(t[~same], y[~same], edges, self.frames)


def compute_overview(
    t: NDArray[np.float64],
    columns: dict[str, NDArray[np.float64]],
    seq: NDArray[np.int64],
    buckets: int = OVERVIEW_BUCKETS,
) -> RunOverview:
    """The overview of one kind of a run from its columns.

    Parameters
    ----------
    t
        Instant times, non-decreasing, s.
    columns
        Signal name -> values at those instants (NaN where not recorded or invalid).
    seq
        The instants' ``seq`` (the historian's recording order).
    buckets
        Fine buckets.
    """
    n = int(t.size)
    count = np.zeros(buckets)
    first_t = np.full(buckets, np.nan)
    seq_lo, seq_hi = np.full(buckets, np.nan), np.full(buckets, np.nan)
    empty = {f: np.full(buckets, np.nan) for f in _SIGNAL_FIELDS}
    signals: dict[str, dict[str, NDArray[np.float64]]] = {}
    if n == 0:
        signals = {name: {f: a.copy() for f, a in empty.items()} for name in columns}
        return RunOverview(0.0, 0.0, 0, count, first_t, seq_lo, seq_hi, signals)
    t_first, t_last = float(t[0]), float(t[-1])
    span = t_last - t_first
    scale = buckets / span if span > 0 else 0.0
    bucket = np.minimum(((t - t_first) * scale).astype(np.int64), buckets - 1)
    starts = np.flatnonzero(np.r_[True, bucket[1:] != bucket[:-1]])
    used = bucket[starts]
    sizes = np.diff(np.r_[starts, n])
    count[used] = sizes
    first_t[used] = t[starts]
    seq_lo[used] = np.minimum.reduceat(seq, starts)
    seq_hi[used] = np.maximum.reduceat(seq, starts)
    positions = np.arange(n)
    for name, y in columns.items():
        finite = np.isfinite(y)
        n_finite = np.add.reduceat(finite.astype(np.int64), starts)
        low = np.minimum.reduceat(np.where(finite, y, np.inf), starts)
        high = np.maximum.reduceat(np.where(finite, y, -np.inf), starts)
        at_low = np.minimum.reduceat(
            np.where(finite & (y == np.repeat(low, sizes)), positions, n), starts
        )
        at_high = np.maximum.reduceat(
            np.where(finite & (y == np.repeat(high, sizes)), positions, -1), starts
        )
        arrays = {f: a.copy() for f, a in empty.items()}
        arrays["finite"][:] = 0.0
        arrays["finite"][used] = n_finite
        has = n_finite > 0
        where = used[has]
        arrays["y_min"][where] = low[has]
        arrays["t_min"][where] = t[at_low[has]]
        arrays["y_max"][where] = high[has]
        arrays["t_max"][where] = t[at_high[has]]
        signals[name] = arrays
    return RunOverview(t_first, t_last, n, count, first_t, seq_lo, seq_hi, signals)
