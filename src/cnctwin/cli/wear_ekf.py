"""``cnctwin wear ekf``: estimate tool wear from a recorded torque series (Christiand 2024)."""

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
from cnctwin.cli._options import MAX_SEED, HtmlReport, check_count, check_number
from cnctwin.errors import DataError
from cnctwin.measurements import read_torque_csv
from cnctwin.report import check_report_path
from cnctwin.wear import (
    CHRISTIAND2024,
    IDLE_TORQUE_NM,
    EKFPreset,
    EKFRun,
    StageMonitor,
    TorqueSeries,
    run_filter,
    synthetic_session,
)

__all__ = ["PRESETS", "ekf"]

#: Filter presets by name.
PRESETS: dict[str, EKFPreset] = {"christiand2024": CHRISTIAND2024}
#: Largest flank wear VB accepted, mm: far beyond the ISO 3685 end-of-life criterion (0.3 mm);
#: no insert survives to it.
MAX_WEAR_MM = 5.0
#: Largest idle torque accepted, N*m: above the spindles of the largest machining centres.
MAX_TORQUE_NM = 1.0e4


def _report(series: TorqueSeries, run: EKFRun, source: str) -> dict[str, Any]:
    report: dict[str, Any] = {
        "source": source,
        "steps": int(series.time_s.size),
        "final_vb_mm": float(run.vb_mm[-1]),
        "final_sd_mm": float(math.sqrt(run.var_mm2[-1])),
        "stage_events": [
            {"stage": e.stage, "time_s": e.time_s, "vb_mm": e.vb_mm, "early": e.early}
            for e in run.events
        ],
    }
    if series.vb_mm is not None:
        known = np.isfinite(series.vb_mm)
        error = np.abs(run.vb_mm[known] - series.vb_mm[known])
        report["mean_abs_error_mm"] = float(error.mean()) if error.size else None
        report["max_abs_error_mm"] = float(error.max()) if error.size else None
    return report


def _write_estimate(path: Path, series: TorqueSeries, run: EKFRun) -> None:
    with path.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(
            ["time_s", "vb_mm", "sd_mm", "prior_vb_mm", "innovation_nm", "gain_mm_per_nm"]
        )
        for k in range(series.time_s.size):
            writer.writerow(
                [
                    f"{series.time_s[k]:.6g}",
                    f"{run.vb_mm[k]:.6g}",
                    f"{math.sqrt(run.var_mm2[k]):.6g}",
                    f"{run.prior_vb_mm[k]:.6g}",
                    f"{run.innovation_nm[k]:.6g}",
                    f"{run.gain_mm_per_nm[k]:.6g}",
                ]
            )


def _plot(path: Path, series: TorqueSeries, run: EKFRun, stages: StageMonitor) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (top, bottom) = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    sd = np.sqrt(run.var_mm2)
    top.fill_between(
        series.time_s, run.vb_mm - 2 * sd, run.vb_mm + 2 * sd, alpha=0.25, label="estimate +- 2 sd"
    )
    top.plot(series.time_s, run.vb_mm, label="EKF estimate")
    if series.vb_mm is not None:
        top.plot(series.time_s, series.vb_mm, "k--", label="true wear")
    for level in stages.boundaries_mm:
        top.axhline(level, color="grey", lw=0.6)
    for event in run.events:
        top.axvline(event.time_s, color="red" if event.early else "orange", lw=0.8)
    top.set_ylabel("VB [mm]")
    top.legend(loc="upper left")
    bottom.plot(series.time_s, series.torque_nm * 1e3, ".", ms=1, label="measured torque")
    bottom.set_ylabel("torque [mN m]")
    bottom.set_xlabel("time [s]")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def ekf(
    data: Annotated[
        Path | None, typer.Option("--data", help="CSV: time_s, torque_nm, material_removed_mm3.")
    ] = None,
    synthetic: Annotated[
        bool, typer.Option("--synthetic", help="Generate a session from the preset's own model.")
    ] = False,
    seed: Annotated[int, typer.Option("--seed", help="Seed of --synthetic.")] = 1,
    preset: Annotated[str, typer.Option("--preset", help="Filter preset.")] = "christiand2024",
    vb0_mm: Annotated[float, typer.Option("--vb0-mm", help="Initial estimate, mm.")] = 0.03,
    stages_mm: Annotated[
        tuple[float, float, float],
        typer.Option("--stages-mm", help="Wear at the start of stages II, III, IV, mm."),
    ] = (0.05, 0.2, 0.55),
    base_torque_nm: Annotated[
        float,
        typer.Option("--base-torque-nm", help="Torque without wear if the CSV has no column."),
    ] = IDLE_TORQUE_NM,
    out: Annotated[
        Path | None, typer.Option("--out", help="Write the estimate per sample to this CSV.")
    ] = None,
    plot: Annotated[Path | None, typer.Option("--plot", help="Draw the estimate to a PNG.")] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    html: HtmlReport = None,
) -> None:
    """Estimate flank wear from spindle torque with the EKF of Christiand 2024."""
    check_count("--seed", seed, 0, MAX_SEED)
    if html is not None:
        check_report_path(html)
    check_number("--vb0-mm", vb0_mm, 0.0, MAX_WEAR_MM, low_open=True, unit="mm")
    for value in stages_mm:
        check_number("--stages-mm", value, 0.0, MAX_WEAR_MM, low_open=True, unit="mm")
    if not stages_mm[0] < stages_mm[1] < stages_mm[2]:
        raise DataError(f"--stages-mm {stages_mm}: give three increasing wear values, mm")
    check_number("--base-torque-nm", base_torque_nm, 0.0, MAX_TORQUE_NM, unit="N*m")
    if preset not in PRESETS:
        raise DataError(f"unknown preset {preset!r}; available: {', '.join(sorted(PRESETS))}")
    chosen = PRESETS[preset]
    if synthetic == (data is not None):
        raise DataError("give exactly one of --data FILE.csv and --synthetic")
    if data is not None:
        series = read_torque_csv(data, base_torque_nm)
        source = str(data)
    else:
        series = synthetic_session(chosen, seed=seed)
        source = f"synthetic session (seed {seed})"
    stages = StageMonitor(stages_mm)
    run = run_filter(chosen.filter(vb0_mm=vb0_mm, var0_mm2=1e-3), series, stages)
    report = _report(series, run, source)
    if out is not None:
        _write_estimate(out, series, run)
    if plot is not None:
        _plot(plot, series, run, stages)
    if html is not None:
        from cnctwin.report import wear_ekf_report

        wear_ekf_report(html, report, series, run, stages)
    if as_json:
        sys.stdout.write(finite_json.dumps(report) + "\n")
        return
    table = Table(title=f"wear EKF: {source}", show_header=False, title_justify="left")
    table.add_row("samples", str(report["steps"]))
    table.add_row("final wear", f"{report['final_vb_mm']:.4f} +- {report['final_sd_mm']:.4f} mm")
    for event in run.events:
        table.add_row(f"stage {event.stage}", event.message)
    if "mean_abs_error_mm" in report:
        table.add_row("mean |error|", f"{report['mean_abs_error_mm']:.4f} mm")
        table.add_row("max |error|", f"{report['max_abs_error_mm']:.4f} mm")
    Console().print(table)
