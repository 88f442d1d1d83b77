"""Trajectory sampling: an interpreted NC program as tool-tip positions at a fixed cycle time.

The sampler turns a stream of :class:`~cnctwin.nc.segments.Segment` objects into samples of the
tool tip (TCP, ``machine coordinates - tool offset``) at ``t_k = k * cycle_s``, ``k = 0, 1, ...``,
for as long as the program moves: a program of duration ``T`` gives ``ceil(T / cycle_s)`` samples,
the last one before ``T``. It streams: segments are read lazily in batches and the samples come
out in chunks of bounded size, so memory does not grow with the program.

Motion model
------------
* Feed moves run at ``feed_mm_min x feed override``, rapids in a straight line at
  ``rapid_mm_min x rapid override``; both overrides may be constant or change during the run
  (:class:`FeedOverride`). Dwells hold the position for ``dwell_s`` whatever the overrides.
  Segments shorter than 1e-9 mm without a dwell take no time (rotary-axis-only moves included:
  rotary axes are not sampled).
* Arcs and helices are interpolated exactly: the angle and the travel along the plane normal are
  linear in the path length. If the start and end radii differ, the radius is linear in the
  angle too (as LinuxCNC does); the length is then taken as the mean radius times the sweep
  (exact for a planar spiral up to a relative (dr / (r sweep))^2 / 2).
* Without :class:`AxisLimits` the speed changes instantly (ideal path, exact arc-length
  parametrisation). With them, a path-speed planner makes trapezoidal profiles:

  - per segment, the path acceleration is ``min_i a_i / |u_i|`` for a line of unit direction
    ``u``; on an arc the worst case over a full turn is used, with half of each in-plane axis'
    acceleration left to the tangential acceleration and the centripetal acceleration
    ``(v cos alpha)^2 / r`` limited to ``sqrt(3) / 2`` of it (so the vector sum stays within the
    axis limit; alpha is the helix angle); axis velocity limits cap the speed the same way;
  - junctions: tangent junctions keep their speed; corners follow the junction-deviation model of
    grbl (``v^2 = a * delta * sin(theta/2) / (1 - sin(theta/2))``, ``a`` the axis-limited
    acceleration along the corner's bisector): the default 0.01 mm (grbl's default) gives
    near-exact stops at sharp corners, ``0`` gives exact stops at every corner. At a corner the
    velocity vector jumps by at most that junction speed: it is the only place the axis
    acceleration limits are not honoured;
  - a lookahead of ``lookahead`` segments (default 128, at least that many are always buffered
    ahead of the moving segment) with a backward pass that assumes a stop after the last
    buffered segment; the program starts and ends at rest, and stops for every dwell;
  - the target speed of a segment is ``min(programmed x override, limits)``. An override change
    re-plans the lookahead; the speed then moves to the new target within the acceleration
    limit (an override drop decelerates at the segment's path acceleration limit, and may
    therefore carry a speed above the new target a short way into the next segments).

Units follow the NC layer: mm, mm/min for feeds and path speed, rpm, s; axis velocities in mm/s
and accelerations in mm/s^2, as machine configurations give them.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from cnctwin.errors import ConfigError, InputError, NCError
from cnctwin.nc import _sampler_kernels as _k
from cnctwin.nc.segments import MachineState, Plane, Segment, Vec3

__all__ = [
    "AxisLimits",
    "FeedOverride",
    "SampleChunk",
    "TrajectorySampler",
    "sample_program",
]

_NAN3: Vec3 = (math.nan, math.nan, math.nan)
_ENDS = {"none": _k.ENDS_NONE, "kind": _k.ENDS_KIND, "all": _k.ENDS_ALL}
_PLANE_INDEX = {Plane.XY: 0, Plane.ZX: 1, Plane.YZ: 2}
_ERRORS = {
    _k.ERR_FEED: "feed move with feed_mm_min={feed!r}; a feed move needs a finite feed > 0 mm/min",
    _k.ERR_NO_CENTER: "arc segment without center_mm; an arc needs its centre",
    _k.ERR_DWELL: "dwell of dwell_s={dwell!r}; a dwell needs a finite time >= 0 s",
    _k.ERR_NOT_FINITE: "segment with non-finite coordinates start_mm={start!r}, end_mm={end!r}",
}


class FeedOverride:
    """A feed (or rapid) override: constant, or piecewise constant in time.

    Parameters
    ----------
    values
        Override factor(s), 1.0 = 100 %; each finite and >= 0 (0 holds the motion). A single
        number is a constant override.
    times_s
        For a time series: the times in s (program time, 0 at the first sample) from which each
        of ``values`` applies, strictly ascending, one per value. ``values[0]`` also applies
        before ``times_s[0]``. ``None`` for a constant.

    Raises
    ------
    InputError
        On a negative or non-finite value, times that are not strictly ascending or not finite,
        lengths that differ, or a last value of 0 (the program would never end).
    """

    __slots__ = ("_times_s", "_values")

    def __init__(
        self, values: float | Sequence[float], times_s: Sequence[float] | None = None
    ) -> None:
        if times_s is None:
            vals = np.array(values, dtype=np.float64).reshape(-1)
            if vals.size != 1:
                raise InputError(
                    f"override values={values!r} without times_s; give one number for a constant "
                    "override or times_s for a time series"
                )
            times = np.zeros(1)
        else:
            vals = np.array(values, dtype=np.float64).reshape(-1)
            times = np.array(times_s, dtype=np.float64).reshape(-1)
            if vals.size == 0 or vals.size != times.size:
                raise InputError(
                    f"override with {vals.size} values and {times.size} times_s; "
                    "give one value per time, at least one"
                )
            if not np.all(np.isfinite(times)):
                raise InputError(f"override times_s={times.tolist()!r}; times must be finite")
            if np.any(np.diff(times) <= 0.0):
                raise InputError(f"override times_s={times.tolist()!r} are not strictly ascending")
        if not np.all(np.isfinite(vals)) or np.any(vals < 0.0):
            raise InputError(f"override values={vals.tolist()!r}; each must be finite and >= 0")
        if vals[-1] == 0.0:
            raise InputError(
                f"override values={vals.tolist()!r} end at 0; the program would never finish, "
                "the last value must be > 0"
            )
        self._times_s = times
        self._values = vals

    @property
    def times_s(self) -> np.ndarray:
        """Times in s from which each value applies (a copy)."""
        return self._times_s.copy()

    @property
    def values(self) -> np.ndarray:
        """Override factors, 1.0 = 100 % (a copy)."""
        return self._values.copy()

    def at(self, t_s: float) -> float:
        """Override factor in force at time ``t_s`` (s)."""
        i = int(np.searchsorted(self._times_s, t_s, side="right")) - 1
        return float(self._values[max(i, 0)])

    def __repr__(self) -> str:
        return f"FeedOverride(values={self._values.tolist()!r}, times_s={self._times_s.tolist()!r})"


@dataclass(frozen=True, slots=True)
class AxisLimits:
    """Per-axis kinematic limits of the machine for the acceleration-limited planner.

    Attributes
    ----------
    accel_mm_s2
        Maximum acceleration of the x, y, z axes in mm/s^2, each finite and > 0.
    velocity_mm_s
        Maximum velocity of the x, y, z axes in mm/s, each > 0 (``math.inf`` for none).
    junction_deviation_mm
        Junction deviation in mm (>= 0) for the corner speed (see the module notes):
        0.01 mm is grbl's default; 0 stops exactly at every corner that is not tangent.

    Raises
    ------
    ConfigError
        On a value outside those ranges.
    """

    accel_mm_s2: Vec3
    velocity_mm_s: Vec3 = (math.inf, math.inf, math.inf)
    junction_deviation_mm: float = 0.01

    def __post_init__(self) -> None:
        acc = self.accel_mm_s2
        vel = self.velocity_mm_s
        if len(acc) != 3 or not all(math.isfinite(a) and a > 0.0 for a in acc):
            raise ConfigError(f"accel_mm_s2={acc!r}; give three finite accelerations > 0 mm/s^2")
        if len(vel) != 3 or not all(v > 0.0 for v in vel):
            raise ConfigError(
                f"velocity_mm_s={vel!r}; give three velocities > 0 mm/s (inf for none)"
            )
        dev = self.junction_deviation_mm
        if not (math.isfinite(dev) and dev >= 0.0):
            raise ConfigError(f"junction_deviation_mm={dev!r}; give a finite deviation >= 0 mm")


class SampleChunk(NamedTuple):
    """A run of consecutive samples; every array has the sample axis first.

    Attributes
    ----------
    t_s
        (n,) sample times ``k * cycle_s`` in s (and segment end times with ``segment_ends``).
    tcp_mm
        (n, 3) tool tip in machine coordinates in mm.
    velocity_mm_s
        (n, 3) tool-tip velocity in mm/s.
    path_speed_mm_min
        (n,) path speed in mm/min (0 during dwells and holds).
    line
        (n,) source line of the segment being executed (int64).
    kind
        (n,) :class:`~cnctwin.nc.segments.MotionKind` of that segment (int8): rapid, linear,
        arc or dwell.
    tool
        (n,) tool number in the spindle (int32).
    spindle_rpm
        (n,) spindle speed of that segment in rpm.
    """

    t_s: np.ndarray
    tcp_mm: np.ndarray
    velocity_mm_s: np.ndarray
    path_speed_mm_min: np.ndarray
    line: np.ndarray
    kind: np.ndarray
    tool: np.ndarray
    spindle_rpm: np.ndarray


def _empty_chunk(n: int) -> SampleChunk:
    return SampleChunk(
        t_s=np.empty(n),
        tcp_mm=np.empty((n, 3)),
        velocity_mm_s=np.empty((n, 3)),
        path_speed_mm_min=np.empty(n),
        line=np.empty(n, dtype=np.int64),
        kind=np.empty(n, dtype=np.int8),
        tool=np.empty(n, dtype=np.int32),
        spindle_rpm=np.empty(n),
    )


def _as_override(value: float | FeedOverride, name: str) -> FeedOverride:
    if isinstance(value, FeedOverride):
        return value
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError(f"{name}={value!r}; give a number (1.0 = 100 %) or a FeedOverride")
    return FeedOverride(float(value))


def _state_row(state: MachineState) -> tuple[float, float, float, float, float]:
    off = state.tool_offset_mm
    return (off[0], off[1], off[2], float(_PLANE_INDEX[Plane(state.plane)]), float(state.tool))


class TrajectorySampler:
    """Iterator of :class:`SampleChunk` for a stream of segments (the sampler's main API).

    Parameters
    ----------
    segments
        Motion segments in program order; any iterable, consumed lazily (a generator from the
        interpreter is read a batch at a time, never as a whole).
    rapid_mm_min
        Rapid traverse rate of the machine along the path in mm/min, > 0.
    cycle_s
        Sample period in s, > 0 (the twin's cycle, 12.5 ms by default).
    feed_override
        Override of feed moves: a factor (1.0 = 100 %) or a :class:`FeedOverride` time series.
    rapid_override
        Override of rapids, likewise.
    limits
        Axis acceleration (and velocity) limits; ``None`` for the ideal path with instant speed
        changes.
    chunk_samples
        Samples per chunk (every chunk but the last is full), >= 1.
    lookahead
        Segments the planner always has buffered ahead of the moving one, >= 1 (used with
        ``limits``).
    batch_segments
        Segments read from ``segments`` at a time, >= 1.
    segment_ends
        Also sample segment ends, at their end time and labelled with their segment, so that
        a step does not span them (offline simulation: what a step cuts belongs to the segment
        that moved the tool there). ``"all"``: the end of every segment (dwells included);
        ``"kind"``: every end but the tangent junction of two feed moves (linear or arc) of
        the same tool (direction change at most 1e-3 rad), where a step may still span the
        junction (every rapid's and dwell's start and end are sampled, every corner, and
        every change of tool: a step spanning a corner would cut the chord, leaving a sliver
        of the corner that a later pass along the same wall reads as a cut of the whole
        wall); ``"none"`` (the default): grid
        samples only. Where an end falls on a grid time (within 1e-9 cycles) that grid sample
        is the end sample; elsewhere the chunk gets an extra sample between two grid times.
        With ``"all"`` or ``"kind"`` the last sample is the program's end.

    Raises
    ------
    InputError
        On an invalid parameter (here), see :class:`FeedOverride` and :class:`AxisLimits`.
    NCError
        While iterating, on a segment that cannot be executed (feed move with no feed, arc
        without centre, negative dwell, non-finite coordinates), with its file and line.

    Notes
    -----
    After the last chunk, :attr:`duration_s` holds the program's duration. Memory is bounded by
    ``chunk_samples`` and ``batch_segments + lookahead``, whatever the program's length.
    """

    def __init__(
        self,
        segments: Iterable[Segment],
        *,
        rapid_mm_min: float,
        cycle_s: float = 0.0125,
        feed_override: float | FeedOverride = 1.0,
        rapid_override: float | FeedOverride = 1.0,
        limits: AxisLimits | None = None,
        chunk_samples: int = 16384,
        lookahead: int = 128,
        batch_segments: int = 4096,
        segment_ends: str = "none",
    ) -> None:
        if not (math.isfinite(rapid_mm_min) and rapid_mm_min > 0.0):
            raise InputError(f"rapid_mm_min={rapid_mm_min!r}; give a finite rapid rate > 0 mm/min")
        if not (math.isfinite(cycle_s) and cycle_s > 0.0):
            raise InputError(f"cycle_s={cycle_s!r}; give a finite cycle time > 0 s")
        for name, value in (
            ("chunk_samples", chunk_samples),
            ("lookahead", lookahead),
            ("batch_segments", batch_segments),
        ):
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise InputError(f"{name}={value!r}; give an integer >= 1")
        if not isinstance(segment_ends, str) or segment_ends not in _ENDS:
            raise InputError(
                f"segment_ends={segment_ends!r}; give one of {', '.join(map(repr, _ENDS))}"
            )
        if limits is not None and not isinstance(limits, AxisLimits):
            raise InputError(f"limits={limits!r}; give an AxisLimits or None")
        self._feed = _as_override(feed_override, "feed_override")
        self._rapid = _as_override(rapid_override, "rapid_override")
        self._iter = iter(segments)
        self._rapid_mm_s = rapid_mm_min / 60.0
        self._dt = float(cycle_s)
        self._limits = limits
        self._chunk = chunk_samples
        self._lookahead = lookahead
        self._batch = batch_segments
        self._ends = _ENDS[segment_ends]
        self._duration_s = 0.0
        self._finished = False
        self._gen = self._generate()

    @property
    def duration_s(self) -> float | None:
        """Duration of the program in s once all chunks are out, ``None`` before."""
        return self._duration_s if self._finished else None

    def __iter__(self) -> TrajectorySampler:
        return self

    def __next__(self) -> SampleChunk:
        return next(self._gen)

    def _read_batch(self, geo: np.ndarray, prev: np.ndarray) -> tuple[int, bool]:
        """Read up to batch_segments segments into geo; returns (rows, stream exhausted)."""
        batch = list(itertools.islice(self._iter, self._batch))
        n = len(batch)
        if n == 0:
            return 0, True
        raw = np.fromiter(
            itertools.chain.from_iterable(
                (
                    s.kind,
                    s.line,
                    *s.start_mm,
                    *s.end_mm,
                    s.feed_mm_min,
                    s.spindle_rpm,
                    *(s.center_mm or _NAN3),
                    s.turns,
                    s.dwell_s,
                )
                for s in batch
            ),
            dtype=np.float64,
            count=_k.N_RAW * n,
        ).reshape(n, _k.N_RAW)
        states = [s.state for s in batch]
        ids = np.fromiter(map(id, states), dtype=np.int64, count=n)
        new = np.ones(n, dtype=bool)
        new[1:] = ids[1:] != ids[:-1]
        first = np.flatnonzero(new)
        table = np.array([_state_row(states[i]) for i in first], dtype=np.float64)
        state_index = np.cumsum(new) - 1
        lim = self._limits
        if lim is None:
            acc = vmax = np.full(3, math.inf)
            dev = 0.0
        else:
            acc = np.array(lim.accel_mm_s2, dtype=np.float64)
            vmax = np.array(lim.velocity_mm_s, dtype=np.float64)
            dev = lim.junction_deviation_mm
        rows, err, at = _k.build_geometry(
            raw, state_index, table, self._rapid_mm_s, acc, vmax, dev, lim is not None, prev, geo
        )
        if err != _k.ERR_NONE:
            seg = batch[at]
            msg = _ERRORS[err].format(
                feed=seg.feed_mm_min, dwell=seg.dwell_s, start=seg.start_mm, end=seg.end_mm
            )
            raise NCError(msg, file=seg.file or "<string>", line=seg.line)
        return rows, n < self._batch

    def _generate(self) -> Iterator[SampleChunk]:
        look = self._lookahead
        cap = look + self._batch
        geo = np.zeros((cap, _k.N_GEO))
        vexit = np.zeros(cap)
        prev = np.zeros(_k.N_PREV)
        fs = np.zeros(_k.N_FSTATE)
        ist = np.zeros(_k.N_ISTATE, dtype=np.int64)
        feed_t, feed_v = self._feed._times_s, self._feed._values
        rapid_t, rapid_v = self._rapid._times_s, self._rapid._values
        limited = self._limits is not None
        out = _empty_chunk(self._chunk)
        n_out = 0
        n_buf = 0
        exhausted = False
        while True:
            n_exec = n_buf if exhausted else n_buf - look
            j = int(ist[_k.I_J])
            if j >= n_exec and ist[_k.I_HAVE] == 0:
                if exhausted:
                    break
                keep = n_buf - j
                geo[:keep] = geo[j:n_buf]
                ist[_k.I_J] = 0
                rows, exhausted = self._read_batch(geo[keep:], prev)
                n_buf = keep + rows
                ist[_k.I_PLANNED] = 0
                continue
            n_out = _k.run(
                geo,
                n_buf,
                n_exec,
                vexit,
                feed_t,
                feed_v,
                rapid_t,
                rapid_v,
                limited,
                self._dt,
                self._ends,
                fs,
                ist,
                *out,
                n_out,
            )
            if n_out == self._chunk:
                yield out
                out = _empty_chunk(self._chunk)
                n_out = 0
        if n_out:
            yield SampleChunk(*(a[:n_out] for a in out))
        self._duration_s = float(fs[_k.F_T])
        self._finished = True


def sample_program(
    segments: Iterable[Segment],
    *,
    rapid_mm_min: float,
    cycle_s: float = 0.0125,
    feed_override: float | FeedOverride = 1.0,
    rapid_override: float | FeedOverride = 1.0,
    limits: AxisLimits | None = None,
) -> tuple[SampleChunk, float]:
    """Sample a whole (small) program into one chunk.

    Parameters are those of :class:`TrajectorySampler` (same units); for long programs iterate a
    :class:`TrajectorySampler` instead, which keeps memory flat.

    Returns
    -------
    samples
        All samples, ``ceil(duration_s / cycle_s)`` of them.
    duration_s
        Duration of the program in s.

    Raises
    ------
    ConfigError
        When the samples (kept, then joined: twice their size) would exceed the memory limit
        (:mod:`cnctwin.memory`): the program is too long for one chunk at this cycle.
    """
    from cnctwin.memory import check_memory

    sampler = TrajectorySampler(
        segments,
        rapid_mm_min=rapid_mm_min,
        cycle_s=cycle_s,
        feed_override=feed_override,
        rapid_override=rapid_override,
        limits=limits,
    )
    chunks: list[SampleChunk] = []
    samples = 0
    nbytes = 0
    for chunk in sampler:
        samples += chunk.t_s.size
        nbytes += sum(part.nbytes for part in chunk)

        def remedy(fraction: float, n: int = samples) -> str:
            return (
                f"at most {n * fraction:.3g} samples fit: iterate a TrajectorySampler, or use "
                "a longer cycle time or a shorter program"
            )

        check_memory(
            f"sampling the program at {cycle_s:g} s into one chunk is more than {samples:.3g} "
            "samples",
            2.0 * nbytes,
            remedy,
        )
        chunks.append(chunk)
    if not chunks:
        return _empty_chunk(0), sampler._duration_s
    return SampleChunk(
        *(np.concatenate(parts) for parts in zip(*chunks, strict=True))
    ), sampler._duration_s
