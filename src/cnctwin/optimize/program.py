"""An NC program rewritten with the feed (and speed) per block that its limits allow.

:func:`optimize_program` cuts the program through the stock once (:func:`~cnctwin.optimize.
loads.program_loads`), takes per step the largest feed per tooth each limit allows, and turns
it into a feed per block:

- a feed ``F = f_z N n`` (N teeth, n rpm: the programmed speed, or the stability schedule's),
  capped by the machine (the slowest linear axis' ``max_velocity_mm_min``), by ``--max-feed``
  and by the programmed feed times ``max_factor``;
- steps without contact (air cutting) never raise the feed: they keep the programmed one,
  unless an ``air_feed_mm_min`` is given, which they then run at (capped by the machine and
  ``--max-feed``). Within :data:`MARGIN_MM` (and two steps at the fastest feed) of a cut the
  cut's feed holds, so a piece never meets material at an air or a faster feed;
- a long straight or circular block whose allowed feed changes along it is split at the change
  points (straight pieces, or arcs about the same centre), pieces at least
  :data:`MIN_PIECE_MM` long whose feeds differ by more than :data:`FEED_STEP`; other blocks
  run at the lowest feed any of their steps allows;
- the program is written anew (:mod:`cnctwin.optimize.rewrite`): an F word only where the
  modal feed changes, block numbers kept on the first piece, the original line as a comment
  before a split block; and cut again, sampled as ``cnctwin simulate`` and ``cnctwin signals``
  sample (a step may span the tangent junction of two feed blocks): a step that still exceeds a
  limit (the engagement of a step shifts with its length and its junction) lowers its piece's feed
  to what that step allows, until no step exceeds a limit (at most ``passes`` cuts).

What is not rewritten (kept as written, its programmed feed restored where an earlier block's
new feed would otherwise carry over): blocks with expressions or keywords, several moves
(canned cycles) or rapids, inverse-time (G93) or per-revolution (G95) feeds. Programs that
jump (loops, subroutines, subprogram files) are refused: the modal feed is written in text
order. Splitting needs absolute coordinates (no G91 in the program), no cutter compensation,
no rotated frame, arcs in G17 with incremental I/J (no R, no G90.1).

Units: mm, mm/min, rpm, N, W, s in the names; the rewritten words are in the program's units.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from cnctwin.errors import InputError
from cnctwin.geometry import Cutter, DexelStock
from cnctwin.mechanics import CuttingCoefficients
from cnctwin.nc import CutterComp, FeedMode, Interpreter, MotionKind, Plane, Segment, arc_sweep_rad
from cnctwin.optimize.loads import FeedLimits, ProgramLoads, program_loads
from cnctwin.optimize.rewrite import (
    Block,
    comment_style,
    format_number,
    read_block,
    set_words,
    split_block,
)
from cnctwin.simulation import step_durations

if TYPE_CHECKING:
    from cnctwin.config import MachiningConfig
    from cnctwin.dynamics import StabilityRoadmap

__all__ = [
    "FEED_STEP",
    "MARGIN_MM",
    "MIN_PIECE_MM",
    "BlockPlan",
    "OptimizedProgram",
    "optimize_program",
]

#: Shortest piece of a split block, mm.
MIN_PIECE_MM = 2.0
#: Relative feed change that starts a new piece.
FEED_STEP = 0.1
#: Length around a cut, mm, where the cut's feed holds (besides two steps at the fastest feed).
MARGIN_MM = 0.5
#: The least feed of a block, as a fraction of its programmed feed, without ``--min-feed``.
MIN_FEED_FRACTION = 0.1
#: Range of a feed given as an option, mm/min: the least the written program can state
#: (three significant digits, 0.001 mm/min) to far above any machine's axes.
FEED_RANGE_MM_MIN = (0.001, 1e6)
#: Most pieces a block is split into.
MAX_PIECES = 12
_MM_PER_INCH = 25.4
_LIMIT_NAMES = ("force", "chip", "power")
_G91 = re.compile(r"g\s*91(?![.\d])", re.IGNORECASE)
_G901 = re.compile(r"g\s*90\s*\.\s*1", re.IGNORECASE)


@dataclass
class BlockPlan:
    """The new feed of one block of the program.

    Attributes
    ----------
    line
        Source line.
    feed_mm_min
        Programmed feed, mm/min.
    rpm
        Programmed spindle speed, rpm.
    new_rpm
        Spindle speed written, rpm (the programmed one without a stability schedule).
    pieces
        ``(end fraction of the path, feed mm/min, limit)`` per piece, in path order; the limit
        is ``"force"``, ``"power"``, ``"chip"``, ``"machine"`` (axis speed or ``--max-feed``),
        ``"factor"`` (programmed feed times the factor), ``"air"`` (no contact) or
        ``"min-feed"`` (a limit not reachable above the least feed).
    split
        Whether the block may be split (its geometry allows it).
    note
        Why the block keeps its programmed feed, if it does.
    """

    line: int
    feed_mm_min: float
    rpm: float
    new_rpm: float
    pieces: list[tuple[float, float, str]] = field(default_factory=list)
    split: bool = False
    note: str = ""

    @property
    def limit(self) -> str:
        """The limit of the slowest piece (``"kept"`` for a block not rewritten)."""
        if not self.pieces:
            return "kept"
        return min(self.pieces, key=lambda p: p[1])[2]


@dataclass
class OptimizedProgram:
    """The result of :func:`optimize_program`.

    Attributes
    ----------
    text
        The optimised program.
    limits
        The limits.
    blocks
        The plan of every feed block, by source line.
    before, after
        The loads of the original and the optimised program (the last cut).
    passes
        Cuts of the optimised program done.
    warnings
        Lines worth a warning (limits not held, blocks the limit cannot be met in).
    origin
        The source line of each line of the optimised program (1-based both).
    """

    text: str
    limits: FeedLimits
    blocks: dict[int, BlockPlan]
    before: ProgramLoads
    after: ProgramLoads
    passes: int
    warnings: list[str] = field(default_factory=list)
    origin: dict[int, int] = field(default_factory=dict)

    def maxima(self, loads: ProgramLoads) -> dict[str, float]:
        """Largest peak force, mean force (N), power (W) and chip (mm) of the feed steps."""
        cut = loads.contact & ~loads.rapid

        def top(values: NDArray[np.float64]) -> float:
            return float(values[cut].max()) if cut.any() else 0.0

        return {
            "max_force_n": top(loads.peak_n),
            "max_mean_force_n": top(loads.mean_n),
            "max_power_w": top(loads.power_w),
            "max_chip_mm": top(loads.chip_mm),
        }

    @property
    def limits_hold(self) -> bool:
        """Whether every feed step of the optimised program respects every limit."""
        return not _violations(self.after, self.limits).any()

    def summary(self) -> dict[str, Any]:
        """The result in figures (the ``--json`` of ``cnctwin optimize``).

        Returns
        -------
        dict
            ``cycle_time_before_s``, ``cycle_time_after_s``, ``cycle_time_change_pct``,
            ``limits`` (N, W, mm; the force metric), ``before`` and ``after`` (the maxima of
            :meth:`maxima`), ``limits_hold``, ``passes``, ``blocks`` (per block: ``line``,
            ``feed_mm_min``, ``new_feed_mm_min`` (per piece), ``rpm``, ``new_rpm``,
            ``limit``, ``time_before_s``, ``time_after_s``, ``note``) and ``warnings``.
        """
        before = float(self.before.t_s[-1]) if self.before.t_s.size else 0.0
        after = float(self.after.t_s[-1]) if self.after.t_s.size else 0.0
        time_before = _line_times(self.before)
        time_after = _line_times(self.after, self.origin)
        return {
            "cycle_time_before_s": before,
            "cycle_time_after_s": after,
            "cycle_time_change_pct": 100.0 * (after - before) / before if before > 0 else 0.0,
            "limits": {
                "max_force_n": self.limits.max_force_n,
                "force_metric": self.limits.force_metric,
                "max_power_w": self.limits.max_power_w,
                "max_chip_mm": self.limits.max_chip_mm,
            },
            "before": self.maxima(self.before),
            "after": self.maxima(self.after),
            "limits_hold": self.limits_hold,
            "passes": self.passes,
            "blocks": [
                {
                    "line": plan.line,
                    "feed_mm_min": plan.feed_mm_min,
                    "new_feed_mm_min": [p[1] for p in plan.pieces] or [plan.feed_mm_min],
                    "rpm": plan.rpm,
                    "new_rpm": plan.new_rpm,
                    "limit": plan.limit,
                    "time_before_s": time_before.get(plan.line, 0.0),
                    "time_after_s": time_after.get(plan.line, 0.0),
                    "note": plan.note,
                }
                for plan in sorted(self.blocks.values(), key=lambda p: p.line)
            ],
            "warnings": list(self.warnings),
        }


def _check_feed(option: str, feed: float | None) -> None:
    """Refuse a feed option (mm/min) outside :data:`FEED_RANGE_MM_MIN`; ``None`` passes."""
    low, high = FEED_RANGE_MM_MIN
    if feed is not None and not (math.isfinite(feed) and low <= feed <= high):
        raise InputError(f"{option} {feed!r}: give a feed from {low:g} to {high:g} mm/min")


def _line_times(loads: ProgramLoads, origin: Mapping[int, int] | None = None) -> dict[int, float]:
    """Time (s) per source line (of the original program, through ``origin``)."""
    dt = step_durations(loads.t_s)
    out: dict[int, float] = {}
    for line, duration in zip(loads.line.tolist(), dt.tolist(), strict=True):
        key = origin.get(line, 0) if origin is not None else line
        out[key] = out.get(key, 0.0) + duration
    return out


def _violations(loads: ProgramLoads, limits: FeedLimits) -> NDArray[np.bool_]:
    """Feed steps that exceed a limit (by more than 1e-6 relative)."""
    cut = loads.contact & ~loads.rapid
    over = np.zeros(loads.t_s.size, dtype=bool)
    force = loads.peak_n if limits.force_metric == "peak" else loads.mean_n
    for values, limit in (
        (force, limits.max_force_n),
        (loads.power_w, limits.max_power_w),
        (loads.chip_mm, limits.max_chip_mm),
    ):
        if limit is not None:
            over |= values > limit * (1.0 + 1e-6)
    return over & cut


def optimize_program(
    text: str,
    name: str,
    config: MachiningConfig,
    limits: FeedLimits,
    *,
    coefficients: CuttingCoefficients,
    density_per_mm: float,
    cycle_s: float,
    speeds_rpm: Mapping[int, float] | None = None,
    min_feed_mm_min: float | None = None,
    max_feed_mm_min: float | None = None,
    max_factor: float = 2.0,
    air_feed_mm_min: float | None = None,
    passes: int = 6,
) -> OptimizedProgram:
    """Rewrite a program's feeds (and speeds) per block from its simulated engagement.

    Parameters
    ----------
    text
        The NC program.
    name
        Its file name (for messages).
    config
        The :class:`~cnctwin.config.MachiningConfig`: machine (rapid rate, axis speeds), tools
        with geometry, stock (mm), NC setup.
    limits
        The force (N), power (W) and chip thickness (mm) limits.
    coefficients
        Cutting coefficients of the workpiece material (Pa, N/m).
    density_per_mm, cycle_s
        Dexel density (1/mm) and cycle time (s) of the cut.
    speeds_rpm
        Spindle speed per source line, rpm (a stability schedule,
        :func:`scheduled_speeds`); lines not in it keep their speed.
    min_feed_mm_min
        Least feed written, mm/min (> 0).
    max_feed_mm_min
        Most feed written, mm/min; default the slowest linear axis' speed.
    max_factor
        Most a feed may grow over the programmed one (>= 1).
    air_feed_mm_min
        Feed of pieces that cut no material, mm/min; default their programmed feed.
    passes
        Most cuts of the optimised program (>= 1).

    Returns
    -------
    OptimizedProgram
        The program, the plans and the loads before and after.

    Raises
    ------
    InputError
        For an option out of range, or a program that jumps (loops, subroutines).
    NCError
        For a program the interpreter refuses.
    """
    for option, feed in (("--min-feed", min_feed_mm_min), ("--max-feed", max_feed_mm_min)):
        _check_feed(option, feed)
    least = 0.0 if min_feed_mm_min is None else min_feed_mm_min
    if max_feed_mm_min is not None and max_feed_mm_min < least:
        raise InputError(f"--max-feed {max_feed_mm_min!r}: give a feed >= --min-feed, mm/min")
    if not (math.isfinite(max_factor) and max_factor >= 1.0):
        raise InputError(f"--max-factor {max_factor!r}: give a factor >= 1")
    _check_feed("--air-feed", air_feed_mm_min)
    if passes < 1:
        raise InputError(f"passes={passes!r}: give at least 1")
    axes = config.machine.axes
    machine_cap = min(axes.x.max_velocity_mm_min, axes.y.max_velocity_mm_min,
                      axes.z.max_velocity_mm_min)  # fmt: skip
    cap = machine_cap if max_feed_mm_min is None else min(machine_cap, max_feed_mm_min)
    cutters = {tool.number: Cutter.from_tool_config(tool) for tool in config.tools}

    def cut(program: str, segment_ends: str = "kind") -> ProgramLoads:
        segments = list(Interpreter(config.nc_setup()).run_text(program, name))
        stock = DexelStock.box(config.stock.min_mm, config.stock.max_mm, density_per_mm)
        return program_loads(
            segments, stock, cutters, coefficients, limits,
            rapid_mm_min=config.machine.rapid_mm_min, cycle_s=cycle_s, segment_ends=segment_ends,
        )  # fmt: skip

    lines = text.splitlines()
    before = cut(text, "all")
    _check_straight(before.segments, name)
    no_split = bool(_G91.search(_code_text(lines))) or bool(_G901.search(_code_text(lines)))
    settings = _Settings(
        cap, max_factor, min_feed_mm_min, air_feed_mm_min, limits,
        MARGIN_MM + 2.0 * cap * cycle_s / 60.0, no_split,
    )  # fmt: skip
    plans = _plan(lines, before, settings, speeds_rpm or {})
    style = comment_style(lines)
    out, origin = _write(lines, before.segments, plans, style)
    after = cut(out)
    done = 1
    while done < passes and _lower(plans, after, origin, limits, settings):
        out, origin = _write(lines, before.segments, plans, style)
        after = cut(out)
        done += 1
    result = OptimizedProgram(out + "\n", limits, plans, before, after, done)
    result.origin = {k: v[0] for k, v in origin.items()}
    over = _violations(after, limits)
    if over.any():
        bad = sorted({result.origin.get(int(k), 0) for k in after.line[over]})
        result.warnings.append(
            f"{name}: {int(over.sum())} steps still exceed a limit after {done} cuts, at "
            f"source lines {', '.join(str(b) for b in bad[:20])}"
            + (" ..." if len(bad) > 20 else "")
        )
    stuck = [p.line for p in plans.values() if p.limit == "min-feed"]
    if stuck:
        result.warnings.append(
            f"{name}: at lines {', '.join(map(str, stuck[:20]))} a limit is not met even at "
            "the least feed (--min-feed, default a tenth of the programmed feed): the edge "
            "force or the engagement alone exceeds it"
        )
    return result


@dataclass(frozen=True)
class _Settings:
    cap_mm_min: float
    max_factor: float
    min_feed_mm_min: float | None

    def floor(self, programmed_mm_min: float) -> float:
        """The least feed of a block programmed at ``programmed_mm_min``, mm/min."""
        if self.min_feed_mm_min is not None:
            return self.min_feed_mm_min
        return MIN_FEED_FRACTION * programmed_mm_min

    air_feed_mm_min: float | None
    limits: FeedLimits
    margin_mm: float
    no_split: bool


def _code_text(lines: list[str]) -> str:
    return "\n".join(re.sub(r"\([^)]*\)|;.*$", "", raw) for raw in lines)


def _check_straight(segments: tuple[Segment, ...], name: str) -> None:
    """Refuse a program whose motion does not follow its text (loops, subroutines, files)."""
    last = 0
    for seg in segments:
        if seg.file and seg.file != name:
            raise InputError(
                f"{name}: line {last} calls {seg.file}: cnctwin optimize rewrites programs that "
                "run top to bottom in one file (no subprograms)"
            )
        if seg.line < last:
            raise InputError(
                f"{name}: line {seg.line} runs again after line {last} (a loop, subroutine or "
                "jump): cnctwin optimize rewrites programs that run top to bottom"
            )
        last = seg.line


def _fractions(seg: Segment, tcp: NDArray[np.float64]) -> NDArray[np.float64]:
    """Path fraction (0 to 1) of each tool-tip position on a segment."""
    offset = np.asarray(seg.state.tool_offset_mm)
    points = tcp + offset
    start = np.asarray(seg.start_mm)
    end = np.asarray(seg.end_mm)
    if seg.kind == MotionKind.ARC and seg.center_mm is not None:
        _, a0, sweep = arc_sweep_rad(seg.start_mm, seg.end_mm, seg.center_mm, seg.turns,
                                     seg.state.plane)  # fmt: skip
        centre = np.asarray(seg.center_mm)
        angle = np.arctan2(points[:, 1] - centre[1], points[:, 0] - centre[0])
        turned = np.mod((angle - a0) * math.copysign(1.0, sweep), 2.0 * math.pi)
        span = abs(sweep)
        # A point just before the start reads as nearly a turn: it is before the start.
        turned = np.where(turned > span + 0.5 * (2.0 * math.pi - span), turned - 2 * math.pi,
                          turned)  # fmt: skip
        frac = turned / span
        # Along the path a fraction never goes back (a full circle's end reads as 0).
        back = frac < np.maximum.accumulate(frac) - 0.5
        frac = np.where(back, frac + 2.0 * math.pi / span, frac)
    else:
        d = end - start
        length2 = float(d @ d)
        frac = (points - start) @ d / length2 if length2 > 0 else np.ones(len(points))
    out: NDArray[np.float64] = np.clip(frac, 0.0, 1.0)
    if out.size:
        out[-1] = 1.0
    return out


def _plan(
    lines: list[str], loads: ProgramLoads, s: _Settings, speeds: Mapping[int, float]
) -> dict[int, BlockPlan]:
    """The plan of every feed block from the first cut."""
    by_line: dict[int, list[Segment]] = {}
    for seg in loads.segments:
        by_line.setdefault(seg.line, []).append(seg)
    rows_of: dict[int, list[int]] = {}
    for k, line in enumerate(loads.line.tolist()):
        rows_of.setdefault(line, []).append(k)
    plans: dict[int, BlockPlan] = {}
    for line, segs in by_line.items():
        feeds = [g for g in segs if g.kind in (MotionKind.LINEAR, MotionKind.ARC)]
        if not feeds:
            continue
        first = feeds[0]
        rpm = first.spindle_rpm
        new_rpm = rpm if first.state.css else float(speeds.get(line, rpm))
        plan = BlockPlan(line, first.feed_mm_min, rpm, new_rpm)
        plans[line] = plan
        block = read_block(lines[line - 1]) if 0 < line <= len(lines) else None
        if len(feeds) != len(segs):
            plan.note = "rapids and feeds in one block (a canned cycle): kept"
        elif first.state.feed_mode != FeedMode.UNITS_PER_MINUTE:
            plan.note = f"G{int(first.state.feed_mode)} feed: kept"
        elif block is None:
            plan.note = "expressions or keywords in the block: kept"
        elif new_rpm <= 0.0:
            plan.note = "spindle stopped: kept"
        elif any(block.has(a) for a in "ABCUVW"):
            plan.note = "rotary or extra axes in the block: kept"
        if plan.note or block is None:
            plan.new_rpm = rpm
            continue
        rows = np.asarray(rows_of.get(line, []), dtype=np.int64)
        plan.split = (
            len(segs) == 1 and not s.no_split and _splittable(first, block)
            and first.length_mm >= 2.0 * MIN_PIECE_MM
        )  # fmt: skip
        plan.pieces = _pieces(plan, first, rows, loads, s)
    return plans


def _splittable(seg: Segment, block: Block) -> bool:
    state = seg.state
    if state.cutter_comp != CutterComp.OFF or state.xy_rotation_deg:
        return False
    if seg.kind == MotionKind.ARC:
        return state.plane == Plane.XY and abs(seg.turns) <= 1 and not block.has("R")
    return True


def _allowed(
    rows: NDArray[np.int64], loads: ProgramLoads, rpm: float, limits: FeedLimits
) -> tuple[NDArray[np.float64], list[str]]:
    """Feed (mm/min) each row allows at ``rpm``, and the limit that sets it."""
    per = np.column_stack((
        loads.fz_force_mm[rows],
        loads.fz_chip_mm[rows],
        loads.fz_power_mm(limits.max_power_w, rows, rpm),
    ))  # fmt: skip
    which = np.argmin(per, axis=1)
    fz = per[np.arange(rows.size), which]
    return fz * loads.flutes[rows] * rpm, [_LIMIT_NAMES[int(w)] for w in which]


def _pieces(
    plan: BlockPlan, seg: Segment, rows: NDArray[np.int64], loads: ProgramLoads, s: _Settings
) -> list[tuple[float, float, str]]:
    """Pieces ``(end fraction, feed, limit)`` of a block."""
    programmed = plan.feed_mm_min
    top = min(s.cap_mm_min, programmed * s.max_factor)
    top_limit = "machine" if s.cap_mm_min <= programmed * s.max_factor else "factor"
    if s.air_feed_mm_min is None:
        air = programmed
    else:
        air = min(s.air_feed_mm_min, s.cap_mm_min)
    floor = s.floor(programmed)
    cutting = loads.contact[rows] & ~loads.rapid[rows]
    allowed, names = _allowed(rows, loads, plan.new_rpm, s.limits)
    length = seg.length_mm
    if not plan.split or length <= 0.0:
        if not cutting.any():
            return [(1.0, air, "air")]
        k = int(np.argmin(np.where(cutting, allowed, np.inf)))
        return [(1.0, *_bounded(float(allowed[k]), names[k], top, top_limit, floor))]
    frac = np.maximum.accumulate(_fractions(seg, loads.tcp_mm[rows]))
    lo = np.concatenate(([0.0], frac[:-1]))
    pad = s.margin_mm / length
    hit = np.flatnonzero(cutting)
    bounded = [_bounded(float(allowed[k]), names[k], top, top_limit, floor) for k in hit]
    cut_lo = np.maximum(lo[hit] - pad, 0.0)
    cut_hi = np.minimum(frac[hit] + pad, 1.0)
    cut_feed = np.array([b[0] for b in bounded])
    bounds = np.unique(np.concatenate(([0.0, 1.0], cut_lo, cut_hi)))
    elements = []
    # The cuts are sorted along the path (both ends), so the cuts over a point are a run.
    for a, b in zip(bounds[:-1].tolist(), bounds[1:].tolist(), strict=True):
        if b - a <= 1e-12:
            continue
        middle = 0.5 * (a + b)
        first = int(np.searchsorted(cut_hi, middle, side="right"))
        last = int(np.searchsorted(cut_lo, middle, side="left"))
        if last > first:
            k = first + int(np.argmin(cut_feed[first:last]))
            elements.append([a, b, float(cut_feed[k]), bounded[k][1]])
        else:
            elements.append([a, b, air, "air"])
    step = MIN_PIECE_MM / length
    merged: list[list[Any]] = []
    for a, b, feed, name in elements:
        if merged:
            cur = merged[-1]
            near = max(feed, cur[2]) <= (1.0 + FEED_STEP) * min(feed, cur[2])
            if near or cur[1] - cur[0] < step:
                if feed < cur[2]:
                    cur[2], cur[3] = feed, name
                cur[1] = b
                continue
        merged.append([a, b, feed, name])
    while len(merged) > 1 and merged[-1][1] - merged[-1][0] < step:
        tail = merged.pop()
        if tail[2] < merged[-1][2]:
            merged[-1][2:] = tail[2:]
        merged[-1][1] = tail[1]
    while len(merged) > MAX_PIECES:
        ratios = [max(x[2], y[2]) / min(x[2], y[2]) for x, y in zip(merged, merged[1:],
                                                                   strict=False)]  # fmt: skip
        k = int(np.argmin(ratios))
        x, y = merged[k], merged.pop(k + 1)
        if y[2] < x[2]:
            x[2:] = y[2:]
        x[1] = y[1]
    return [(float(b), float(feed), str(name)) for _, b, feed, name in merged]


def _bounded(
    allowed: float, name: str, top: float, top_limit: str, floor: float
) -> tuple[float, str]:
    """A row's feed between the least feed and the caps, and the limit that sets it."""
    if allowed > top:
        return top, top_limit
    if allowed < floor:
        return floor, "min-feed"
    return allowed, name


def _lower(
    plans: dict[int, BlockPlan],
    after: ProgramLoads,
    origin: Mapping[int, tuple[int, int]],
    limits: FeedLimits,
    s: _Settings,
) -> bool:
    """Lower the pieces whose steps exceed a limit to what those steps allow; whether any
    piece changed."""
    over = np.flatnonzero(_violations(after, limits))
    changed = False
    for k in over.tolist():
        source = origin.get(int(after.line[k]))
        if source is None or source[0] not in plans:
            continue
        plan = plans[source[0]]
        if not plan.pieces:
            continue
        rows = np.array([k])
        allowed, names = _allowed(rows, after, plan.new_rpm, limits)
        index = source[1]
        end, feed, _ = plan.pieces[index]
        new = min(float(allowed[0]) * 0.97, feed * 0.95)
        if new < s.floor(plan.feed_mm_min):
            new, name = s.floor(plan.feed_mm_min), "min-feed"
        else:
            name = names[0]
        if new < feed:
            plan.pieces[index] = (end, new, name)
            changed = True
    return changed


def _program_units(seg: Segment, value_mm: float) -> float:
    return value_mm / _MM_PER_INCH if seg.state.units == "inch" else value_mm


def _feed_text(seg: Segment, feed_mm_min: float, programmed_mm_min: float) -> tuple[float, str]:
    """The feed in program units, rounded down to 3 significant digits (never below the
    programmed feed where it is at least that), and its text."""
    if abs(feed_mm_min - programmed_mm_min) <= 1e-9 * programmed_mm_min:
        value = seg.state.programmed_feed
        return value, format_number(value, 6)
    value = _program_units(seg, feed_mm_min)
    q = 10.0 ** (math.floor(math.log10(value)) - 2) if value > 0 else 1.0
    rounded = math.floor(value / q * (1 + 1e-12)) * q
    if feed_mm_min >= programmed_mm_min:
        rounded = max(rounded, seg.state.programmed_feed)
    decimals = max(0, -int(math.floor(math.log10(q)))) if q < 1 else 0
    return rounded, format_number(rounded, decimals)


def _speed_text(rpm: float) -> tuple[float, str]:
    value = float(round(rpm))
    return value, format_number(value, 0)


def _piece_words(seg: Segment, plan: BlockPlan) -> list[dict[str, str]]:
    """Axis and centre words (program units) of each piece's end."""
    inch = seg.state.units == "inch"
    decimals = 5 if inch else 4

    def prog(point: tuple[float, float, float]) -> NDArray[np.float64]:
        p = np.asarray(seg.state.to_program(point))
        return p / _MM_PER_INCH if inch else p

    start = prog(seg.start_mm)
    end = prog(seg.end_mm)
    out = []
    previous = start
    if seg.kind == MotionKind.ARC and seg.center_mm is not None:
        centre = prog(seg.center_mm)
        radius, a0, sweep = arc_sweep_rad(tuple(start), tuple(end), tuple(centre), seg.turns,
                                          Plane.XY)  # fmt: skip
        for frac, _, _ in plan.pieces:
            angle = a0 + frac * sweep
            point = np.array([centre[0] + radius * math.cos(angle),
                              centre[1] + radius * math.sin(angle),
                              start[2] + frac * (end[2] - start[2])])  # fmt: skip
            if frac >= 1.0:
                point = end
            words = {"X": format_number(point[0], decimals), "Y": format_number(point[1], decimals)}
            if abs(end[2] - start[2]) > 1e-9:
                words["Z"] = format_number(point[2], decimals)
            words["I"] = format_number(centre[0] - previous[0], decimals)
            words["J"] = format_number(centre[1] - previous[1], decimals)
            out.append(words)
            previous = np.array([float(words["X"]), float(words["Y"]), point[2]])
        return out
    moving = [k for k in range(3) if abs(end[k] - start[k]) > 1e-12]
    for frac, _, _ in plan.pieces:
        point = start + frac * (end - start)
        out.append({"XYZ"[k]: format_number(point[k], decimals) for k in moving})
    return out


def _write(
    lines: list[str], segments: tuple[Segment, ...], plans: Mapping[int, BlockPlan], style: str
) -> tuple[str, dict[int, tuple[int, int]]]:
    """The program with the plans written, and the origin (source line, piece) of each
    output line."""
    first_feed: dict[int, Segment] = {}
    for seg in segments:
        if seg.kind in (MotionKind.LINEAR, MotionKind.ARC):
            first_feed.setdefault(seg.line, seg)
    any_speed = any(p.new_rpm != p.rpm for p in plans.values())
    out: list[str] = []
    origin: dict[int, tuple[int, int]] = {}
    modal_f: float | None = None
    modal_s: float | None = None

    def emit(text: str, source: int, piece: int) -> None:
        out.append(text)
        origin[len(out)] = (source, piece)

    for number, raw in enumerate(lines, start=1):
        block = read_block(raw)
        found = first_feed.get(number)
        plan = plans.get(number)
        if found is None:
            emit(raw, number, 0)
            if block is None:
                if re.search(r"f", _code_text([raw]), re.IGNORECASE):
                    modal_f = None
                if re.search(r"s", _code_text([raw]), re.IGNORECASE):
                    modal_s = None
            else:
                modal_f = block.value("F") if block.has("F") else modal_f
                modal_s = block.value("S") if block.has("S") else modal_s
            continue
        seg = found
        want_s: tuple[float, str] | None = None
        if any_speed and not seg.state.css:
            want_s = _speed_text(plan.new_rpm if plan is not None else seg.spindle_rpm)
        if plan is None or not plan.pieces or block is None:
            want_f = seg.state.programmed_feed
            if block is None:
                need = []
                if modal_f is None or abs(modal_f - want_f) > 1e-9 * max(want_f, 1.0):
                    need.append("F" + format_number(want_f, 6))
                if want_s is not None and modal_s != want_s[0]:
                    need.append("S" + want_s[1])
                if need:
                    emit(" ".join(need), number, 0)
                emit(raw, number, 0)
                modal_f = want_f
                if want_s is not None:
                    modal_s = want_s[0]
                continue
            values = {}
            if block.has("F") or modal_f is None or abs(modal_f - want_f) > 1e-9 * want_f:
                values["F"] = format_number(want_f, 6)
            if want_s is not None and (block.has("S") or modal_s != want_s[0]):
                values["S"] = want_s[1]
            emit(set_words(block, values) if values else raw, number, 0)
            modal_f = want_f
            modal_s = want_s[0] if want_s is not None else (
                block.value("S") if block.has("S") else modal_s)  # fmt: skip
            continue
        feeds = [_feed_text(seg, feed, plan.feed_mm_min) for _, feed, _ in plan.pieces]
        if len(plan.pieces) == 1:
            values = {}
            value, text = feeds[0]
            if block.has("F") or modal_f is None or abs(modal_f - value) > 1e-9 * value:
                values["F"] = text
            if want_s is not None and (block.has("S") or modal_s != want_s[0]):
                values["S"] = want_s[1]
            emit(set_words(block, values) if values else raw, number, 0)
            modal_f = value
            if want_s is not None:
                modal_s = want_s[0]
            elif block.has("S"):
                modal_s = block.value("S")
            continue
        words = _piece_words(seg, plan)
        pieces = []
        for k, (value, text) in enumerate(feeds):
            others = {}
            if (
                modal_f is None
                or abs(modal_f - value) > 1e-9 * value
                or (k == 0 and block.has("F"))
            ):
                others["F"] = text
            modal_f = value
            if k == 0 and want_s is not None and (block.has("S") or modal_s != want_s[0]):
                others["S"] = want_s[1]
            pieces.append((words[k], others))
        if want_s is not None:
            modal_s = want_s[0]
        elif block.has("S"):
            modal_s = block.value("S")
        lines_out = split_block(
            block, pieces, style, f"cnctwin optimize: line {number} in {len(pieces)} pieces"
        )
        emit(lines_out[0], number, 0)
        for k, text in enumerate(lines_out[1:]):
            emit(text, number, k)
    return "\n".join(out), origin


def scheduled_speeds(roadmap: StabilityRoadmap) -> dict[int, float]:
    """The spindle speed (rpm) a stability roadmap schedules per source line, where it differs
    from the programmed one.

    A line the roadmap cuts in several segments takes the schedule of its deepest (largest
    ``ap``) segment with lobes; a line without a stable speed keeps its programmed one (Ward
    2021, sec. 3.4: the roadmap's schedule; :mod:`cnctwin.dynamics.roadmap`).

    Parameters
    ----------
    roadmap
        The program's roadmap (:func:`cnctwin.dynamics.program_roadmap`).

    Returns
    -------
    dict
        Scheduled speed in rpm by source line.
    """
    deepest: dict[int, Any] = {}
    for seg in roadmap.segments:
        if seg.lobes < 0:
            continue
        if seg.line not in deepest or seg.ap_mm > deepest[seg.line].ap_mm:
            deepest[seg.line] = seg
    return {
        line: float(seg.scheduled_rpm)
        for line, seg in deepest.items()
        if seg.has_stable_speed and not seg.programmed_stable
    }
