"""Running an NC program through the stock: the offline twin of the cut.

The interpreted program is sampled at the cycle time (:mod:`cnctwin.nc.sampler`); at each
sample the virtual tool cuts the tri-dexel stock (:func:`cnctwin.geometry.cut`, the
discrete-position method of Heide 2025) and the engagement of that step is recorded. This is
the loop of the twin cycle (docs/twin.md: kinematics, cut, engagement) without a machine.

Attribution: the sampler also samples segment ends (``segment_ends``), so that the material a
move leaves between its last cycle and its end point is cut by a step of that move, not by the
first step of the next one (a rapid retract after a cut would otherwise "cut" it, a collision
that is not). By default every end is sampled but the tangent junction of two feed moves of one
tool: no step spans a rapid's or a dwell's start or end, nor a corner between two feed moves
(a step spanning a corner cuts the chord and leaves a sliver of the corner on the wall, which a
later pass along that wall, the next layer, would read as a cut of the wall's whole height: a
single-step force spike); across a tangent junction a step may span the two moves (the cut of
at most one cycle booked to the later line). ``segment_ends="all"`` samples every block's end:
every step then belongs to one line, at up to one extra cut per block (2.3 times the steps of
CAMotics' ``bear.nc``, whose tessellated surfaces turn at nearly every block: 2.2 times with
the default). An end step lies between two cycle times: ``t_s`` is its
true time, and each row stands for the time since the row before (:func:`step_durations`);
the rates (``mrr_mm3_s``, ``feed_mm_min``) are per that time.

Units as in the NC and geometry layers: mm, mm/min, rpm, s (names say so).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from cnctwin.errors import NCError
from cnctwin.geometry import Cutter, DexelStock, Engagement, cut_path
from cnctwin.memory import check_memory
from cnctwin.nc import AxisLimits, MotionKind, Segment, TrajectorySampler

__all__ = ["COLUMNS", "CutStep", "StepTable", "simulate_cut", "step_durations"]

#: Columns of a :class:`StepTable`, with their units.
COLUMNS = (
    "t_s",
    "x_mm",
    "y_mm",
    "z_mm",
    "line",
    "tool",
    "rapid",
    "spindle_rpm",
    "path_speed_mm_min",
    "feed_per_tooth_mm",
    "contact",
    "removed_mm3",
    "mrr_mm3_s",
    "ae_mm",
    "ap_mm",
    "feed_mm_min",
    "h_mean_mm",
    "h_max_mm",
    "bottom_contact",
    "above_flutes",
)


@dataclass(frozen=True, slots=True)
class CutStep:
    """One simulated step, handed to an observer (e.g. the force model).

    Attributes
    ----------
    index
        Step number from 0.
    t_s
        Time, s.
    tcp_mm
        Tool tip, machine coordinates, mm.
    line
        Source line of the NC program.
    tool
        Tool number.
    cutter
        The tool's geometry.
    spindle_rpm
        Spindle speed, rpm.
    feed_per_tooth_mm
        Feed per tooth from the path speed, mm.
    engagement
        The engagement of this step.
    """

    index: int
    t_s: float
    tcp_mm: tuple[float, float, float]
    line: int
    tool: int
    cutter: Cutter
    spindle_rpm: float
    feed_per_tooth_mm: float
    engagement: Engagement


@dataclass(slots=True)
class StepTable:
    """Per-step results as columns (see :data:`COLUMNS`), filled chunk by chunk.

    Attributes
    ----------
    columns
        The blocks of each column.
    row_bytes
        Memory a row costs the computation that fills the table, bytes: the table's own
        8 per column by default, more where the rows feed further arrays. The rows so far
        times this are checked against the memory limit (:mod:`cnctwin.memory`) before
        each block is kept: the number of positions of a program (its duration over the cycle
        time) is known only once it has been sampled.
    """

    columns: dict[str, list[NDArray[np.float64]]] = field(
        default_factory=lambda: {name: [] for name in COLUMNS}
    )
    row_bytes: int = 8 * len(COLUMNS)
    rows: int = 0

    def append(self, block: NDArray[np.float64]) -> None:
        """Append an (n, len(COLUMNS)) block of rows.

        Raises
        ------
        cnctwin.errors.ConfigError
            When the rows would exceed the memory limit: the program is too long for its
            cycle time.
        """
        rows = self.rows + len(block)
        t_s = float(block[-1, 0]) if len(block) else 0.0
        check_memory(
            f"the program at this cycle time is more than {rows:.3g} positions by t = {t_s:.6g} s",
            float(rows) * self.row_bytes,
            lambda fraction: (
                f"at most {rows * fraction:.3g} positions fit: use a longer cycle time "
                "(cycle_ms, --cycle-ms) or a shorter program"
            ),
        )
        for k, name in enumerate(COLUMNS):
            self.columns[name].append(block[:, k].copy())
        self.rows = rows

    def column(self, name: str) -> NDArray[np.float64]:
        """One column over all steps."""
        parts = self.columns[name]
        return np.concatenate(parts) if parts else np.empty(0)

    def __len__(self) -> int:
        return self.rows


def step_durations(t_s: NDArray[np.float64]) -> NDArray[np.float64]:
    """The time each row of a step table stands for: since the row before, s (0 for the first).

    Parameters
    ----------
    t_s
        (n,) row times, s, increasing (the ``t_s`` column).

    Returns
    -------
    numpy.ndarray
        (n,) durations, s; they add up to the last row's time (the program's duration).
    """
    return np.diff(t_s, prepend=t_s[:1]) if t_s.size else np.empty(0)


def simulate_cut(
    segments: Iterable[Segment],
    stock: DexelStock,
    cutters: Mapping[int, Cutter],
    *,
    rapid_mm_min: float,
    cycle_s: float = 0.0125,
    limits: AxisLimits | None = None,
    on_step: Callable[[CutStep], None] | None = None,
    segment_ends: str = "kind",
) -> Iterator[NDArray[np.float64]]:
    """Cut the stock along a program, yielding per-step rows chunk by chunk.

    Parameters
    ----------
    segments
        The interpreted program (consumed lazily).
    stock
        The stock, cut in place.
    cutters
        Geometry of every tool the program uses, by tool number.
    rapid_mm_min
        The machine's rapid rate, mm/min.
    cycle_s
        Cycle time, s.
    limits
        Optional axis acceleration limits for the sampler.
    on_step
        Called with every step that touches material (a :class:`CutStep`).
    segment_ends
        Which segment ends are steps of their own: ``"kind"`` (all but the junction of two
        feed moves of one tool), ``"all"`` (every segment) or ``"none"`` (cycles only, as the
        live twin samples); see the module notes and
        :class:`~cnctwin.nc.TrajectorySampler`.

    Yields
    ------
    numpy.ndarray
        (n, len(COLUMNS)) rows, in the order of :data:`COLUMNS`: one per cycle and one at each
        sampled segment end (then the last row is the program's end, ``t_s`` its duration);
        the rates of a row are per the time since the row before (the cycle for the first row).

    Raises
    ------
    cnctwin.errors.NCError
        When the program moves a tool that has no geometry, naming the tool and the line.
    """
    sampler = TrajectorySampler(
        segments,
        rapid_mm_min=rapid_mm_min,
        cycle_s=cycle_s,
        limits=limits,
        segment_ends=segment_ends,
    )
    previous: NDArray[np.float64] | None = None
    previous_tool = -1
    index = 0
    rapid = float(MotionKind.RAPID)
    t_before = math.nan
    for chunk in sampler:
        n = chunk.t_s.size
        # Rates per the time each row stands for (the cut divides by the cycle time).
        dt = np.diff(chunk.t_s, prepend=t_before if index else chunk.t_s[0] - cycle_s)
        scale = cycle_s / dt
        t_before = float(chunk.t_s[-1])
        rows = np.zeros((n, len(COLUMNS)))
        rows[:, 0] = chunk.t_s
        rows[:, 1:4] = chunk.tcp_mm
        rows[:, 4] = chunk.line
        rows[:, 5] = chunk.tool
        rows[:, 6] = chunk.kind == rapid
        rows[:, 7] = chunk.spindle_rpm
        rows[:, 8] = chunk.path_speed_mm_min
        tools = chunk.tool.astype(np.int64)
        # Runs of consecutive positions with the same tool: one compiled cut per run.
        breaks = np.flatnonzero(np.diff(tools)) + 1
        for lo, hi in zip(
            np.concatenate(([0], breaks)), np.concatenate((breaks, [n])), strict=True
        ):
            tool = int(tools[lo])
            cutter = cutters.get(tool)
            if cutter is None:
                raise NCError(
                    f"tool T{tool} has no geometry: add it to the configuration's [[tools]] "
                    "with its kind, diameter_mm, flute_length_mm and flutes",
                    line=int(chunk.line[lo]),
                )
            if tool != previous_tool:
                previous = None
                previous_tool = tool
            rpm = chunk.spindle_rpm[lo:hi]
            speed = chunk.path_speed_mm_min[lo:hi]
            fz = np.divide(speed, rpm * cutter.flutes, out=np.zeros(hi - lo), where=rpm > 0.0)
            positions = chunk.tcp_mm[lo:hi]
            path = cut_path(stock, cutter, positions, previous, fz, cycle_s)
            previous = positions[-1]
            run = rows[lo:hi]
            run[:, 9] = fz
            hit = path.contact
            rate = scale[lo:hi]
            feed = np.where(np.isfinite(path.feed_mm_min), path.feed_mm_min * rate, 0.0)
            run[hit, 10:] = np.column_stack(
                (
                    np.ones(int(hit.sum())),
                    path.removed_volume_mm3[hit],
                    path.mrr_mm3_s[hit] * rate[hit],
                    path.ae_mm[hit],
                    path.ap_mm[hit],
                    feed[hit],
                    path.h_mean_mm[hit],
                    path.h_max_mm[hit],
                    path.bottom_contact[hit],
                    path.above_flutes[hit],
                )
            )
            if on_step is not None:
                for k in np.flatnonzero(hit):
                    i = lo + int(k)
                    position = chunk.tcp_mm[i]
                    on_step(
                        CutStep(
                            index + i,
                            float(chunk.t_s[i]),
                            (float(position[0]), float(position[1]), float(position[2])),
                            int(chunk.line[i]),
                            tool,
                            cutter,
                            float(rpm[k]),
                            float(fz[k]),
                            path.engagement(int(k)),
                        )
                    )
        index += n
        yield rows
