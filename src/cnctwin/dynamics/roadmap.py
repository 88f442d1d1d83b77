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

Units: mm, rpm, Hz and rad in the names at this level (the map's units); SI inside the lobe
computations.
"""

from __future__ import annotations

import logging
import math
import os
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np

from cnctwin.dynamics.stability import MillingProcess, ToolDynamics, sdm_lobes, zoa_lobes
from cnctwin.errors import ConfigError, InputError, NCError
from cnctwin.geometry import Cutter, DexelStock, EngagementMap
from cnctwin.mechanics import CuttingCoefficients

if TYPE_CHECKING:
    from cnctwin.config import MachiningConfig
    from cnctwin.dynamics.config import StabilityConfig
    from cnctwin.nc import Segment

__all__ = [
    "DEFAULT_MARGIN",
    "RPM_STEP",
    "EngagementLobes",
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
_RPM = math.pi / 30.0  # rad/s per rpm
_ANGLE_DIGITS = 3  # segments whose angles agree to 1 mrad share their lobes

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
        Chatter frequency per grid speed in Hz (NaN where none).
    """

    teeth: int
    entry_rad: float
    exit_rad: float
    critical_depth_mm: np.ndarray
    chatter_frequency_hz: np.ndarray


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


def stability_roadmap(
    engagement_map: EngagementMap,
    programmed_rpm: Mapping[int, float],
    tool: ToolDynamics,
    coefficients: CuttingCoefficients,
    teeth: Mapping[int, int],
    spindle_rpm: np.ndarray,
    *,
    margin: float = DEFAULT_MARGIN,
    method: Method = "zoa",
    max_depth_mm: float = 10.0,
    steps: int | None = None,
    quantile: float = 0.95,
) -> StabilityRoadmap:
    """The stability roadmap of a program and its spindle-speed schedule (module notes).

    Parameters
    ----------
    engagement_map
        The program's engagement map (mm, rad).
    programmed_rpm
        Programmed spindle speed in rpm by program line (each line that cuts).
    tool
        Tool-tip modes (SI).
    coefficients
        Cutting coefficients; the shear terms ``ktc`` and ``krc`` (Pa) are used.
    teeth
        Number of teeth by tool number (each tool that cuts).
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

    Returns
    -------
    StabilityRoadmap
        The segments with their stable ranges and scheduled speeds, and the lobe diagrams.

    Raises
    ------
    ConfigError
        On a bad grid, margin or method, a cutting line without a programmed speed, or a
        tool without a number of teeth.
    """
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
    runs = [_Run(*group) for group in engagement_segments(engagement_map)]
    ap = engagement_map.column("ap_mm")
    depth_limit = max(max_depth_mm, 1.5 * margin * max((float(ap[r.rows].max()) for r in runs),
                                                       default=0.0))  # fmt: skip
    cache: dict[tuple[int, float, float], int] = {}
    lobes: list[EngagementLobes] = []
    segments = []
    for run in runs:
        if run.line not in programmed_rpm:
            raise ConfigError(f"line {run.line} cuts but has no programmed spindle speed")
        if run.tool not in teeth:
            raise ConfigError(f"tool T{run.tool} cuts but its number of teeth is not given")
        process = (teeth[run.tool], coefficients.ktc, coefficients.krc)
        segment = _segment(
            engagement_map, run, float(programmed_rpm[run.line]), process, grid, margin,
            quantile, cache, lobes,
            lambda cut, speeds: _lobes(tool, cut, speeds, method, depth_limit, steps),
        )  # fmt: skip
        segments.append(segment)
    logger.info(
        "stability roadmap: %d segments, %d lobe diagrams, %d without a stable speed",
        len(segments), len(lobes),
        sum(1 for s in segments if s.lobes >= 0 and not s.has_stable_speed),
    )  # fmt: skip
    return StabilityRoadmap(grid, tuple(lobes), tuple(segments), float(margin), method)


def program_roadmap(
    program: str | os.PathLike[str],
    config: MachiningConfig,
    stability: StabilityConfig,
    spindle_rpm: np.ndarray | None = None,
    *,
    margin: float = DEFAULT_MARGIN,
    density_per_mm: float | None = None,
    step_mm: float | None = None,
) -> StabilityRoadmap:
    """The stability roadmap of an NC program file (Ward 2021, sec. 3.4; module notes).

    The program runs through the stock of ``config`` (machine, tools with their geometry,
    stock) into an engagement map (:class:`~cnctwin.geometry.EngagementMap`, one location
    every ``step_mm`` along the path); :func:`stability_roadmap` then takes the tool-tip modes,
    the method, the depth limit and the steps of ``stability`` (a stability file), the cutting
    coefficients of its ``[cut]`` or else of the configuration's ``[material]``
    (:meth:`~cnctwin.dynamics.StabilityConfig.milling_coefficients`), the programmed spindle
    speed of each line and the teeth of each tool.

    Parameters
    ----------
    program
        NC program file.
    config
        Machine, tools and stock (mm).
    stability
        Modes, coefficients, method and speed range.
    spindle_rpm
        Speed grid in rpm, > 0, increasing; default the stability file's ``[lobes] rpm``
        range every :data:`RPM_STEP` rpm. Speeds above the machine's ``max_spindle_rpm``
        are left out.
    margin
        Factor on the depth of cut, >= 1.
    density_per_mm
        Dexels per mm of the stock; default the configuration's ``[simulation]``.
    step_mm
        Map step along the path in mm; default the dexel pitch ``1 / density_per_mm``.

    Raises
    ------
    ConfigError
        For a cut that is not milling, no cutting coefficients, no grid speed within the
        machine's limit, and the checks of the stock, the map and :func:`stability_roadmap`.
    NCError
        ``"FILE:LINE: message"`` for a program the interpreter refuses.
    """
    from cnctwin.nc import Interpreter  # the interpreter only when a program is read

    rho = config.simulation.density_per_mm if density_per_mm is None else density_per_mm
    step = 1.0 / rho if step_mm is None else step_mm
    if spindle_rpm is None:
        low, high = stability.lobes.rpm
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
    coefficients = stability.milling_coefficients(config.material.name)
    cutters = {tool.number: Cutter.from_tool_config(tool) for tool in config.tools}
    teeth = {tool.number: tool.flutes for tool in config.tools}
    stock = DexelStock.box(config.stock.min_mm, config.stock.max_mm, rho)
    speeds: dict[int, float] = {}
    segments = _recording(Interpreter(config.nc_setup()).run_file(os.fspath(program)), speeds)
    try:
        emap = EngagementMap.build(segments, stock, cutters, step_mm=step)
    except NCError as err:
        if err.file == "<string>":
            raise NCError(err.message, os.fspath(program), err.line, err.column) from None
        raise
    steps = None if stability.lobes.steps == "auto" else stability.lobes.steps
    return stability_roadmap(
        emap, speeds, stability.tool_dynamics(), coefficients, teeth, grid, margin=margin,
        method=stability.lobes.method, max_depth_mm=stability.lobes.max_depth_mm, steps=steps,
    )  # fmt: skip


def _recording(segments: Iterable[Segment], speeds: dict[int, float]) -> Iterator[Segment]:
    """Pass the segments on, noting each line's programmed spindle speed (rpm)."""
    for segment in segments:
        speeds[segment.line] = segment.spindle_rpm
        yield segment


def _segment(
    emap: EngagementMap,
    run: _Run,
    programmed: float,
    cut: tuple[int, float, float],
    grid: np.ndarray,
    margin: float,
    quantile: float,
    cache: dict[tuple[int, float, float], int],
    lobes: list[EngagementLobes],
    compute: _Solver,
) -> RoadmapSegment:
    """The segment of ``run``: its worst engagement, lobes (cached), ranges and schedule.

    ``cut`` is (teeth, Ktc in Pa, Krc in Pa); ``cache`` maps (teeth, entry, exit) to the
    index of the engagement's lobes in ``lobes``.
    """
    teeth, ktc, krc = cut
    rows = run.rows
    entry = emap.column("entry_rad")[rows]
    exit_ = emap.column("exit_rad")[rows]
    ap = float(np.quantile(emap.column("ap_mm")[rows], quantile, method="higher"))
    ae = float(np.quantile(emap.column("ae_mm")[rows], quantile, method="higher"))
    sides = np.isfinite(entry) & np.isfinite(exit_)
    s = emap.s_mm[rows]
    nan = math.nan
    entry_rad = exit_rad = programmed_depth = programmed_hz = nan
    scheduled = scheduled_depth = nan
    index = -1
    ranges: tuple[tuple[float, float], ...] = ()
    if sides.any():
        low = float(np.quantile(entry[sides], 1.0 - quantile, method="lower"))
        high = float(np.quantile(exit_[sides], quantile, method="higher"))
        key = (teeth, round(low, _ANGLE_DIGITS), round(high, _ANGLE_DIGITS))
        entry_rad, exit_rad = key[1], key[2]
        process = MillingProcess(teeth, ktc, krc, entry_rad, exit_rad)
        if key not in cache:
            depth, frequency = compute(process, grid)
            cache[key] = len(lobes)
            lobes.append(EngagementLobes(teeth, entry_rad, exit_rad, depth, frequency))
        index = cache[key]
        critical = lobes[index].critical_depth_mm
        stable = critical >= margin * ap
        ranges = _ranges(grid, stable)
        if programmed > 0.0:  # a cut with the spindle off has no lobes at its speed
            at_programmed, chatter = compute(process, np.array([programmed]))
            programmed_depth, programmed_hz = float(at_programmed[0]), float(chatter[0])
        if programmed_depth >= margin * ap and grid[0] <= programmed <= grid[-1]:
            scheduled, scheduled_depth = programmed, programmed_depth
        elif stable.any():
            candidates = np.flatnonzero(stable)
            distance = np.abs(grid[candidates] - programmed)
            best = candidates[np.lexsort((-grid[candidates], distance))[0]]
            scheduled, scheduled_depth = float(grid[best]), float(critical[best])
    return RoadmapSegment(
        line=run.line,
        tool=run.tool,
        start_s_mm=float(s[0]),
        end_s_mm=float(s[-1]),
        locations=int(rows.size),
        ap_mm=ap,
        ae_mm=ae,
        entry_rad=entry_rad,
        exit_rad=exit_rad,
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
