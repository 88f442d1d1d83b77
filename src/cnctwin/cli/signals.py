"""``cnctwin signals``: predicted machine signals of an NC program (forces, spindle, feed drives).

The program is cut through the dexel stock as ``cnctwin simulate`` does; at every cycle the
engagement gives the cutting forces of the configured material, the cutting torque loads the
configured spindle drive (``[machine.spindle]``), and the results are written as a CSV table
with a plot. Units, frames and signs: docs/signals.md.
"""

from __future__ import annotations

import csv
import itertools
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer
from rich.console import Console
from rich.table import Table

from cnctwin import finite_json
from cnctwin.cli._options import CycleMs, Density, progress
from cnctwin.cli.simulate import resolution
from cnctwin.config import MachiningConfig, load_config

if TYPE_CHECKING:
    from cnctwin.simulation import MachineSignals

__all__ = ["signals", "signals_report"]


def signals_report(
    program: Path,
    config: MachiningConfig,
    *,
    density_per_mm: float,
    cycle_s: float,
    out: Path | None = None,
    plot: Path | None = None,
    progress_bar: bool = False,
) -> dict[str, Any]:
    """Predict the signals of a program (:func:`~cnctwin.simulation.predict_program_signals`),
    write the outputs to ``out`` (``signals.csv``, ``signals.png``, ``summary.json``; created)
    and ``plot`` (PNG, instead of ``out/signals.png``), return the summary
    (:meth:`~cnctwin.simulation.ProgramSignals.summary`). ``progress_bar`` shows a progress
    bar on stderr."""
    from cnctwin.simulation import predict_program_signals

    with progress("predicting signals", progress_bar) as on_chunk:
        predicted = predict_program_signals(
            program, config, density_per_mm=density_per_mm, cycle_s=cycle_s, on_chunk=on_chunk
        )
    result = predicted.signals
    report = predicted.summary()
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        _write_csv(out / "signals.csv", result)
        (out / "summary.json").write_text(finite_json.dumps(report, indent=2) + "\n")
        if plot is None:
            plot = out / "signals.png"
    if plot is not None:
        _plot(plot, result, program.name, (config.stock.min_mm, config.stock.max_mm))
    return report


def _write_csv(path: Path, result: MachineSignals) -> None:
    from cnctwin.simulation import SIGNAL_COLUMNS

    with path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(SIGNAL_COLUMNS)
        for row in result.table():
            # t_s to 12 digits: a segment end lies between two cycle times.
            writer.writerow([f"{row[0]:.12g}", *(f"{v:.6g}" for v in row[1:])])


def _plot(path: Path, result: MachineSignals, title: str, stock_mm: Any) -> None:
    """Four panels over time: axis forces, torques, powers, spindle current and speed; beside
    them the tool tip's path from above with the stock (``stock_mm``: its two corners, mm).

    The torque, power and current panels are scaled to the cutting; a higher transient (the
    spindle's start-up) is clipped and its peak named in the legend. The path view is limited
    to the stock and the cutting; moves in air are faint and clipped at its edge.
    """
    import numpy as np
    from matplotlib.figure import Figure  # matplotlib only when asked for

    from cnctwin.nc import draw_top_view

    c = result.columns
    t = c["t_s"]
    contact = c["contact"] > 0
    figure = Figure(figsize=(15.0, 9.0), dpi=100, layout="constrained")
    grid = figure.add_gridspec(4, 2, width_ratios=(2.0, 1.0))
    forces = figure.add_subplot(grid[0, 0])
    torque, power, current = (figure.add_subplot(grid[k, 0], sharex=forces) for k in (1, 2, 3))
    # Runs of steps in and out of contact, each ending where the next begins.
    xyz = np.column_stack([c["x_mm"], c["y_mm"], c["z_mm"]]).tolist()
    cuts = [0, *(np.flatnonzero(np.diff(contact)) + 1).tolist(), len(xyz)]
    runs = [
        (not bool(contact[a]), [tuple(p) for p in xyz[a : min(b + 1, len(xyz))]])
        for a, b in itertools.pairwise(cuts)
        if b > a
    ]
    path_view = figure.add_subplot(grid[:, 1])
    outside = draw_top_view(path_view, runs, stock_mm, labels=("cutting", "not cutting"))
    path_view.legend(loc="upper right", fontsize="small")
    if outside:
        path_view.set_title(f"top view (XY); {outside} moves in air clipped at the edge")
    figure.suptitle(f"{title}: predicted machine signals ({result.drive})")
    for name, label in (("fx_n", "Fx"), ("fy_n", "Fy"), ("fz_n", "Fz")):
        forces.plot(t, c[name], linewidth=0.8, label=f"{label} (mean)")
    forces.plot(t, c["f_peak_n"], color="black", linewidth=0.6, alpha=0.5, label="|F| peak")
    forces.set_ylabel("force on the tool [N]")
    forces.legend(loc="upper right", fontsize="small", ncols=4)
    panels = (
        (torque, "torque [N m]", "N m", (("cutting_torque_nm", "cutting torque"),
                                         ("motor_torque_nm", "motor torque (drive)"))),
        (power, "power [W]", "W", (("cutting_power_w", "cutting power"),
                                   ("spindle_power_w", "spindle power (drive)"))),
        (current, "spindle current [A]", "A", (("spindle_current_a", "current (drive)"),)),
    )  # fmt: skip
    for axes, ylabel, unit, series in panels:
        top = _scale([c[name] for name, _ in series], contact)
        for name, label in series:
            peak = float(c[name].max()) if t.size else 0.0
            if top is not None and peak > top:
                label = f"{label}; transient to {peak:.3g} {unit} off scale"
            axes.plot(t, c[name], linewidth=0.8, label=label)
        if top is not None:
            axes.set_ylim(-0.1 * top, top)
        axes.set_ylabel(ylabel)
        axes.legend(loc="upper right", fontsize="small")
    current.set_xlabel("time [s]")
    speed = current.twinx()
    speed.plot(t, c["spindle_speed_rpm"], color="tab:gray", linewidth=0.8)
    speed.set_ylabel("spindle speed [rpm] (grey)")
    for axes in (forces, torque, power, current):
        axes.fill_between(
            t, 0, 1, where=contact, color="tab:green", alpha=0.08,
            transform=axes.get_xaxis_transform(), linewidth=0,
        )  # fmt: skip
        axes.grid(alpha=0.3)
    figure.savefig(path)


def _scale(series: list[Any], contact: Any) -> float | None:
    """Upper y limit showing the cutting, or None when nothing rises far above it."""
    import numpy as np

    if not np.any(contact):
        return None
    cutting = max(float(np.max(values[contact])) for values in series)
    highest = max(float(np.max(values)) for values in series)
    return 1.3 * cutting if cutting > 0.0 and highest > 2.0 * cutting else None


def signals(
    program: Annotated[Path, typer.Argument(help="NC program.")],
    config: Annotated[
        Path, typer.Option("--config", "-c", help="Configuration TOML or CAMotics project.")
    ],
    out: Annotated[
        Path | None,
        typer.Option("--out", help="Write signals.csv, signals.png and summary.json here."),
    ] = None,
    plot: Annotated[
        Path | None, typer.Option("--plot", help="Write the plot to this PNG file.")
    ] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    density: Density = None,
    cycle_ms: CycleMs = None,
) -> None:
    """Predicted forces, spindle torque, power and current, and feed-drive loads over time.

    Forces on the tool in machine X, Y, Z (the loads of the feed drives); spindle from the
    [machine.spindle] drive preset; material from the materials library.
    """
    settings = load_config(config)
    rho, cycle_s = resolution(settings, density, cycle_ms)
    report = signals_report(
        program,
        settings,
        density_per_mm=rho,
        cycle_s=cycle_s,
        out=out,
        plot=plot,
        progress_bar=not as_json and sys.stderr.isatty(),
    )
    if as_json:
        sys.stdout.write(finite_json.dumps(report) + "\n")
        return
    table = Table(title=str(program), show_header=False, title_justify="left")
    rows = (
        ("process time", f"{report['process_time_s']:.2f} s"),
        ("cutting time", f"{report['cutting_time_s']:.2f} s"),
        ("material", report["material"]),
        ("spindle drive", report["spindle_drive"]),
        ("max force (peak over a revolution)", f"{report['max_force_n']:.0f} N"),
        ("mean cutting power", f"{report['mean_power_w']:.0f} W"),
        ("max cutting power", f"{report['max_power_w']:.0f} W"),
        ("max cutting torque", f"{report['max_spindle_torque_nm']:.3g} N m"),
        ("max spindle current", f"{report['max_spindle_current_a']:.3g} A"),
        ("mean current while cutting", f"{report['mean_cutting_current_a']:.3g} A"),
        ("overloaded steps", str(report["overload_steps"])),
    )
    for key, value in rows:
        table.add_row(key, value)
    Console().print(table)
    warn = Console(stderr=True)
    for warning in report["warnings"]:
        warn.print(f"warning: {warning}", style="yellow", markup=False, highlight=False)
