"""A one-pass summary of an NC program's motion: lengths, times, tool-tip bounds, tools.

The summary streams over segments; it never holds them. Times are nominal: every move at
its programmed (resolved) feed or at the machine's rapid rate, with no acceleration limits.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from itertools import repeat
from typing import Any, Final

from cnctwin.errors import ConfigError, NCError
from cnctwin.nc.runs import MoveRun, arc_sweeps, map_floats, rows
from cnctwin.nc.segments import PLANE_AXES, FeedMode, MotionKind, Segment, Vec3, arc_sweep_rad

__all__ = ["ProgramSummary", "arc_extreme_points", "summarize"]

_QUARTER: Final = math.pi / 2.0
#: cos and sin of k * 90 degrees, exactly.
_COS: Final = (1.0, 0.0, -1.0, 0.0)
_SIN: Final = (0.0, 1.0, 0.0, -1.0)
_ZERO3: Final = (0.0, 0.0, 0.0)


@dataclass(frozen=True, slots=True)
class ProgramSummary:
    """What an NC program does, in numbers.

    Attributes
    ----------
    motion_blocks
        Number of motion segments (rapid, linear and arc; not dwells).
    feed_length_mm, rapid_length_mm
        Path length of feed moves (linear and arc) and of rapids in mm.
    machining_time_s
        Sum over feed moves of length / feed, in s (moves with feed 0 add nothing); a move
        that turns only rotary axes takes its angle / F, F in degrees/min (LinuxCNC).
    rapid_time_s
        Rapid length at the machine's rapid rate, in s.
    dwell_time_s
        Sum of dwells in s.
    total_time_s
        machining + rapid + dwell time, in s.
    bounds_min_mm, bounds_max_mm
        Box around the tool tip's path in machine coordinates, mm, arcs included exactly;
        ``None`` without motion.
    tools
        Sorted tool numbers in the spindle during motion (tool 0, no tool, excluded).
    zero_feed_moves
        Number of feed moves whose feed is 0.
    warnings
        ``"FILE:LINE: message"`` lines, e.g. about moves with feed 0.
    """

    motion_blocks: int
    feed_length_mm: float
    rapid_length_mm: float
    machining_time_s: float
    rapid_time_s: float
    dwell_time_s: float
    total_time_s: float
    bounds_min_mm: Vec3 | None
    bounds_max_mm: Vec3 | None
    tools: tuple[int, ...]
    zero_feed_moves: int
    warnings: tuple[str, ...]

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form: numbers, lists, ``bounds_mm`` as ``{"min": [x, y, z], "max": ...}``."""
        return {
            "motion_blocks": self.motion_blocks,
            "feed_length_mm": self.feed_length_mm,
            "rapid_length_mm": self.rapid_length_mm,
            "machining_time_s": self.machining_time_s,
            "rapid_time_s": self.rapid_time_s,
            "dwell_time_s": self.dwell_time_s,
            "total_time_s": self.total_time_s,
            "bounds_mm": {
                "min": list(self.bounds_min_mm) if self.bounds_min_mm else None,
                "max": list(self.bounds_max_mm) if self.bounds_max_mm else None,
            },
            "tools": list(self.tools),
            "zero_feed_moves": self.zero_feed_moves,
            "warnings": list(self.warnings),
        }


def summarize(
    segments: Iterable[Segment | MoveRun],
    *,
    rapid_mm_min: float,
    travel_mm: tuple[Vec3, Vec3] | None = None,
) -> ProgramSummary:
    """Summarize a program's segments in one pass.

    Parameters
    ----------
    segments
        Segments from the interpreter, consumed once; runs of moves
        (:meth:`~cnctwin.nc.interpreter.Interpreter.run_file_bulk`) are summed in bulk,
        to the same numbers as their segments.
    rapid_mm_min
        The machine's rapid traverse rate in mm/min, > 0.
    travel_mm
        The machine's axis travel ``(min, max)`` in machine coordinates, mm. When given,
        the controlled point (tool tip + tool offset: what the axes read) is checked
        against it, arcs included, and the first move beyond each limit is warned about.

    Returns
    -------
    ProgramSummary
        Lengths in mm, times in s, tool-tip bounds in mm.

    Raises
    ------
    cnctwin.errors.ConfigError
        If ``rapid_mm_min`` is not a positive finite number.
    """
    if not (math.isfinite(rapid_mm_min) and rapid_mm_min > 0):
        raise ConfigError(f"rapid_mm_min must be a positive number of mm/min; got {rapid_mm_min!r}")
    motion = 0
    feed_length = rapid_length = machining_time = dwell_time = 0.0
    tools: set[int] = set()
    zero_feed = 0
    first_zero_feed = ""
    beyond: dict[tuple[int, int], str] = {}
    low_x = low_y = low_z = math.inf
    high_x = high_y = high_z = -math.inf
    dwell, rapid, arc = MotionKind.DWELL, MotionKind.RAPID, MotionKind.ARC
    if travel_mm is not None:
        segments = _one_by_one(segments)
    for seg in segments:
        if isinstance(seg, MoveRun):
            motion += len(seg)
            if seg.state.tool:
                tools.add(seg.state.tool)
            rapid_length, feed_length, machining_time, run_low, run_high = _add_run(
                seg,
                rapid_length,
                feed_length,
                machining_time,
                (low_x, low_y, low_z),
                (high_x, high_y, high_z),
            )
            low_x, low_y, low_z = run_low
            high_x, high_y, high_z = run_high
            continue
        kind = seg.kind
        if kind is dwell:
            dwell_time += seg.dwell_s
            continue
        motion += 1
        state = seg.state
        offset = state.tool_offset_mm
        s, e = seg.start_mm, seg.end_mm
        sweep_geometry = None
        if kind is arc and seg.center_mm is not None:
            sweep_geometry = arc_sweep_rad(s, e, seg.center_mm, seg.turns, state.plane)
            normal = PLANE_AXES[state.plane][2]
            length = math.hypot(sweep_geometry[0] * sweep_geometry[2], e[normal] - s[normal])
        else:
            length = math.sqrt((e[0] - s[0]) ** 2 + (e[1] - s[1]) ** 2 + (e[2] - s[2]) ** 2)
        if kind is rapid:
            rapid_length += length
        else:
            feed_length += length
            turn_deg = 0.0 if length > 0.0 else _rotary_distance_deg(seg)
            if turn_deg > 0.0 and (rotary_feed := _rotary_feed_deg_min(seg, turn_deg)) > 0.0:
                machining_time += 60.0 * turn_deg / rotary_feed
            elif turn_deg <= 0.0 and seg.feed_mm_min > 0:
                machining_time += 60.0 * length / seg.feed_mm_min
            else:
                zero_feed += 1
                first_zero_feed = first_zero_feed or f"{seg.file or '<program>'}:{seg.line}"
        if state.tool:
            tools.add(state.tool)
        points: Iterable[Vec3] = (
            (s[0] - offset[0], s[1] - offset[1], s[2] - offset[2]),
            (e[0] - offset[0], e[1] - offset[1], e[2] - offset[2]),
        )
        if sweep_geometry is not None:
            # Without a tool offset the tool tip's arc is the controlled point's: same numbers.
            if offset != _ZERO3:
                sweep_geometry = None
            points = (*points, *_arc_extremes(seg, sweep_geometry))
        for x, y, z in points:
            if x < low_x:
                low_x = x
            if x > high_x:
                high_x = x
            if y < low_y:
                low_y = y
            if y > high_y:
                high_y = y
            if z < low_z:
                low_z = z
            if z > high_z:
                high_z = z
            if travel_mm is not None:
                _check_travel(seg, (x, y, z), travel_mm, beyond)
    low = [low_x, low_y, low_z]
    high = [high_x, high_y, high_z]
    rapid_time = 60.0 * rapid_length / rapid_mm_min
    warnings: tuple[str, ...] = tuple(beyond[key] for key in sorted(beyond))
    if zero_feed:
        warnings += (
            f"{first_zero_feed}: {zero_feed} feed move{'s' if zero_feed > 1 else ''} with feed 0 "
            "mm/min (the first here); their machining time is not counted",
        )
    return ProgramSummary(
        motion_blocks=motion,
        feed_length_mm=feed_length,
        rapid_length_mm=rapid_length,
        machining_time_s=machining_time,
        rapid_time_s=rapid_time,
        dwell_time_s=dwell_time,
        total_time_s=machining_time + rapid_time + dwell_time,
        bounds_min_mm=(low[0], low[1], low[2]) if motion else None,
        bounds_max_mm=(high[0], high[1], high[2]) if motion else None,
        tools=tuple(sorted(tools)),
        zero_feed_moves=zero_feed,
        warnings=warnings,
    )


def _one_by_one(items: Iterable[Segment | MoveRun]) -> Iterator[Segment]:
    """The segments of ``items``, runs taken apart."""
    for item in items:
        if isinstance(item, MoveRun):
            yield from item.segments()
        else:
            yield item


def _add_run(
    run: MoveRun,
    rapid_length: float,
    feed_length: float,
    machining_time: float,
    low: Vec3,
    high: Vec3,
) -> tuple[float, float, float, Vec3, Vec3]:
    """The totals of :func:`summarize` after the moves of ``run``: rapid and feed length
    (mm), machining time (s) and the tool tip's box (mm), each the number the loop over the
    run's segments gives (same operations, same order: sums are sequential, squares are
    Python's float power, arc sweeps ``math.atan2``, ``math.hypot`` and ``%``)."""
    import numpy as np

    ends = run.end_mm
    starts = np.empty_like(ends)
    starts[0] = run.start_mm
    starts[1:] = ends[:-1]
    n = len(ends)
    on_arc = run.motion >= 20
    any_arc = bool(on_arc.any())
    arcs = rows(np.flatnonzero(on_arc), n)
    straight = np.flatnonzero(~on_arc)
    lengths = np.empty(n)
    if len(straight):
        straight = rows(straight, n)
        x2, y2, z2 = (
            map_floats(pow, steps.tolist(), repeat(2)) if steps.any() else steps
            for steps in (ends[straight] - starts[straight]).T
        )
        lengths[straight] = np.sqrt(x2 + y2 + z2)
    turns = np.where(run.motion[arcs] == 30, 1, -1)
    if any_arc:
        radius, a0, sweep = arc_sweeps(
            starts[arcs], ends[arcs], run.center_mm[arcs], turns, run.radius_mm[arcs]
        )
        # math.hypot(a, 0.0) is abs(a) to the bit (a scaling by a power of two, an exact
        # square and a correctly rounded root), so only helices take math.hypot.
        rise = ends[arcs, 2] - starts[arcs, 2]
        arc_lengths = np.abs(radius * sweep)
        helix = np.flatnonzero(rise)
        if len(helix):
            arc_lengths[helix] = map_floats(
                math.hypot, (radius * sweep)[helix].tolist(), rise[helix].tolist()
            )
        lengths[arcs] = arc_lengths
    rapid = run.motion == 0
    if rapid.any():
        rapid_length = float(np.add.accumulate(np.append(rapid_length, lengths[rapid]))[-1])
    fed = ~rapid
    if fed.any():
        feed = lengths[fed]
        feed_length = float(np.add.accumulate(np.append(feed_length, feed))[-1])
        times = 60.0 * feed / run.feed_mm_min[fed]
        machining_time = float(np.add.accumulate(np.append(machining_time, times))[-1])
    offset = np.array(run.state.tool_offset_mm)
    # Each move's points in the loop's order: start, end, an arc's up to four extremes.
    points = np.empty((n, 6 if any_arc else 2, 3))
    points[:, 0] = starts - offset
    points[:, 1] = ends - offset
    valid = None
    if any_arc:
        valid = np.zeros((n, 6), dtype=bool)
        valid[:, :2] = True
        tcp_start, tcp_end = points[arcs, 0], points[arcs, 1]
        center = run.center_mm[arcs] - offset
        if run.state.tool_offset_mm != _ZERO3:
            radius, a0, sweep = arc_sweeps(tcp_start, tcp_end, center, turns)
        lo = np.minimum(a0, a0 + sweep)
        hi = np.maximum(a0, a0 + sweep)
        k_first = np.ceil(lo / _QUARTER)
        k_last = np.minimum(np.floor(hi / _QUARTER), k_first + 3)
        quadrant_cos, quadrant_sin = np.array(_COS), np.array(_SIN)
        for slot in range(4):
            k = k_first + slot
            taken = k <= k_last
            if not taken.any():  # nor any later slot
                break
            quadrant = np.mod(k, 4).astype(np.intp)
            fraction = (k * _QUARTER - a0) / sweep
            extreme = np.empty((len(center), 3))
            extreme[:, 0] = center[:, 0] + radius * quadrant_cos[quadrant]
            extreme[:, 1] = center[:, 1] + radius * quadrant_sin[quadrant]
            extreme[:, 2] = tcp_start[:, 2] + fraction * (tcp_end[:, 2] - tcp_start[:, 2])
            points[arcs, 2 + slot] = extreme
            valid[arcs, 2 + slot] = taken
    flat_valid = None if valid is None else valid.reshape(-1)
    low, high = _box(points.reshape(-1, 3), flat_valid, low, high)
    return rapid_length, feed_length, machining_time, low, high


def _box(points: Any, valid: Any, low: Vec3, high: Vec3) -> tuple[Vec3, Vec3]:
    """The box ``low``, ``high`` (mm) grown by the (n, 3) ``points`` (those rows where
    ``valid``, if given) in order, as the loop of :func:`summarize` grows it: the first
    point of the lowest (highest) value wins (-0.0 against 0.0)."""
    import numpy as np

    taken = points if valid is None else points[valid]
    lows = taken[np.argmin(taken, axis=0), (0, 1, 2)].tolist()
    highs = taken[np.argmax(taken, axis=0), (0, 1, 2)].tolist()
    new_low = [v if v < old else old for v, old in zip(lows, low, strict=True)]
    new_high = [v if v > old else old for v, old in zip(highs, high, strict=True)]
    return (new_low[0], new_low[1], new_low[2]), (new_high[0], new_high[1], new_high[2])


def _rotary_distance_deg(seg: Segment) -> float:
    """How far a move turns its rotary axes A, B, C together, in degrees."""
    return math.dist(seg.start_abc_deg, seg.end_abc_deg)


def _rotary_feed_deg_min(seg: Segment, turn_deg: float) -> float:
    """Feed rate of a move that turns only rotary axes, deg/min.

    LinuxCNC reads F as degrees per minute on such a move (per minute under G94, per
    revolution of the spindle under G95; under G93 the move takes 1/F minutes).
    ``turn_deg``: the move's rotary distance in degrees.
    """
    state = seg.state
    if state.feed_mode == FeedMode.INVERSE_TIME:
        return turn_deg * state.programmed_feed
    if state.feed_mode == FeedMode.UNITS_PER_REV:
        return state.programmed_feed * seg.spindle_rpm
    return state.programmed_feed


def _check_travel(
    seg: Segment, tcp: Vec3, travel: tuple[Vec3, Vec3], beyond: dict[tuple[int, int], str]
) -> None:
    """Record the first point of the program beyond each end of each axis' travel."""
    offset = seg.state.tool_offset_mm
    for axis in range(3):
        value = tcp[axis] + offset[axis]
        lo, hi = travel[0][axis], travel[1][axis]
        side = 0 if value < lo - 1e-9 else 1 if value > hi + 1e-9 else -1
        if side < 0 or (axis, side) in beyond:
            continue
        name = "XYZ"[axis]
        beyond[(axis, side)] = (
            f"{seg.file or '<program>'}:{seg.line}: {name} reaches {value:.3f} mm, beyond the "
            f"machine's travel {lo:.3f} .. {hi:.3f} mm (machine.axes.{name.lower()})"
        )


def arc_extreme_points(seg: Segment) -> Iterator[Vec3]:
    """Tool-tip points where an arc (or helix) crosses 0, 90, 180 or 270 degrees in its plane.

    Together with the start and end these bound the arc exactly.

    Parameters
    ----------
    seg
        An arc segment (``center_mm`` set).

    Yields
    ------
    Vec3
        Points in machine coordinates of the tool tip, mm; at most four, the normal
        coordinate interpolated along the helix.

    Raises
    ------
    cnctwin.errors.NCError
        If the segment has no centre.
    """
    if seg.center_mm is None:
        raise NCError(
            f"{seg.kind.name} segment has no arc centre", seg.file or "<program>", seg.line
        )
    return iter(_arc_extremes(seg, None))


def _arc_extremes(seg: Segment, geometry: tuple[float, float, float] | None) -> list[Vec3]:
    """:func:`arc_extreme_points` of an arc with a centre; ``geometry``: its tool tip's
    (radius mm, start angle rad, sweep rad) if already known."""
    offset = seg.state.tool_offset_mm
    start, end = seg.tcp_start_mm, seg.tcp_end_mm
    c = seg.center_mm
    assert c is not None
    center = (c[0] - offset[0], c[1] - offset[1], c[2] - offset[2])
    if geometry is None:
        geometry = arc_sweep_rad(start, end, center, seg.turns, seg.state.plane)
    radius, a0, sweep = geometry
    first_axis, second_axis, normal = PLANE_AXES[seg.state.plane]
    lo, hi = sorted((a0, a0 + sweep))
    k_first = math.ceil(lo / _QUARTER)
    k_last = min(math.floor(hi / _QUARTER), k_first + 3)
    points: list[Vec3] = []
    for k in range(k_first, k_last + 1):
        fraction = (k * _QUARTER - a0) / sweep if sweep else 0.0
        point = [0.0, 0.0, 0.0]
        point[first_axis] = center[first_axis] + radius * _COS[k % 4]
        point[second_axis] = center[second_axis] + radius * _SIN[k % 4]
        point[normal] = start[normal] + fraction * (end[normal] - start[normal])
        points.append((point[0], point[1], point[2]))
    return points
