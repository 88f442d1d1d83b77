"""Stability roadmap: stable spindle speeds along a program's engagement, and a speed schedule.

Ward 2021, sec. 3.4 (Fig. 4 and 12): the stability roadmap (SRM) is the stability lobe diagram
evaluated along the toolpath, one cutter-workpiece engagement after the other; it shows, per
position, which spindle speeds cut stably, and a controller picks a stable speed near the
programmed one (their 18700 rpm, chattering at about 4.6 kHz, became 19675 rpm).

Here the engagement comes from an engagement map (:class:`cnctwin.geometry.engagement_map.
EngagementMap`, Ward 2021 sec. 3.2) built on the program. Its locations in contact are grouped
into segments: runs of consecutive cutting (not rapid) locations of one program line and tool.
Per segment the stability problem is the worst engagement the segment meets, up to a quantile
``q`` (default 0.95): the axial depth ``ap`` and width ``ae`` exceeded at no more than 5 % of
its locations, and the immersion from the entry angle that 95 % of the locations reach or
exceed to the exit angle that 95 % reach or stay below (angles in the frame of
:mod:`cnctwin.mechanics.engagement`). The quantile keeps a single location from deciding: the
discrete-position cut of the map reports the full wall height for one location where a pass
retraces the previous one (the KIT notch program: 1 of 100 locations of a 6 mm pass at 12 mm);
``q = 1`` takes the plain worst case. A segment whose contact is at the flat bottom only (a
plunge: no angles) has no lobes and is reported so.

For each segment's immersion the critical depth ``a_lim(n)`` over a spindle-speed grid comes
from the zero-order approximation or the semi-discretization
(:mod:`cnctwin.dynamics.stability`; segments of equal teeth and angles share one
computation). With a margin factor ``m`` (default 1.2):

- the *stable ranges* are the runs of grid speeds with ``a_lim(n) >= m ap``;
- the *scheduled speed* is the programmed speed if ``a_lim`` there is ``>= m ap``, else the
  grid speed nearest to the programmed one that satisfies it (a tie goes to the higher
  speed); none when no grid speed does. The grid spans the machine's speed limits, so the
  schedule stays inside them; its resolution is the grid step.

Modes per tool: one set of modes (and coefficients) for every tool, or a set per tool
number; the segments of a tool without modes (a drill, say) get no lobes and keep their
programmed speed (``has_modes`` False), never rescheduled.

With the semi-discretization the lobes are computed coarse to fine: the SDM at
``sdm_points`` speeds spread over the grid (default :data:`DEFAULT_SDM_POINTS`), and between
them the ZOA's lobes (cheap at every grid speed) scaled by the SDM/ZOA ratio interpolated
linearly; the angles are widened outward to whole 3 degree steps so that nearly equal
immersions share one computation. The decisions are computed: the critical depth at each
programmed speed, and at each candidate speed whose depth was interpolated before it is
scheduled (up to 12, then the nearest computed stable speed). :func:`program_roadmap`'s
default SDM grid starts at :data:`SDM_LOWEST_FRACTION` of the lowest programmed speed.

Units: mm, rpm, Hz and rad in the names at this level (the map's units); SI inside the lobe
computations.
"""

from __future__ import annotations

import logging
import math
import os
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal, Protocol

import numpy as np

from cnctwin.dynamics.stability import (
    MillingProcess,
    SdmCost,
    ToolDynamics,
    sdm_cost,
    sdm_lobes,
    zoa_lobes,
)
from cnctwin.errors import ConfigError, InputError, NCError
from cnctwin.geometry import Cutter, DexelStock, EngagementMap
from cnctwin.mechanics import CuttingCoefficients

if TYPE_CHECKING:
    from cnctwin.config import MachiningConfig
    from cnctwin.dynamics.config import StabilityConfig
    from cnctwin.nc import Segment

__all__ = [
    "DEFAULT_MARGIN",
    "DEFAULT_SDM_POINTS",
    "RPM_STEP",
    "SDM_LOWEST_FRACTION",
    "EngagementLobes",
    "RoadmapProgress",
    "RoadmapSegment",
    "StabilityRoadmap",
    "engagement_segments",
    "program_roadmap",
    "stability_roadmap",
]

logger = logging.getLogger(__name__)

#: Default margin: the scheduled speed's critical depth is at least 1.2 times the depth of cut.
DEFAULT_MARGIN = 1.2
#: Spacing of :func:`program_roadmap`'s default speed grid, rpm (the schedule's resolution).
RPM_STEP = 10.0
#: Default number of speeds at which :func:`stability_roadmap` computes semi-discretization
#: lobes (the coarse-to-fine search of the module notes).
DEFAULT_SDM_POINTS = 20
#: SDM: the default grid of :func:`program_roadmap` starts at this fraction of the lowest
#: programmed speed (of the tools with modes): lower speeds halve the metal removal rate
#: and cost the semi-discretization the most steps.
SDM_LOWEST_FRACTION = 0.5
_RPM = math.pi / 30.0  # rad/s per rpm
_ANGLE_DIGITS = 3  # ZOA: segments whose angles agree to 1 mrad share their lobes
_ANGLE_STEP = 10.0**-_ANGLE_DIGITS
_SDM_ANGLE_STEP = math.radians(3.0)  # SDM: angles widened to whole 3 degree steps
_CHECKS = 12  # SDM: interpolated candidate speeds computed before one is scheduled
_BATCH = 8  # SDM: speeds per call of the solver (progress granularity)
#: Tool kinds that mill (:data:`cnctwin.config.tools.CutterKind`): one stability file for
#: every tool gives its modes to these only; a drill or tap has none.
_MILLING_KINDS = frozenset({"flat", "ball", "bull", "conical", "snub"})

Method = Literal["zoa", "sdm"]
#: Critical depth (mm) and chatter frequency (Hz) per speed (rpm) of one engagement.
_Solver = Callable[[MillingProcess, np.ndarray], tuple[np.ndarray, np.ndarray]]


@dataclass(frozen=True)
class RoadmapSegment:
    """One segment of the roadmap: a run of cutting locations of one program line and tool.

    Attributes
    ----------
    line
        Source line of the NC program.
    tool
        Tool number.
    start_s_mm, end_s_mm
        Path parameter of the first and last location in mm (the map's ``s``).
    locations
        Number of map locations in the segment.
    ap_mm
        Axial depth of cut of the segment (its q-quantile over the locations), mm.
    ae_mm
        Radial depth of cut (width) of the segment (its q-quantile), mm.
    entry_rad, exit_rad
        Immersion of the segment (the (1 - q)-quantile of the entry and the q-quantile of the
        exit angles) in rad, rounded to 1 mrad; NaN for bottom contact only.
    programmed_rpm
        Programmed spindle speed, rpm.
    lobes
        Index into :attr:`StabilityRoadmap.lobes` of the segment's lobe diagram; -1 without.
    programmed_critical_depth_mm
        Critical depth at the programmed speed, mm (``inf``: none found; NaN without lobes).
    programmed_chatter_hz
        Chatter frequency at the programmed speed, Hz (NaN where none).
    stable_ranges_rpm
        Runs ``(low, high)`` of grid speeds whose critical depth is at least margin x ap.
    scheduled_rpm
        Scheduled spindle speed, rpm: the programmed one if stable with the margin, else the
        nearest such grid speed; NaN if there is none (or no lobes).
    scheduled_critical_depth_mm
        Critical depth at the scheduled speed, mm (NaN if none).
    has_modes
        False for a segment of a tool without modes (a drill, say): no lobes, the programmed
        speed unchanged (``scheduled_rpm`` is the programmed speed).
    """

    line: int
    tool: int
    start_s_mm: float
    end_s_mm: float
    locations: int
    ap_mm: float
    ae_mm: float
    entry_rad: float
    exit_rad: float
    programmed_rpm: float
    lobes: int
    programmed_critical_depth_mm: float
    programmed_chatter_hz: float
    stable_ranges_rpm: tuple[tuple[float, float], ...]
    scheduled_rpm: float
    scheduled_critical_depth_mm: float
    has_modes: bool = True

    @property
    def programmed_stable(self) -> bool:
        """Whether the programmed speed is kept (stable with the margin)."""
        return self.scheduled_rpm == self.programmed_rpm

    @property
    def has_stable_speed(self) -> bool:
        """Whether a stable speed (with the margin) exists within the limits."""
        return math.isfinite(self.scheduled_rpm)


@dataclass(frozen=True, eq=False)
class EngagementLobes:
    """The lobe diagram of one engagement (teeth and immersion angles) on the speed grid.

    Attributes
    ----------
    teeth
        Number of teeth.
    entry_rad, exit_rad
        Immersion angles in rad.
    critical_depth_mm
        Critical depth per grid speed in mm (``inf`` where none was found).
    chatter_frequency_hz
        Chatter frequency per grid speed in Hz (NaN where none or not computed).
    exact
        Per grid speed, whether the critical depth was computed there; the others are
        interpolated (the semi-discretization's coarse-to-fine search, module notes). None:
        all computed.
    tool
        The tool number whose modes the lobes are of (-1 when one set of modes serves all).
    """

    teeth: int
    entry_rad: float
    exit_rad: float
    critical_depth_mm: np.ndarray
    chatter_frequency_hz: np.ndarray
    exact: np.ndarray | None = None
    tool: int = -1


@dataclass(frozen=True, eq=False)
class StabilityRoadmap:
    """Result of :func:`stability_roadmap`.

    Attributes
    ----------
    spindle_rpm
        The speed grid in rpm (increasing, inside the machine's limits).
    lobes
        One lobe diagram per distinct engagement.
    segments
        The segments in path order.
    margin
        Margin factor on the depth of cut.
    method
        ``"zoa"`` or ``"sdm"``.
    """

    spindle_rpm: np.ndarray
    lobes: tuple[EngagementLobes, ...]
    segments: tuple[RoadmapSegment, ...]
    margin: float
    method: str

    @property
    def unstable_segments(self) -> tuple[RoadmapSegment, ...]:
        """Segments without a stable speed (with the margin) within the limits."""
        return tuple(s for s in self.segments if s.lobes >= 0 and not s.has_stable_speed)

    @property
    def unmodelled_segments(self) -> tuple[RoadmapSegment, ...]:
        """Segments of tools without modes, left at their programmed speed."""
        return tuple(s for s in self.segments if not s.has_modes)


@dataclass(frozen=True)
class _Run:
    line: int
    tool: int
    rows: np.ndarray  # map location indices


def engagement_segments(engagement_map: EngagementMap) -> list[tuple[int, int, np.ndarray]]:
    """Group the map's cutting locations into segments: consecutive, same line and tool.

    Parameters
    ----------
    engagement_map
        The program's engagement map.

    Returns
    -------
    list of tuple
        ``(line, tool, location indices)`` per segment, in path order.
    """
    contact = engagement_map.column("contact") > 0
    rapid = engagement_map.column("rapid") > 0
    line = engagement_map.column("line").astype(np.int64)
    tool = engagement_map.column("tool").astype(np.int64)
    cutting = np.flatnonzero(contact & ~rapid)
    if cutting.size == 0:
        return []
    breaks = (np.diff(cutting) != 1) | (np.diff(line[cutting]) != 0) | (np.diff(tool[cutting]) != 0)
    groups = np.split(cutting, np.flatnonzero(breaks) + 1)
    return [(int(line[g[0]]), int(tool[g[0]]), g) for g in groups]


class RoadmapProgress(Protocol):
    """What :func:`stability_roadmap` tells about a long run (the CLI's ``ProgressLine``)."""

    def estimate(self, cost: SdmCost, what: str = "speeds") -> None:
        """The estimated cost before the lobes are computed."""

    def __call__(self, done: int, total: int) -> None:
        """``done`` of ``total`` speed evaluations."""


@dataclass(frozen=True)
class _Model:
    """The modes and cutting coefficients of one or more tools, with their search settings."""

    tool: ToolDynamics
    coefficients: CuttingCoefficients
    max_depth_mm: float
    steps: int | None
    number: int  # the tool number, -1 when shared by every tool


@dataclass(frozen=True)
class _Engagement:
    """A segment before its lobes: the run, its worst engagement and its lobe-cache key."""

    run: _Run
    ap: float
    ae: float
    entry: float
    exit: float
    key: tuple[int, int, float, float] | None  # (model, teeth, entry, exit); None: no lobes


def stability_roadmap(
    engagement_map: EngagementMap,
    programmed_rpm: Mapping[int, float],
    tool: ToolDynamics | Mapping[int, ToolDynamics],
    coefficients: CuttingCoefficients | Mapping[int, CuttingCoefficients],
    teeth: Mapping[int, int],
    spindle_rpm: np.ndarray,
    *,
    margin: float = DEFAULT_MARGIN,
    method: Method = "zoa",
    max_depth_mm: float = 10.0,
    steps: int | None = None,
    quantile: float = 0.95,
    sdm_points: int | None = DEFAULT_SDM_POINTS,
    progress: RoadmapProgress | None = None,
) -> StabilityRoadmap:
    """The stability roadmap of a program and its spindle-speed schedule (module notes).

    Parameters
    ----------
    engagement_map
        The program's engagement map (mm, rad).
    programmed_rpm
        Programmed spindle speed in rpm by program line (each line that cuts).
    tool
        Tool-tip modes (SI): one set for every tool, or a set per tool number; the segments
        of a tool without modes keep their programmed speed (``has_modes`` False).
    coefficients
        Cutting coefficients, one set or one per tool number (each tool with modes); the
        shear terms ``ktc`` and ``krc`` (Pa) are used.
    teeth
        Number of teeth by tool number (each tool with modes that cuts).
    spindle_rpm
        Speed grid in rpm, > 0, increasing: the machine's limits and the schedule's
        resolution.
    margin
        Factor on the depth of cut, >= 1: a speed is stable if ``a_lim >= margin ap``.
    method
        ``"zoa"`` (zero-order approximation) or ``"sdm"`` (semi-discretization).
    max_depth_mm
        SDM: highest depth searched in mm; raised to 1.5 x margin x the largest ``ap``
        when that is higher (a speed stable to the limit has ``inf``).
    steps
        SDM: steps per period (``None``: automatic).
    quantile
        Quantile ``q`` of the locations' engagement taken for the segment, 0.5 <= q <= 1
        (module notes).
    sdm_points
        SDM: speeds of the grid at which the lobes are computed, >= 2 (the coarse-to-fine
        search of the module notes); ``None``: at every grid speed.
    progress
        Told the estimated cost and the speed evaluations done (SDM only).

    Returns
    -------
    StabilityRoadmap
        The segments with their stable ranges and scheduled speeds, and the lobe diagrams.

    Raises
    ------
    ConfigError
        On a bad grid, margin or method, a cutting line without a programmed speed, or a
        tool without a number of teeth or without coefficients.
    """
    if isinstance(tool, ToolDynamics):
        if not isinstance(coefficients, CuttingCoefficients):
            raise ConfigError("one set of modes for every tool takes one set of coefficients")
        models: dict[int, _Model] | _Model = _Model(tool, coefficients, max_depth_mm, steps, -1)
    else:
        models = {}
        for number, dynamics in tool.items():
            if isinstance(coefficients, CuttingCoefficients):
                own = coefficients
            elif number in coefficients:
                own = coefficients[number]
            else:
                raise ConfigError(f"tool T{number} has modes but no cutting coefficients")
            models[number] = _Model(dynamics, own, max_depth_mm, steps, number)
    return _roadmap(engagement_map, programmed_rpm, models, teeth, spindle_rpm, margin=margin,
                    method=method, quantile=quantile, sdm_points=sdm_points,
                    progress=progress)  # fmt: skip


def _roadmap(
    engagement_map: EngagementMap,
    programmed_rpm: Mapping[int, float],
    models: Mapping[int, _Model] | _Model,
    teeth: Mapping[int, int],
    spindle_rpm: np.ndarray,
    *,
    margin: float,
    method: Method,
    quantile: float,
    sdm_points: int | None,
    progress: RoadmapProgress | None,
) -> StabilityRoadmap:
    """:func:`stability_roadmap` with a model per tool (or one for all)."""
    grid = np.asarray(spindle_rpm, dtype=np.float64)
    if grid.ndim != 1 or grid.size < 1 or not np.all(np.isfinite(grid) & (grid > 0.0)):
        raise InputError(f"spindle speed grid {spindle_rpm!r}; give speeds > 0 rpm")
    if grid.size > 1 and np.any(np.diff(grid) <= 0.0):
        raise InputError("spindle speed grid: give increasing speeds")
    if not (math.isfinite(margin) and margin >= 1.0):
        raise InputError(f"margin={margin!r}; give a factor >= 1")
    if method not in ("zoa", "sdm"):
        raise InputError(f"method={method!r}; give 'zoa' or 'sdm'")
    if not 0.5 <= quantile <= 1.0:
        raise InputError(f"quantile={quantile!r}; give 0.5 <= quantile <= 1")
    if sdm_points is not None and (isinstance(sdm_points, bool) or sdm_points < 2):
        raise InputError(f"sdm_points={sdm_points!r}; give an integer >= 2 or None")
    runs = [_Run(*group) for group in engagement_segments(engagement_map)]
    ap = engagement_map.column("ap_mm")
    deepest = 1.5 * margin * max((float(ap[r.rows].max()) for r in runs), default=0.0)
    step = _SDM_ANGLE_STEP if method == "sdm" else _ANGLE_STEP
    found: list[_Engagement] = []
    owners: dict[int, _Model] = {}
    for run in runs:
        if run.line not in programmed_rpm:
            raise ConfigError(f"line {run.line} cuts but has no programmed spindle speed")
        model = models if isinstance(models, _Model) else models.get(run.tool)
        if model is not None:
            if run.tool not in teeth:
                raise ConfigError(f"tool T{run.tool} cuts but its number of teeth is not given")
            owners[id(model)] = model
        found.append(_engage(engagement_map, run, quantile, step, model, teeth))
    solvers = {key: _solver(model, method, max(model.max_depth_mm, deepest))
               for key, model in owners.items()}  # fmt: skip
    keys = list(dict.fromkeys(e.key for e in found if e.key is not None))
    coarse = _coarse(grid, sdm_points if method == "sdm" else None)
    total = len(keys) * coarse.size + sum(1 for e in found if e.key is not None)
    if progress is not None and method == "sdm" and keys:
        widest = max(keys, key=lambda k: k[3] - k[2])
        model = owners[widest[0]]
        cost = sdm_cost(
            model.tool,
            _process(model, widest),
            coarse * _RPM,
            max_depth_m=max(model.max_depth_mm, deepest) * 1e-3,
            steps=model.steps,
        )
        progress.estimate(SdmCost(total, cost.evaluations_per_speed,
                                  cost.seconds_per_evaluation), "speed evaluations")  # fmt: skip
    counter = _Counter(total, progress if method == "sdm" else None)  # the ZOA takes ms
    lobes: list[EngagementLobes] = []
    index: dict[tuple[int, int, float, float], int] = {}
    for key in keys:
        model = owners[key[0]]
        depth, frequency, exact = _diagram(model, solvers[key[0]], _process(model, key), grid,
                                           coarse, counter)  # fmt: skip
        index[key] = len(lobes)
        lobes.append(EngagementLobes(key[1], key[2], key[3], depth, frequency,
                                     None if exact.all() else exact, model.number))  # fmt: skip
    segments = []
    exact_at: dict[tuple[tuple[int, int, float, float], float], tuple[float, float]] = {}
    for engagement in found:
        programmed = float(programmed_rpm[engagement.run.line])
        if engagement.key is None:
            segments.append(_without_lobes(engagement_map, engagement, programmed,
                                           isinstance(models, _Model) or
                                           engagement.run.tool in models))  # fmt: skip
            continue
        key = engagement.key
        model = owners[key[0]]
        process = _process(model, key)

        def at(rpm: float, key: tuple[int, int, float, float] = key,
               process: MillingProcess = process) -> tuple[float, float]:  # fmt: skip
            if (key, rpm) not in exact_at:
                depth, hz = solvers[key[0]](process, np.array([rpm]))
                exact_at[(key, rpm)] = (float(depth[0]), float(hz[0]))
            return exact_at[(key, rpm)]

        segments.append(_schedule(engagement_map, engagement, programmed, grid, margin,
                                  index[key], lobes[index[key]], at))  # fmt: skip
        counter.advance(1)
    logger.info(
        "stability roadmap: %d segments, %d lobe diagrams, %d without a stable speed, "
        "%d of tools without modes",
        len(segments), len(lobes),
        sum(1 for s in segments if s.lobes >= 0 and not s.has_stable_speed),
        sum(1 for s in segments if not s.has_modes),
    )  # fmt: skip
    return StabilityRoadmap(grid, tuple(lobes), tuple(segments), float(margin), method)


def program_roadmap(
    program: str | os.PathLike[str],
    config: MachiningConfig,
    stability: StabilityConfig | Mapping[int, StabilityConfig],
    spindle_rpm: np.ndarray | None = None,
    *,
    margin: float = DEFAULT_MARGIN,
    density_per_mm: float | None = None,
    step_mm: float | None = None,
    method: Method | None = None,
    sdm_points: int | None = DEFAULT_SDM_POINTS,
    progress: RoadmapProgress | None = None,
) -> StabilityRoadmap:
    """The stability roadmap of an NC program file (Ward 2021, sec. 3.4; module notes).

    The program runs through the stock of ``config`` (machine, tools with their geometry,
    stock) into an engagement map (:class:`~cnctwin.geometry.EngagementMap`, one location
    every ``step_mm`` along the path); :func:`stability_roadmap` then takes the tool-tip modes,
    the method, the depth limit and the steps of ``stability`` (a stability file, or one per
    tool number), the cutting coefficients of its ``[cut]`` or else of the configuration's
    ``[material]`` (:meth:`~cnctwin.dynamics.StabilityConfig.milling_coefficients`), the
    programmed spindle speed of each line and the teeth of each tool.

    Parameters
    ----------
    program
        NC program file.
    config
        Machine, tools and stock (mm).
    stability
        Modes, coefficients, method and speed range: one file for every milling tool (a tool
        of another kind, such as a drill, has no modes), or a file per tool number (the
        other tools have none). Segments of tools without modes keep their speed.
    spindle_rpm
        Speed grid in rpm, > 0, increasing; default the stability files' ``[lobes] rpm``
        range (from the lowest to the highest) every :data:`RPM_STEP` rpm. Speeds above the
        machine's ``max_spindle_rpm`` are left out.
    margin
        Factor on the depth of cut, >= 1.
    density_per_mm
        Dexels per mm of the stock; default the configuration's ``[simulation]``.
    step_mm
        Map step along the path in mm; default the dexel pitch ``1 / density_per_mm``.
    method
        ``"zoa"`` or ``"sdm"``; default the files' ``[lobes] method`` (which must agree).
    sdm_points, progress
        As :func:`stability_roadmap`.

    Raises
    ------
    ConfigError
        For a cut that is not milling, no cutting coefficients, a tool number that is not in
        the configuration, files that disagree on the method, no grid speed within the
        machine's limit, and the checks of the stock, the map and :func:`stability_roadmap`.
    NCError
        ``"FILE:LINE: message"`` for a program the interpreter refuses.
    """
    from cnctwin.nc import Interpreter  # the interpreter only when a program is read

    rho = config.simulation.density_per_mm if density_per_mm is None else density_per_mm
    step = 1.0 / rho if step_mm is None else step_mm
    numbers = [tool.number for tool in config.tools]
    if isinstance(stability, Mapping):
        files = dict(stability)
        for number in files:
            if number not in numbers:
                raise ConfigError(
                    f"stability file for tool T{number}: the configuration has no such tool "
                    f"(its tools: {', '.join(f'T{n}' for n in numbers) or 'none'})"
                )
    else:
        files = {t.number: stability for t in config.tools if t.kind in _MILLING_KINDS}
    if not files:
        raise ConfigError("no tool of the configuration has modes: give --stability FILE")
    chosen = {f.lobes.method for f in files.values()} if method is None else {method}
    if len(chosen) != 1:
        raise ConfigError("the stability files disagree on [lobes] method; give --method")
    the_method: Method = chosen.pop()
    interpreted = list(Interpreter(config.nc_setup()).run_file(os.fspath(program)))
    if spindle_rpm is None:
        low = min(f.lobes.rpm[0] for f in files.values())
        high = max(f.lobes.rpm[1] for f in files.values())
        if the_method == "sdm":
            programmed = [seg.spindle_rpm for seg in interpreted
                          if seg.state.tool in files and seg.spindle_rpm > 0.0]  # fmt: skip
            if programmed:
                low = min(max(low, SDM_LOWEST_FRACTION * min(programmed)), high - RPM_STEP)
        spindle_rpm = np.linspace(low, high, max(2, round((high - low) / RPM_STEP) + 1))
    grid = np.asarray(spindle_rpm, dtype=float)
    cap = config.machine.max_spindle_rpm
    if cap is not None:
        grid = grid[grid <= cap]
        if grid.size == 0:
            raise ConfigError(
                f"machine.max_spindle_rpm={cap:g} is below the lowest speed of the grid "
                f"({float(np.min(spindle_rpm)):g} rpm); give lower speeds (--rpm-range)"
            )
    shared: dict[int, _Model] = {}
    models: dict[int, _Model] = {}
    for number, file in files.items():
        if id(file) not in shared:
            steps = None if file.lobes.steps == "auto" else file.lobes.steps
            shared[id(file)] = _Model(file.tool_dynamics(),
                                      file.milling_coefficients(config.material.name),
                                      file.lobes.max_depth_mm, steps,
                                      number if isinstance(stability, Mapping) else -1)  # fmt: skip
        models[number] = shared[id(file)]
    cutters = {tool.number: Cutter.from_tool_config(tool) for tool in config.tools}
    teeth = {tool.number: tool.flutes for tool in config.tools}
    stock = DexelStock.box(config.stock.min_mm, config.stock.max_mm, rho)
    speeds: dict[int, float] = {}
    segments = _recording(iter(interpreted), speeds)
    try:
        emap = EngagementMap.build(segments, stock, cutters, step_mm=step)
    except NCError as err:
        if err.file == "<string>":
            raise NCError(err.message, os.fspath(program), err.line, err.column) from None
        raise
    return _roadmap(emap, speeds, models, teeth, grid, margin=margin, method=the_method,
                    quantile=0.95, sdm_points=sdm_points, progress=progress)  # fmt: skip


def _recording(segments: Iterable[Segment], speeds: dict[int, float]) -> Iterator[Segment]:
    """Pass the segments on, noting each line's programmed spindle speed (rpm)."""
    for segment in segments:
        speeds[segment.line] = segment.spindle_rpm
        yield segment


class _Counter:
    """Counts speed evaluations for a :class:`RoadmapProgress`."""

    def __init__(self, total: int, progress: RoadmapProgress | None) -> None:
        self.total, self.done, self.progress = total, 0, progress

    def advance(self, count: int) -> None:
        self.done += count
        if self.progress is not None:
            self.progress(self.done, self.total)


def _engage(
    emap: EngagementMap,
    run: _Run,
    quantile: float,
    angle_step: float,
    model: _Model | None,
    teeth: Mapping[int, int],
) -> _Engagement:
    """The worst engagement of ``run`` up to the quantile (module notes) and its lobe key.

    The angles are rounded to ``angle_step`` rad: to the nearest step for the ZOA's 1 mrad;
    widened outward (entry down, exit up) for the semi-discretization's coarser step.
    """
    rows = run.rows
    entry = emap.column("entry_rad")[rows]
    exit_ = emap.column("exit_rad")[rows]
    ap = float(np.quantile(emap.column("ap_mm")[rows], quantile, method="higher"))
    ae = float(np.quantile(emap.column("ae_mm")[rows], quantile, method="higher"))
    sides = np.isfinite(entry) & np.isfinite(exit_)
    if not sides.any():
        return _Engagement(run, ap, ae, math.nan, math.nan, None)
    low = float(np.quantile(entry[sides], 1.0 - quantile, method="lower"))
    high = float(np.quantile(exit_[sides], quantile, method="higher"))
    if angle_step == _ANGLE_STEP:
        low, high = round(low, _ANGLE_DIGITS), round(high, _ANGLE_DIGITS)
    else:
        low = max(0.0, math.floor(low / angle_step + 1e-9) * angle_step)
        high = min(2.0 * math.pi, math.ceil(high / angle_step - 1e-9) * angle_step)
    if model is None:
        return _Engagement(run, ap, ae, low, high, None)
    return _Engagement(run, ap, ae, low, high, (id(model), teeth[run.tool], low, high))


def _process(model: _Model, key: tuple[int, int, float, float]) -> MillingProcess:
    coefficients = model.coefficients
    return MillingProcess(key[1], coefficients.ktc, coefficients.krc, key[2], key[3])


def _solver(model: _Model, method: Method, max_depth_mm: float) -> _Solver:
    def solve(process: MillingProcess, rpm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return _lobes(model.tool, process, rpm, method, max_depth_mm, model.steps)

    return solve


def _coarse(grid: np.ndarray, points: int | None) -> np.ndarray:
    """The grid speeds at which the lobes are computed: all, or ``points`` evenly spread."""
    if points is None or grid.size <= points:
        return grid
    chosen: np.ndarray = grid[
        np.unique(np.round(np.linspace(0, grid.size - 1, points)).astype(int))
    ]
    return chosen


def _diagram(
    model: _Model,
    solve: _Solver,
    process: MillingProcess,
    grid: np.ndarray,
    coarse: np.ndarray,
    counter: _Counter,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Critical depth (mm) and chatter frequency (Hz) on the grid, and where computed.

    At the ``coarse`` speeds the solver's values; between them (the semi-discretization's
    coarse-to-fine search, module notes) the ZOA lobes on the whole grid times the ratio of
    the two methods, interpolated linearly between the coarse speeds (a speed the SDM finds
    stable to its depth limit counts at that limit); the chatter frequency is NaN there.
    """
    if coarse.size == grid.size:
        depth, frequency = solve(process, grid)
        counter.advance(grid.size)
        return depth, frequency, np.ones(grid.size, dtype=bool)
    frequency = np.full(grid.size, math.nan)
    exact = np.isin(grid, coarse)
    found = np.empty(coarse.size)
    for start in range(0, coarse.size, _BATCH):
        part = coarse[start : start + _BATCH]
        found[start : start + part.size], hz = solve(process, part)
        frequency[np.searchsorted(grid, part)] = hz
        counter.advance(part.size)
    zoa = zoa_lobes(model.tool, process, grid * _RPM).critical_depth_m * 1e3
    limit = float(np.max(found[np.isfinite(found)], initial=0.0))
    capped = np.where(np.isfinite(found), found, max(limit, model.max_depth_mm))
    usable = np.isfinite(zoa[exact]) & (zoa[exact] > 0.0)
    if usable.sum() >= 2:
        ratio = np.interp(grid, coarse[usable], capped[usable] / zoa[exact][usable])
        depth = np.where(np.isfinite(zoa), zoa * ratio, np.interp(grid, coarse, capped))
    else:
        depth = np.interp(grid, coarse, capped)
    depth[exact] = found
    return depth, frequency, exact


def _without_lobes(
    emap: EngagementMap, engagement: _Engagement, programmed: float, has_modes: bool
) -> RoadmapSegment:
    """A plunge (bottom contact only: no lobes) or a segment of a tool without modes."""
    run = engagement.run
    s = emap.s_mm[run.rows]
    nan = math.nan
    return RoadmapSegment(
        line=run.line, tool=run.tool, start_s_mm=float(s[0]), end_s_mm=float(s[-1]),
        locations=int(run.rows.size), ap_mm=engagement.ap, ae_mm=engagement.ae,
        entry_rad=engagement.entry, exit_rad=engagement.exit, programmed_rpm=programmed,
        lobes=-1, programmed_critical_depth_mm=nan, programmed_chatter_hz=nan,
        stable_ranges_rpm=(), scheduled_rpm=nan if has_modes else programmed,
        scheduled_critical_depth_mm=nan, has_modes=has_modes,
    )  # fmt: skip


def _schedule(
    emap: EngagementMap,
    engagement: _Engagement,
    programmed: float,
    grid: np.ndarray,
    margin: float,
    index: int,
    lobes: EngagementLobes,
    at: Callable[[float], tuple[float, float]],
) -> RoadmapSegment:
    """The segment's stable ranges and schedule from its lobes (module notes).

    ``at(rpm)`` computes the critical depth (mm) and chatter frequency (Hz) at one speed: at
    the programmed speed, and at each candidate speed whose depth was interpolated, before it
    is scheduled (up to :data:`_CHECKS` of them; then the nearest computed stable speed).
    """
    run = engagement.run
    ap = engagement.ap
    critical = lobes.critical_depth_mm
    stable = critical >= margin * ap
    ranges = _ranges(grid, stable)
    programmed_depth = programmed_hz = scheduled = scheduled_depth = math.nan
    if programmed > 0.0:  # a cut with the spindle off has no lobes at its speed
        programmed_depth, programmed_hz = at(programmed)
    if programmed_depth >= margin * ap and grid[0] <= programmed <= grid[-1]:
        scheduled, scheduled_depth = programmed, programmed_depth
    elif stable.any():
        candidates = np.flatnonzero(stable)
        distance = np.abs(grid[candidates] - programmed)
        ordered = candidates[np.lexsort((-grid[candidates], distance))]
        exact = lobes.exact
        checks = 0
        for best in ordered:
            if exact is None or exact[best]:
                scheduled, scheduled_depth = float(grid[best]), float(critical[best])
                break
            if checks == _CHECKS:
                continue  # only computed speeds from here on
            checks += 1
            depth, _ = at(float(grid[best]))
            if depth >= margin * ap:
                scheduled, scheduled_depth = float(grid[best]), depth
                break
    s = emap.s_mm[run.rows]
    return RoadmapSegment(
        line=run.line,
        tool=run.tool,
        start_s_mm=float(s[0]),
        end_s_mm=float(s[-1]),
        locations=int(run.rows.size),
        ap_mm=ap,
        ae_mm=engagement.ae,
        entry_rad=engagement.entry,
        exit_rad=engagement.exit,
        programmed_rpm=programmed,
        lobes=index,
        programmed_critical_depth_mm=programmed_depth,
        programmed_chatter_hz=programmed_hz,
        stable_ranges_rpm=ranges,
        scheduled_rpm=scheduled,
        scheduled_critical_depth_mm=scheduled_depth,
    )


def _lobes(
    tool: ToolDynamics,
    process: MillingProcess,
    rpm: np.ndarray,
    method: Method,
    max_depth_mm: float,
    steps: int | None,
) -> tuple[np.ndarray, np.ndarray]:
    """Critical depth (mm) and chatter frequency (Hz) per speed (rpm) of one engagement."""
    if method == "zoa":
        result = zoa_lobes(tool, process, rpm * _RPM)
    else:
        result = sdm_lobes(tool, process, rpm * _RPM, max_depth_m=max_depth_mm * 1e-3,
                           steps=steps)  # fmt: skip
    return result.critical_depth_m * 1e3, result.chatter_frequency_hz


def _ranges(grid: np.ndarray, stable: np.ndarray) -> tuple[tuple[float, float], ...]:
    """Runs of consecutive stable grid speeds as ``(low, high)`` rpm."""
    if not stable.any():
        return ()
    edges = np.diff(np.concatenate(([0], stable.astype(np.int8), [0])))
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1
    return tuple((float(grid[a]), float(grid[b])) for a, b in zip(starts, stops, strict=True))
