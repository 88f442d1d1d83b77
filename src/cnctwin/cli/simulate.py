"""``cnctwin simulate``: run an NC program through the tri-dexel stock, offline."""

from __future__ import annotations

import csv
import math
import sys
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import typer
from rich.console import Console
from rich.table import Table

from cnctwin import finite_json
from cnctwin.cli._options import CycleMs, Density, HtmlReport, progress
from cnctwin.config import (
    MAX_CYCLE_MS,
    MAX_DENSITY_PER_MM,
    MIN_CYCLE_MS,
    MIN_DENSITY_PER_MM,
    MachiningConfig,
    load_config,
)
from cnctwin.errors import InputError
from cnctwin.report import check_report_path

__all__ = ["STL_RESOLUTION_MM", "resolution", "simulate", "simulate_report"]

#: Default size of the cells of the written stock.stl, mm (the demo's file: about 2 MB).
STL_RESOLUTION_MM = 0.5


def resolution(
    settings: MachiningConfig, density: float | None, cycle_ms: float | None
) -> tuple[float, float]:
    """Dexel density (per mm) and cycle time (s): the options where given, else the config's
    ``[simulation]``; a one-line :class:`InputError` for values out of range."""
    rho = density if density is not None else settings.simulation.density_per_mm
    cycle = cycle_ms if cycle_ms is not None else settings.simulation.cycle_ms
    if not (MIN_DENSITY_PER_MM <= rho <= MAX_DENSITY_PER_MM):
        raise InputError(
            f"--density {rho}: give {MIN_DENSITY_PER_MM:g} <= density <= "
            f"{MAX_DENSITY_PER_MM:g} dexels per mm"
        )
    if not (MIN_CYCLE_MS <= cycle <= MAX_CYCLE_MS):
        raise InputError(
            f"--cycle-ms {cycle}: give {MIN_CYCLE_MS:g} <= cycle <= {MAX_CYCLE_MS:g} ms"
        )
    return rho, cycle / 1e3


def simulate_report(
    program: Path,
    config: MachiningConfig,
    *,
    density_per_mm: float,
    cycle_s: float,
    out: Path | None = None,
    progress_bar: bool = False,
    html: Path | None = None,
    stl_resolution_mm: float | None = STL_RESOLUTION_MM,
    stl_ascii: bool = False,
) -> dict[str, Any]:
    """Run the program through the stock (:func:`~cnctwin.simulation.simulate_program`),
    write the outputs to ``out`` (``engagement.csv``, ``stock.stl``, ``summary.json``;
    created) and return the summary (:meth:`~cnctwin.simulation.ProgramCut.summary`).
    ``progress_bar`` shows a progress bar on stderr; ``html`` is the file of the HTML report
    (:func:`~cnctwin.report.simulation.simulation_report`); ``stl_resolution_mm`` the cell size
    of ``stock.stl`` (``None``: the dexel pitch; :func:`~cnctwin.geometry.stock_mesh`),
    ``stl_ascii`` its format (else binary)."""
    from cnctwin.geometry import stock_mesh, write_stl
    from cnctwin.simulation import COLUMNS, simulate_program

    with progress("simulating", progress_bar) as on_chunk:
        cut = simulate_program(
            program, config, density_per_mm=density_per_mm, cycle_s=cycle_s, on_chunk=on_chunk
        )
    report = cut.summary()
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        with (out / "engagement.csv").open("w", newline="") as handle:
            writer = csv.writer(handle)
            writer.writerow(COLUMNS)
            data = np.column_stack([cut.table.column(name) for name in COLUMNS])
            for row in data:
                # t_s to 12 digits: a segment end lies between two cycle times.
                writer.writerow([f"{row[0]:.12g}", *(f"{v:.6g}" for v in row[1:])])
        write_stl(
            out / "stock.stl",
            stock_mesh(cut.stock, stl_resolution_mm),
            f"cnctwin stock after {program.name}",
            binary=not stl_ascii,
        )
        (out / "summary.json").write_text(finite_json.dumps(report, indent=2) + "\n")
    if html is not None:
        from cnctwin.report import simulation_report

        simulation_report(html, report, cut.table, cut.stock)
    return report


def simulate(
    program: Annotated[Path, typer.Argument(help="NC program.")],
    config: Annotated[
        Path, typer.Option("--config", "-c", help="Configuration TOML or CAMotics project.")
    ],
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    out: Annotated[
        Path | None, typer.Option("--out", help="Write engagement.csv, stock.stl, summary.json.")
    ] = None,
    density: Density = None,
    cycle_ms: CycleMs = None,
    html: HtmlReport = None,
    stl_resolution_mm: Annotated[
        float,
        typer.Option(
            "--stl-resolution-mm",
            help="Cell size of stock.stl in mm (the dexel pitch or less: every dexel).",
        ),
    ] = STL_RESOLUTION_MM,
    stl_ascii: Annotated[
        bool, typer.Option("--stl-ascii", help="Write stock.stl as text (else binary).")
    ] = False,
) -> None:
    """Cut the stock along a program: engagement per step, removed volume, final stock."""
    if html is not None:
        check_report_path(html)
    settings = load_config(config)
    rho, cycle_s = resolution(settings, density, cycle_ms)
    if not (math.isfinite(stl_resolution_mm) and stl_resolution_mm > 0.0):
        raise InputError(
            f"--stl-resolution-mm {stl_resolution_mm}: give a resolution > 0 mm "
            "(below the dexel pitch: the pitch)"
        )
    report = simulate_report(
        program,
        settings,
        density_per_mm=rho,
        cycle_s=cycle_s,
        out=out,
        progress_bar=not as_json and sys.stderr.isatty(),
        html=html,
        stl_resolution_mm=stl_resolution_mm,
        stl_ascii=stl_ascii,
    )
    if as_json:
        sys.stdout.write(finite_json.dumps(report) + "\n")
        return
    table = Table(title=str(program), show_header=False, title_justify="left")
    for key in (
        "steps",
        "process_time_s",
        "runtime_s",
        "realtime_factor",
        "removed_volume_mm3",
        "max_ae_mm",
        "max_ap_mm",
        "max_mrr_mm3_s",
    ):
        value = report[key]
        table.add_row(key, f"{value:.4g}" if isinstance(value, float) else str(value))
    Console().print(table)
    warn = Console(stderr=True)
    for warning in report["warnings"]:
        warn.print(f"warning: {warning}", style="yellow", markup=False, highlight=False)
