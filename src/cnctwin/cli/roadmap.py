"""``cnctwin stability roadmap``: stable spindle speeds along a program, and a speed schedule.

The program runs through the stock of the configuration (``--config``: machine, tools, stock)
into an engagement map (:mod:`cnctwin.geometry.engagement_map`); the stability file
(``--stability FILE`` for every milling tool, or ``--stability T1=FILE`` once per tool,
docs/stability.md) gives the tool-tip modes, the cutting coefficients (its ``[cut]`` material
or ``ktc_n_mm2``/``krc_n_mm2``; else the configuration's ``[material]``) and the speed range
(``[lobes] rpm``). :mod:`cnctwin.dynamics.roadmap` does the rest (Ward
2021, sec. 3.4). The teeth come from the program's tools, the immersion from the map.
"""

from __future__ import annotations

import math
import re
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import numpy as np
import typer
from rich.console import Console
from rich.table import Table

from cnctwin import finite_json
from cnctwin.cli._options import Density, HtmlReport
from cnctwin.cli.stability import ProgressLine, parse_rpm_range
from cnctwin.errors import InputError
from cnctwin.report import check_report_path

if TYPE_CHECKING:
    from cnctwin.config import MachiningConfig
    from cnctwin.dynamics import StabilityConfig, StabilityRoadmap

__all__ = ["parse_stability_options", "roadmap", "roadmap_report"]

MAX_STEP_MM = 100.0
"""Longest map step along the path, mm: longer steps skip whole features of a part."""
MAX_MARGIN = 100.0
"""Largest safety factor on the critical depth: beyond it no speed of any lobe qualifies."""
MAX_SDM_POINTS = 100_000
"""Most speeds of the semi-discretization's lobes (``--sdm-points``; as ``[lobes] points``)."""


def parse_stability_options(values: list[str]) -> Path | dict[int, Path]:
    """The ``--stability`` options: one ``FILE`` for every milling tool, or ``T<n>=FILE``
    once per tool (a ``T<n>`` prefix is case-insensitive; ``n`` >= 0).

    Raises
    ------
    InputError
        One line naming the bad value and what is valid.
    """
    if not values:
        raise InputError("--stability: give a stability file, or T<n>=FILE per tool")
    plain = [v for v in values if not _TOOL_PREFIX.match(v)]
    if plain and len(values) > 1:
        raise InputError(
            f"--stability {plain[0]}: give one FILE for every tool, or T<n>=FILE for each "
            "tool (e.g. --stability T1=a.toml --stability T2=b.toml), not both"
        )
    if plain:
        return Path(plain[0])
    files: dict[int, Path] = {}
    for value in values:
        match = _TOOL_PREFIX.match(value)
        assert match is not None
        number, path = int(match.group(1)), match.group(2)
        if not path:
            raise InputError(f"--stability {value}: give T{number}=FILE")
        if number in files:
            raise InputError(f"--stability {value}: tool T{number} given twice")
        files[number] = Path(path)
    return files


_TOOL_PREFIX = re.compile(r"^[Tt](\d{1,6})=(.*)$")


def roadmap_report(
    program: Path,
    config: MachiningConfig,
    stability: StabilityConfig | dict[int, StabilityConfig],
    *,
    margin: float,
    rpm_range: str | None = None,
    density_per_mm: float | None = None,
    step_mm: float | None = None,
    method: str | None = None,
    sdm_points: int | None = None,
    progress: ProgressLine | None = None,
) -> tuple[dict[str, Any], StabilityRoadmap]:
    """Build the program's engagement map and its stability roadmap.

    Parameters
    ----------
    program
        NC file.
    config
        Machine, tools (with geometry) and stock.
    stability
        Modes, coefficients, method and speed range (:class:`StabilityConfig`), one for
        every milling tool or one per tool number.
    margin
        Factor on the depth of cut, >= 1.
    rpm_range
        ``MIN:MAX:N`` speed grid; default the stability file's range every 10 rpm.
    density_per_mm
        Dexels per mm; default the configuration's.
    step_mm
        Map step along the path, mm; default the dexel pitch.
    method
        ``zoa`` or ``sdm``; default the stability files'.
    sdm_points
        SDM: speeds at which the lobes are computed (default
        :data:`cnctwin.dynamics.DEFAULT_SDM_POINTS`).
    progress
        Where the estimated cost and the progress go (stderr).

    Returns
    -------
    tuple
        The ``--json`` object and the roadmap. JSON: ``program``, ``method``, ``margin``,
        ``spindle_rpm_min``, ``spindle_rpm_max``, ``spindle_rpm_points``, ``segments``
        (per segment ``line``, ``tool``, ``start_s_mm``, ``end_s_mm``, ``ap_mm``, ``ae_mm``,
        ``radial_immersion``, ``entry_deg``, ``exit_deg``, ``programmed_rpm``,
        ``programmed_critical_depth_mm``, ``programmed_chatter_hz``, ``programmed_stable``,
        ``stable_ranges_rpm``, ``scheduled_rpm``, ``scheduled_critical_depth_mm``; null for
        a missing value), ``changed_lines``, ``lines_without_stable_speed``,
        ``plunge_lines`` (bottom contact only: no lobes), ``tools_without_modes`` and
        ``lines_without_modes`` (left at their programmed speed), ``engagements`` (distinct
        engagements: tool (null: all), teeth, angles, lowest critical depth),
        ``sdm_points``, ``seconds``.
    """
    from cnctwin.config import MAX_DENSITY_PER_MM, MIN_DENSITY_PER_MM
    from cnctwin.dynamics import program_roadmap

    rho = config.simulation.density_per_mm if density_per_mm is None else density_per_mm
    if not (MIN_DENSITY_PER_MM <= rho <= MAX_DENSITY_PER_MM):
        raise InputError(
            f"--density {rho!r}; give {MIN_DENSITY_PER_MM:g} <= density <= "
            f"{MAX_DENSITY_PER_MM:g} dexels per mm"
        )
    step = 1.0 / rho if step_mm is None else step_mm
    if not (math.isfinite(step) and 0.1 / rho <= step <= MAX_STEP_MM):
        raise InputError(
            f"--step-mm {step!r}; give {0.1 / rho:g} (a tenth of the dexel spacing) <= step "
            f"<= {MAX_STEP_MM:g} mm"
        )
    grid = None if rpm_range is None else parse_rpm_range(rpm_range)
    diameter = {tool.number: tool.diameter_mm for tool in config.tools}
    started = time.perf_counter()
    from cnctwin.dynamics import DEFAULT_SDM_POINTS

    points = DEFAULT_SDM_POINTS if sdm_points is None else sdm_points
    if not 2 <= points <= MAX_SDM_POINTS:
        raise InputError(f"--sdm-points {points}; give 2 <= N <= {MAX_SDM_POINTS}")
    if method is not None and method not in ("zoa", "sdm"):
        raise InputError(f"--method {method!r}; give zoa or sdm")
    result = program_roadmap(
        program, config, stability, grid, margin=margin, density_per_mm=rho, step_mm=step,
        method=method, sdm_points=points, progress=progress,  # type: ignore[arg-type]
    )  # fmt: skip
    seconds = time.perf_counter() - started
    rows = []
    for seg in result.segments:
        rows.append(
            {
                "line": seg.line,
                "tool": seg.tool,
                "start_s_mm": seg.start_s_mm,
                "end_s_mm": seg.end_s_mm,
                "ap_mm": seg.ap_mm,
                "ae_mm": seg.ae_mm,
                "radial_immersion": seg.ae_mm / diameter[seg.tool],
                "entry_deg": finite_json.finite(math.degrees(seg.entry_rad)),
                "exit_deg": finite_json.finite(math.degrees(seg.exit_rad)),
                "programmed_rpm": seg.programmed_rpm,
                "programmed_critical_depth_mm": finite_json.finite(
                    seg.programmed_critical_depth_mm
                ),
                "programmed_chatter_hz": finite_json.finite(seg.programmed_chatter_hz),
                "programmed_stable": seg.programmed_stable,
                "stable_ranges_rpm": [list(pair) for pair in seg.stable_ranges_rpm],
                "scheduled_rpm": finite_json.finite(seg.scheduled_rpm),
                "scheduled_critical_depth_mm": finite_json.finite(seg.scheduled_critical_depth_mm),
            }
        )
    with_lobes = [seg for seg in result.segments if seg.lobes >= 0]
    report = {
        "program": str(program),
        "method": result.method,
        "margin": result.margin,
        "spindle_rpm_min": float(result.spindle_rpm[0]),
        "spindle_rpm_max": float(result.spindle_rpm[-1]),
        "spindle_rpm_points": int(result.spindle_rpm.size),
        "segments": rows,
        "changed_lines": sorted({s.line for s in with_lobes if not s.programmed_stable}),
        "lines_without_stable_speed": sorted({s.line for s in result.unstable_segments}),
        "plunge_lines": sorted({s.line for s in result.segments if s.lobes < 0 and s.has_modes}),
        "tools_without_modes": sorted({s.tool for s in result.unmodelled_segments}),
        "lines_without_modes": sorted({s.line for s in result.unmodelled_segments}),
        "engagements": [
            {
                "tool": None if lobes.tool < 0 else lobes.tool,
                "teeth": lobes.teeth,
                "entry_deg": math.degrees(lobes.entry_rad),
                "exit_deg": math.degrees(lobes.exit_rad),
                "min_critical_depth_mm": finite_json.finite(float(np.min(lobes.critical_depth_mm))),
            }
            for lobes in result.lobes
        ],
        "sdm_points": points if result.method == "sdm" else None,
        "seconds": seconds,
    }
    return report, result


def roadmap(
    program: Annotated[Path, typer.Argument(help="NC program.")],
    config: Annotated[
        Path, typer.Option("--config", "-c", help="Configuration: machine, tools, stock.")
    ],
    stability: Annotated[
        list[str],
        typer.Option(
            "--stability",
            help="Stability file (modes, coefficients, method, rpm) for every milling tool, "
            "a tool map ([tools] T1 = FILE), or T<n>=FILE once per tool (tools without one "
            "keep their speed).",
        ),
    ],
    margin: Annotated[
        float, typer.Option("--margin", help="Critical depth at least this times the depth.")
    ] = 1.2,
    method: Annotated[
        str | None, typer.Option("--method", help="zoa or sdm (default: the stability file).")
    ] = None,
    rpm_range: Annotated[
        str | None,
        typer.Option("--rpm-range", help="MIN:MAX:N speed grid (default: file's, every 10 rpm)."),
    ] = None,
    density: Density = None,
    step_mm: Annotated[
        float | None,
        typer.Option("--step-mm", help="Map step along the path, mm (default 1/density)."),
    ] = None,
    sdm_points: Annotated[
        int | None,
        typer.Option("--sdm-points", help="sdm: speeds at which lobes are computed (default 40)."),
    ] = None,
    plot: Annotated[
        Path | None, typer.Option("--plot", help="Write the roadmap and lobes to this PNG.")
    ] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    html: HtmlReport = None,
) -> None:
    """Stability roadmap: stable spindle speeds per program segment and a speed schedule.

    Per segment (a program line's cut) the widest immersion and largest depth; the speeds
    whose critical depth is at least --margin times that depth; the scheduled speed: the
    programmed one if stable, else the nearest stable one (Ward 2021, Fig. 12).
    """
    from cnctwin.config import load_config
    from cnctwin.dynamics import load_stability_config, load_tool_stability

    if not (math.isfinite(margin) and 1.0 <= margin <= MAX_MARGIN):
        raise InputError(f"--margin {margin!r}; give a factor >= 1 and <= {MAX_MARGIN:g}")
    if html is not None:
        check_report_path(html)
    if method is not None and method not in ("zoa", "sdm"):
        raise InputError(f"--method {method!r}; give zoa or sdm")
    files = parse_stability_options(stability)
    settings = load_config(config)
    modes: StabilityConfig | dict[int, StabilityConfig]
    if isinstance(files, Path):
        modes = load_tool_stability(files)
    else:
        modes = {number: load_stability_config(path) for number, path in files.items()}
    report, result = roadmap_report(
        program, settings, modes, margin=margin, rpm_range=rpm_range,
        density_per_mm=density, step_mm=step_mm, method=method, sdm_points=sdm_points,
        progress=ProgressLine("stability roadmap"),
    )  # fmt: skip
    if plot is not None:
        _plot(plot, result, program.name)
    if html is not None:
        from cnctwin.report import roadmap_report as write_roadmap_report

        write_roadmap_report(html, report, result, program.name)
    if as_json:
        sys.stdout.write(finite_json.dumps(report) + "\n")
        return
    Console().print(_table(report))


def _table(report: dict[str, Any]) -> Table:
    table = Table(
        title=f"stability roadmap: {report['program']} ({report['method']}, "
        f"margin {report['margin']:g})",
        title_justify="left",
        caption=f"speeds {report['spindle_rpm_min']:.0f}-{report['spindle_rpm_max']:.0f} rpm "
        f"({report['spindle_rpm_points']} points); {len(report['engagements'])} engagements "
        f"in {report['seconds']:.2f} s",
        caption_justify="left",
    )
    for name in ("line", "s [mm]", "ap [mm]", "ae/D", "programmed", "a_lim there", "scheduled"):
        table.add_column(name, justify="right")
    for row in report["segments"]:
        limit = row["programmed_critical_depth_mm"]
        scheduled = row["scheduled_rpm"]
        if row["tool"] in report["tools_without_modes"]:
            verdict = f"T{row['tool']} has no modes: kept"
        elif row["entry_deg"] is None:
            verdict = "plunge (no lobes)"
        elif scheduled is None:
            verdict = "[red]no stable speed[/red]"
        elif row["programmed_stable"]:
            verdict = "kept"
        else:
            verdict = f"[yellow]{scheduled:.0f} rpm[/yellow]"
        table.add_row(
            str(row["line"]),
            f"{row['start_s_mm']:.1f}-{row['end_s_mm']:.1f}",
            f"{row['ap_mm']:.2f}",
            f"{row['radial_immersion']:.2f}",
            f"{row['programmed_rpm']:.0f}",
            "-" if limit is None else f"{limit:.3g} mm",
            verdict,
        )
    return table


def _plot(path: Path, result: StabilityRoadmap, title: str) -> None:
    """Ward 2021 Fig. 12: unstable speeds along the path with the schedule; and the lobes."""
    from matplotlib.colors import ListedColormap
    from matplotlib.figure import Figure  # matplotlib only when asked for

    grid = result.spindle_rpm
    segments = [s for s in result.segments if s.lobes >= 0]
    figure = Figure(figsize=(13.0, 5.0), dpi=100, layout="constrained")
    road, lobes_axes = figure.subplots(1, 2, width_ratios=(3, 2))
    step = float(np.median(np.diff(grid))) if grid.size > 1 else 1.0
    edges = np.concatenate(([grid[0] - step / 2], 0.5 * (grid[1:] + grid[:-1]),
                            [grid[-1] + step / 2]))  # fmt: skip
    for seg in segments:
        critical = result.lobes[seg.lobes].critical_depth_mm
        unstable = (critical < result.margin * seg.ap_mm).astype(float)[:, None]
        end = max(seg.end_s_mm, seg.start_s_mm + 1e-6)
        road.pcolormesh([seg.start_s_mm, end], edges, unstable, vmin=0, vmax=1,
                        cmap=ListedColormap(["white", "tab:red"]), alpha=0.6)  # fmt: skip
    for i, seg in enumerate(segments):
        a, b = seg.start_s_mm, seg.end_s_mm
        road.plot([a, b], [seg.programmed_rpm] * 2, color="black", linewidth=1.5,
                  label="programmed" if i == 0 else None)  # fmt: skip
        if seg.has_stable_speed:
            road.plot([a, b], [seg.scheduled_rpm] * 2, color="tab:blue", linewidth=2.5,
                      label="scheduled" if i == 0 else None)  # fmt: skip
    road.set_ylim(edges[0], edges[-1])
    road.set_xlabel("path length s [mm]")
    road.set_ylabel("spindle speed [rpm]")
    road.set_title(f"{title}: stability roadmap (red: chatter at the segment's depth "
                   f"x {result.margin:g})")  # fmt: skip
    road.legend(loc="upper right", fontsize="small")
    shown = sorted({seg.lobes for seg in segments})[:8]
    colours = [f"C{i}" for i in range(len(shown))]
    top = 0.0
    for colour, index in zip(colours, shown, strict=True):
        lobe = result.lobes[index]
        depth = np.where(np.isfinite(lobe.critical_depth_mm), lobe.critical_depth_mm, np.nan)
        label = f"{math.degrees(lobe.entry_rad):.0f}-{math.degrees(lobe.exit_rad):.0f} deg"
        lobes_axes.plot(grid, depth, color=colour, linewidth=1.0, label=label)
        mine = [seg for seg in segments if seg.lobes == index]
        lobes_axes.plot([s.programmed_rpm for s in mine], [s.ap_mm for s in mine], "x",
                        color=colour)  # fmt: skip
        moved = [s for s in mine if s.has_stable_speed and not s.programmed_stable]
        lobes_axes.plot([s.scheduled_rpm for s in moved], [s.ap_mm for s in moved], "o",
                        color=colour, markerfacecolor="none")  # fmt: skip
        top = max(top, max(s.ap_mm for s in mine))
    lobes_axes.set_ylim(0.0, 3.0 * top if top > 0.0 else 1.0)
    lobes_axes.set_xlim(grid[0], grid[-1])
    lobes_axes.set_xlabel("spindle speed [rpm]")
    lobes_axes.set_ylabel("axial depth of cut [mm]")
    lobes_axes.set_title("lobes per engagement: x programmed, o scheduled")
    lobes_axes.grid(alpha=0.3)
    lobes_axes.legend(loc="upper left", fontsize="small", title="immersion")
    figure.savefig(path)
