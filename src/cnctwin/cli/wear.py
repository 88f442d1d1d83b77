"""``cnctwin wear``: tool wear twins. ``simulate-lathe`` re-runs Bolyn 2023's Tests 1-6.

Each command is a function registered on :data:`app`; a command group of its own (the EKF,
the compensation registry) adds its commands to the same app.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.table import Table

from cnctwin import finite_json
from cnctwin.wear import DEFAULT_PARTS, LatheRun, run_test

__all__ = ["app", "simulate_lathe", "simulate_lathe_report"]

app = typer.Typer(help="Tool wear twins: monitoring and compensation.", no_args_is_help=True)

_UM = 1e-6


@app.callback()
def _wear() -> None:
    """Tool wear twins: monitoring and compensation."""


def _um(value_m: float | None) -> float | None:
    """A length in m as um, rounded to 1 nm; None stays None."""
    return None if value_m is None else round(value_m / _UM, 3)


def simulate_lathe_report(run: LatheRun, test: int, seed: int) -> dict[str, Any]:
    """The JSON of ``cnctwin wear simulate-lathe``.

    Parameters
    ----------
    run
        A simulated run.
    test, seed
        What produced it.

    Returns
    -------
    dict
        ``test``, ``name``, ``seed``, ``parts``, ``parts_before_trusted``,
        ``first_trusted_part``, ``max_abs_deviation_um`` (true dimensions),
        ``max_abs_measured_deviation_um``, ``out_of_tolerance`` (parts outside the
        interval), ``heritage_used``, ``heritage_slope_um_per_part``,
        ``final_slope_um_per_part``, ``final_sigma_um``, ``tolerance_um`` (limits relative to
        the target), ``target_mm``, and per part: ``deviation_um``,
        ``measured_deviation_um``, ``correction_um`` (applied after the part; the first entry
        of ``offset_um`` is the one applied before part 1 from the heritage), ``offset_um``
        (in force when the part was made), ``slope_um_per_part``,
        ``slope_in_use_um_per_part`` (what the next correction was based on, null when
        none), ``relative_change``, ``trusted``.
    """
    case = run.scenario
    last = run.observations[-1]
    return {
        "test": test,
        "name": case.name,
        "seed": seed,
        "parts": run.parts,
        "parts_before_trusted": run.parts_before_trusted,
        "first_trusted_part": run.first_trusted_part,
        "max_abs_deviation_um": _um(run.max_abs_deviation),
        "max_abs_measured_deviation_um": _um(float(abs(run.measured_deviation).max())),
        "out_of_tolerance": run.out_of_tolerance,
        "heritage_used": run.heritage is not None,
        "heritage_slope_um_per_part": _um(run.heritage.slope if run.heritage else None),
        "final_slope_um_per_part": _um(last.slope),
        "final_sigma_um": _um(last.sigma),
        "tolerance_um": [_um(case.lower - case.target), _um(case.upper - case.target)],
        "target_mm": round(case.target * 1e3, 6),
        "deviation_um": [_um(float(v)) for v in run.deviation],
        "measured_deviation_um": [_um(float(v)) for v in run.measured_deviation],
        "correction_um": [_um(o.correction) for o in run.observations],
        "offset_um": [_um(float(v)) for v in run.offset],
        "slope_um_per_part": [_um(o.slope) for o in run.observations],
        "slope_in_use_um_per_part": [_um(o.slope_in_use) for o in run.observations],
        "relative_change": [
            None if o.relative_change is None else round(o.relative_change, 6)
            for o in run.observations
        ],
        "trusted": [o.trusted for o in run.observations],
    }


@app.command("simulate-lathe")
def simulate_lathe(
    test: Annotated[
        int, typer.Option("--test", min=1, max=6, help="The paper's test, 1-6 (Tables 2-3).")
    ],
    seed: Annotated[int, typer.Option("--seed", min=0, help="Seed of the process scatter.")] = 0,
    parts: Annotated[
        int, typer.Option("--parts", min=1, max=100_000, help="Parts made by the tool.")
    ] = DEFAULT_PARTS,
    plot: Annotated[
        Path | None,
        typer.Option("--plot", help="Draw deviations, tolerance, corrections and slope to a PNG."),
    ] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
) -> None:
    """Simulate a tool life on a lathe with wear compensation (Bolyn 2023, section IV)."""
    run = run_test(test, seed, parts)
    report = simulate_lathe_report(run, test, seed)
    if plot is not None:
        _plot(run, report, plot)
    if as_json:
        sys.stdout.write(finite_json.dumps(report) + "\n")
        return
    console = Console()
    console.print(_table(report))
    console.print(_summary(report))
    if plot is not None:
        console.print(f"plot written to {plot}")


def _table(report: dict[str, Any]) -> Table:
    table = Table(title=f"{report['name']}, seed {report['seed']}", title_justify="left")
    for column in ("part", "deviation", "measured", "slope", "change", "trusted", "correction"):
        table.add_column(column, justify="right")
    rows = zip(
        report["deviation_um"],
        report["measured_deviation_um"],
        report["slope_um_per_part"],
        report["relative_change"],
        report["trusted"],
        report["correction_um"],
        strict=True,
    )
    for part, (dev, meas, slope, change, trusted, corr) in enumerate(rows, start=1):
        table.add_row(
            str(part),
            f"{dev:+.2f} um",
            f"{meas:+.1f} um",
            f"{slope:.3f} um/part",
            "-" if change is None else f"{100 * change:.1f} %",
            "yes" if trusted else "no",
            f"{corr:+.0f} um" if corr else "",
        )
    return table


def _summary(report: dict[str, Any]) -> Table:
    table = Table(show_header=False)
    table.add_column("quantity", style="bold")
    table.add_column("value", justify="right")
    before = report["parts_before_trusted"]
    table.add_row("slope trusted for good after part", "never" if before is None else str(before))
    table.add_row("max |deviation|", f"{report['max_abs_deviation_um']:.2f} um")
    table.add_row("parts out of tolerance", str(report["out_of_tolerance"]))
    heritage = report["heritage_slope_um_per_part"]
    table.add_row("heritage", "none" if heritage is None else f"{heritage:.3f} um/part")
    table.add_row("final slope", f"{report['final_slope_um_per_part']:.3f} um/part")
    sigma = report["final_sigma_um"]
    table.add_row("final scatter", "-" if sigma is None else f"{sigma:.2f} um")
    return table


def _plot(run: LatheRun, report: dict[str, Any], path: Path) -> None:
    """Draw a run as the paper's Figures 6-15 do.

    Three panels: the deviation of each part in the tolerance band; the drift (measurements
    less corrections) with the cumulative correction; the slope, the slope in use and its
    relative change against the criterion.
    """
    from matplotlib.figure import Figure  # matplotlib only when asked for

    parts = list(range(1, run.parts + 1))
    low, high = report["tolerance_um"]
    figure = Figure(figsize=(8.0, 8.0), dpi=100, layout="constrained")
    top, middle, bottom = figure.subplots(3, 1, sharex=True)
    top.axhspan(low, high, color="tab:green", alpha=0.12, label="tolerance interval")
    top.axhline(0.0, color="black", linewidth=0.6)
    top.plot(parts, report["deviation_um"], "o-", markersize=3, label="produced")
    top.plot(
        parts, report["measured_deviation_um"], "s", markersize=3, mfc="none", label="measured"
    )
    top.set_ylabel("deviation from target [um]")
    top.legend(loc="best", fontsize="small")
    uncorrected = [
        m - c for m, c in zip(report["measured_deviation_um"], report["offset_um"], strict=True)
    ]
    middle.plot(parts, uncorrected, "o", markersize=3, label="measured - corrections (drift)")
    middle.step(
        parts, report["offset_um"], where="mid", color="tab:red", label="cumulative correction"
    )
    middle.plot(
        parts,
        [report["final_slope_um_per_part"] * p for p in parts],
        ":",
        color="tab:gray",
        label="final drift b i",
    )
    middle.set_ylabel("[um]")
    middle.legend(loc="best", fontsize="small")
    bottom.plot(parts, report["slope_um_per_part"], "o-", markersize=3, label="slope b")
    bottom.step(
        parts,
        [float("nan") if v is None else v for v in report["slope_in_use_um_per_part"]],
        where="post",
        color="tab:red",
        label="slope in use",
    )
    if run.heritage is not None:
        bottom.axhline(
            report["heritage_slope_um_per_part"],
            color="tab:purple",
            linestyle="--",
            label="inherited slope",
        )
    bottom.set_ylabel("slope [um/part]")
    bottom.set_xlabel("part produced")
    change = bottom.twinx()
    change.plot(
        parts,
        [float("nan") if c is None else 100 * c for c in report["relative_change"]],
        ".-",
        color="tab:orange",
        label="relative change",
    )
    change.axhline(100 * run.lathe.criterion, color="tab:orange", linestyle=":", label="criterion")
    change.set_ylim(0, 50)
    change.set_ylabel("relative change [%]")
    bottom.legend(loc="upper left", fontsize="small")
    change.legend(loc="upper right", fontsize="small")
    top.set_title(f"{run.scenario.name} (Bolyn 2023), seed {report['seed']}")
    figure.savefig(path)
