"""``cnctwin simulate``: run an NC program through the tri-dexel stock, offline."""

from __future__ import annotations

import csv
import math
import sys
import time
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import typer
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from cnctwin import finite_json
from cnctwin.config import MachiningConfig, load_config
from cnctwin.config.simulation import (
    MAX_CYCLE_MS,
    MAX_DENSITY_PER_MM,
    MIN_CYCLE_MS,
    MIN_DENSITY_PER_MM,
)
from cnctwin.errors import ConfigError, NCError

__all__ = ["resolution", "simulate", "simulate_report"]


def resolution(
    settings: MachiningConfig, density: float | None, cycle_ms: float | None
) -> tuple[float, float]:
    """Dexel density (per mm) and cycle time (s): the options where given, else the config's
    ``[simulation]``; a one-line :class:`ConfigError` for values out of range."""
    rho = density if density is not None else settings.simulation.density_per_mm
    cycle = cycle_ms if cycle_ms is not None else settings.simulation.cycle_ms
    if not (MIN_DENSITY_PER_MM <= rho <= MAX_DENSITY_PER_MM):
        raise ConfigError(
            f"--density {rho}: give {MIN_DENSITY_PER_MM:g} <= density <= "
            f"{MAX_DENSITY_PER_MM:g} dexels per mm"
        )
    if not (MIN_CYCLE_MS <= cycle <= MAX_CYCLE_MS):
        raise ConfigError(
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
    progress: bool = False,
) -> dict[str, Any]:
    """Run the program through the stock; write the outputs; return the summary.

    Parameters
    ----------
    program
        NC file.
    config
        Machine, tools (with geometry) and stock.
    density_per_mm
        Dexel density, 1/mm.
    cycle_s
        Cycle time, s.
    out
        Folder for ``engagement.csv``, ``stock.stl`` and ``summary.json`` (created).
    progress
        Show a progress bar on stderr.

    Returns
    -------
    dict
        ``steps``, ``process_time_s``, ``runtime_s``, ``realtime_factor``,
        ``removed_volume_mm3``, ``max_ae_mm``, ``max_ap_mm``, ``max_mrr_mm3_s``,
        stock volumes, warnings and the settings used.
    """
    from cnctwin.geometry import Cutter, DexelStock
    from cnctwin.geometry.mesh import stock_mesh
    from cnctwin.nc.interpreter import Interpreter
    from cnctwin.simulation.cut import COLUMNS, StepTable, simulate_cut

    cutters = {}
    for tool in config.tools:
        cutters[tool.number] = Cutter.from_tool_config(tool)
    stock_cfg = config.stock
    stock = DexelStock.box(stock_cfg.min_mm, stock_cfg.max_mm, density_per_mm)
    volume_before = stock.volume_mm3()
    interpreter = Interpreter(config.nc_setup())
    table = StepTable()
    started = time.perf_counter()
    segments = interpreter.run_file(program)
    try:
        chunks = simulate_cut(
            segments, stock, cutters, rapid_mm_min=config.machine.rapid_mm_min, cycle_s=cycle_s
        )
        if progress:
            with Progress(
                TextColumn("simulating"),
                BarColumn(),
                TextColumn("{task.fields[t]:.1f} s"),
                TimeElapsedColumn(),
                console=Console(stderr=True),
                transient=True,
            ) as bar:
                task = bar.add_task("cut", total=None, t=0.0)
                for rows in chunks:
                    table.append(rows)
                    bar.update(task, t=float(rows[-1, 0]) if len(rows) else 0.0)
        else:
            for rows in chunks:
                table.append(rows)
    except NCError as err:
        if err.file == "<string>":
            raise NCError(err.message, str(program), err.line, err.column) from None
        raise
    runtime = time.perf_counter() - started
    volume_after = stock.volume_mm3()
    n = len(table)
    process_time = float(table.column("t_s")[-1]) + cycle_s if n else 0.0
    contact = table.column("contact") > 0
    rapid = table.column("rapid") > 0
    warnings = []
    crash = np.flatnonzero(contact & rapid)
    if crash.size:
        warnings.append(
            f"{program}:{int(table.column('line')[crash[0]])}: a rapid move cuts material "
            f"({crash.size} steps in all): a collision on the machine"
        )
    shank = np.flatnonzero(table.column("above_flutes") > 0)
    if shank.size:
        warnings.append(
            f"{program}:{int(table.column('line')[shank[0]])}: material above the flutes "
            f"({shank.size} steps): the shank would rub"
        )
    removed = float(table.column("removed_mm3").sum())
    report: dict[str, Any] = {
        "file": str(program),
        "steps": n,
        "process_time_s": process_time,
        "runtime_s": runtime,
        "realtime_factor": process_time / runtime if runtime > 0 else math.inf,
        "removed_volume_mm3": removed,
        "stock_volume_before_mm3": volume_before,
        "stock_volume_after_mm3": volume_after,
        "volume_balance_mm3": volume_before - volume_after - removed,
        "max_ae_mm": float(table.column("ae_mm").max()) if n else 0.0,
        "max_ap_mm": float(table.column("ap_mm").max()) if n else 0.0,
        "max_mrr_mm3_s": float(table.column("mrr_mm3_s").max()) if n else 0.0,
        "density_per_mm": density_per_mm,
        "cycle_ms": cycle_s * 1e3,
        "warnings": [*interpreter.warnings, *warnings],
    }
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        with (out / "engagement.csv").open("w", newline="") as handle:
            writer = csv.writer(handle)
            writer.writerow(COLUMNS)
            data = np.column_stack([table.column(name) for name in COLUMNS])
            for row in data:
                writer.writerow([f"{v:.6g}" for v in row])
        _write_stl(out / "stock.stl", stock_mesh(stock), program.name)
        (out / "summary.json").write_text(finite_json.dumps(report, indent=2) + "\n")
    return report


def _write_stl(path: Path, triangles: np.ndarray, name: str) -> None:
    """Binary STL: 80-byte header, triangle count, then normal, 3 vertices, attribute."""
    tri = np.asarray(triangles, dtype=np.float32)
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    lengths = np.linalg.norm(normals, axis=1, keepdims=True)
    normals = np.divide(normals, lengths, out=np.zeros_like(normals), where=lengths > 0)
    record = np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    data = np.zeros(len(tri), dtype=record)
    data["n"] = normals
    data["v"] = tri
    with path.open("wb") as handle:
        handle.write(f"cnctwin stock after {name}"[:80].ljust(80).encode("ascii", "replace"))
        handle.write(np.uint32(len(tri)).tobytes())
        handle.write(data.tobytes())


def simulate(
    program: Annotated[Path, typer.Argument(help="NC program.")],
    config: Annotated[
        Path, typer.Option("--config", "-c", help="Configuration TOML or CAMotics project.")
    ],
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    out: Annotated[
        Path | None, typer.Option("--out", help="Write engagement.csv, stock.stl, summary.json.")
    ] = None,
    density: Annotated[
        float | None, typer.Option("--density", help="Dexels per mm (overrides the config).")
    ] = None,
    cycle_ms: Annotated[
        float | None, typer.Option("--cycle-ms", help="Cycle time in ms (overrides the config).")
    ] = None,
) -> None:
    """Cut the stock along a program: engagement per step, removed volume, final stock."""
    settings = load_config(config)
    rho, cycle_s = resolution(settings, density, cycle_ms)
    report = simulate_report(
        program,
        settings,
        density_per_mm=rho,
        cycle_s=cycle_s,
        out=out,
        progress=not as_json and sys.stderr.isatty(),
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
