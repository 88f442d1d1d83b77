"""``cnctwin optimize``: the program rewritten with the feed (and speed) per block its limits allow.

The command reads the program and the configuration, checks the options, calls
:func:`cnctwin.optimize.optimize_program` (and, with ``--stability``, the stability roadmap of
:mod:`cnctwin.dynamics` for the speeds), writes the program and the report, and prints the
figures. What the feeds are and how they are found: docs/optimize.md.
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.table import Table

from cnctwin import finite_json
from cnctwin.cli._options import CycleMs, Density
from cnctwin.cli.simulate import resolution
from cnctwin.errors import InputError

__all__ = ["optimize"]

#: Blocks listed in the table (the JSON lists them all).
_TABLE_BLOCKS = 40


def optimize(
    program: Annotated[Path, typer.Argument(help="NC program.")],
    config: Annotated[
        Path, typer.Option("--config", "-c", help="Configuration TOML or CAMotics project.")
    ],
    out: Annotated[Path, typer.Option("--out", help="Write the optimised program here.")],
    max_force_n: Annotated[
        float | None, typer.Option("--max-force-n", help="Force limit on the tool, N.")
    ] = None,
    force_metric: Annotated[
        str,
        typer.Option(
            "--force-metric", help="What the force limit bounds: peak (over a revolution) or mean."
        ),
    ] = "peak",
    max_power_w: Annotated[
        float | None, typer.Option("--max-power-w", help="Cutting power limit, W.")
    ] = None,
    max_chip_mm: Annotated[
        float | None, typer.Option("--max-chip-mm", help="Uncut chip thickness limit, mm.")
    ] = None,
    stability: Annotated[
        Path | None,
        typer.Option(
            "--stability",
            help="Stability file or tool map: spindle speeds from the program's roadmap.",
        ),
    ] = None,
    min_feed: Annotated[
        float | None,
        typer.Option("--min-feed", help="Least feed written, mm/min (default: F / 10)."),
    ] = None,
    max_feed: Annotated[
        float | None,
        typer.Option("--max-feed", help="Most feed written, mm/min (default: the axes' speed)."),
    ] = None,
    max_factor: Annotated[
        float, typer.Option("--max-factor", help="Most a feed may grow over the programmed one.")
    ] = 2.0,
    air_feed: Annotated[
        float | None,
        typer.Option("--air-feed", help="Feed of pieces that cut nothing, mm/min (default: kept)."),
    ] = None,
    report: Annotated[
        Path | None, typer.Option("--report", help="Write the report as JSON here.")
    ] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    density: Density = None,
    cycle_ms: CycleMs = None,
) -> None:
    """Rewrite a program's feeds (and speeds) per block from force, power and chip limits."""
    from cnctwin.config import load_config
    from cnctwin.mechanics import milling_material
    from cnctwin.optimize import FeedLimits, optimize_program, scheduled_speeds

    if not math.isfinite(max_factor):
        raise InputError(f"--max-factor {max_factor!r}: give a finite number")
    if force_metric not in ("peak", "mean"):
        raise InputError(f"--force-metric {force_metric!r}: give peak or mean")
    if out.resolve() == program.resolve():
        raise InputError(f"--out {out}: give a file other than the program")
    limits = FeedLimits(max_force_n, max_power_w, max_chip_mm, force_metric)  # type: ignore[arg-type]
    settings = load_config(config)
    rho, cycle_s = resolution(settings, density, cycle_ms)
    try:
        text = program.read_text(encoding="utf-8", errors="replace")
    except OSError as err:
        raise InputError(f"{program}: cannot read the program ({err.strerror})") from None
    # The forces are the configuration's material's, with or without a stability file (whose
    # own [cut] coefficients, if any, serve its lobes).
    try:
        coefficients = milling_material(settings.material.name).coefficients
    except InputError as err:
        raise InputError(f"{config}: material.name: {err}") from None
    started = time.perf_counter()
    speeds = None
    if stability is not None:
        from cnctwin.dynamics import load_tool_stability, program_roadmap

        modes = load_tool_stability(stability)
        speeds = scheduled_speeds(program_roadmap(program, settings, modes, density_per_mm=rho))
    result = optimize_program(
        text, str(program), settings, limits, coefficients=coefficients,
        density_per_mm=rho, cycle_s=cycle_s, speeds_rpm=speeds, min_feed_mm_min=min_feed,
        max_feed_mm_min=max_feed, max_factor=max_factor, air_feed_mm_min=air_feed,
    )  # fmt: skip
    summary: dict[str, Any] = {
        "program": str(program),
        "out": str(out),
        **result.summary(),
        "runtime_s": time.perf_counter() - started,
    }
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(result.text)
    if report is not None:
        report.parent.mkdir(parents=True, exist_ok=True)
        report.write_text(finite_json.dumps(summary, indent=2) + "\n")
    if as_json:
        sys.stdout.write(finite_json.dumps(summary) + "\n")
    else:
        _print(summary)
    warn = Console(stderr=True)
    for warning in summary["warnings"]:
        warn.print(f"warning: {warning}", style="yellow", markup=False, highlight=False)


def _print(summary: dict[str, Any]) -> None:
    console = Console()
    head = Table(title=f"{summary['program']} -> {summary['out']}", show_header=False,
                 title_justify="left")  # fmt: skip
    before, after = summary["cycle_time_before_s"], summary["cycle_time_after_s"]
    head.add_row(
        "cycle time", f"{before:.4g} s -> {after:.4g} s ({summary['cycle_time_change_pct']:+.1f} %)"
    )
    limits = summary["limits"]
    for key, unit, limit in (
        ("max_force_n" if limits["force_metric"] == "peak" else "max_mean_force_n", "N",
         limits["max_force_n"]),
        ("max_power_w", "W", limits["max_power_w"]),
        ("max_chip_mm", "mm", limits["max_chip_mm"]),
    ):  # fmt: skip
        bound = "free" if limit is None else f"limit {limit:.4g} {unit}"
        head.add_row(
            key, f"{summary['before'][key]:.4g} -> {summary['after'][key]:.4g} {unit} ({bound})"
        )
    head.add_row("every limit holds", "yes" if summary["limits_hold"] else "NO")
    head.add_row("cuts of the optimised program", str(summary["passes"]))
    head.add_row("runtime", f"{summary['runtime_s']:.3g} s")
    console.print(head)
    blocks = Table(title="feed blocks", title_justify="left")
    for name in ("line", "F mm/min", "new F mm/min", "S rpm", "limit", "time s", "note"):
        blocks.add_column(name)
    rows = summary["blocks"]
    for row in rows[:_TABLE_BLOCKS]:
        new = row["new_feed_mm_min"]
        s = f"{row['rpm']:.0f}" + (
            f" -> {row['new_rpm']:.0f}" if row["new_rpm"] != row["rpm"] else ""
        )
        blocks.add_row(
            str(row["line"]), f"{row['feed_mm_min']:.4g}", " / ".join(f"{f:.4g}" for f in new), s,
            row["limit"], f"{row['time_before_s']:.3g} -> {row['time_after_s']:.3g}", row["note"],
        )  # fmt: skip
    if len(rows) > _TABLE_BLOCKS:
        blocks.caption = f"{len(rows) - _TABLE_BLOCKS} more blocks: see --json or --report"
    console.print(blocks)
