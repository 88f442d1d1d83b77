"""``cnctwin study``: parameter studies; ``study dexel``: Heide 2025's density x cycle time."""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.markup import escape
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from cnctwin import finite_json
from cnctwin.cli._options import check_count
from cnctwin.errors import InputError
from cnctwin.report import check_report_path

__all__ = ["app", "dexel", "dexel_report"]

#: Most worker processes: the paper's study has 240 runs, so more would idle.
MAX_WORKERS = 256

app = typer.Typer(help="Parameter studies of the simulation.", no_args_is_help=True)


@app.callback()
def _study() -> None:
    """Parameter studies of the simulation."""


def dexel_report(
    out: Path,
    *,
    quick: bool = False,
    workers: int | None = None,
    progress: bool = False,
    html: Path | None = None,
) -> dict[str, Any]:
    """Run the dexel study, write its outputs into ``out`` and return the summary.

    Parameters
    ----------
    out
        Folder for results.csv, the heat maps (PNG), summary.json and report.md (created).
    quick
        Run :meth:`~cnctwin.studies.DexelStudy.quick` (24 short runs) instead of the paper's
        240 runs.
    workers
        Processes, >= 1; ``None`` for the number of CPUs.
    progress
        Show a progress bar on stderr.
    html
        File of the HTML report (:func:`~cnctwin.report.study.dexel_study_report`), or None.

    Returns
    -------
    dict
        The contents of summary.json (see :func:`cnctwin.studies.report.write_outputs`).
    """
    from cnctwin.studies import DexelStudy, default_workers, run_study, write_outputs

    n = default_workers() if workers is None else workers
    check_count("--workers", n, 1, MAX_WORKERS, unit="processes")
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {out}: not a folder; give a folder for the results")
    if html is not None:
        check_report_path(html)
    study = DexelStudy.quick() if quick else DexelStudy.paper()
    started = time.perf_counter()
    if progress:
        with Progress(
            TextColumn("dexel study"),
            BarColumn(),
            MofNCompleteColumn(),
            TimeElapsedColumn(),
            console=Console(stderr=True),
            transient=True,
        ) as bar:
            task = bar.add_task("runs", total=len(study.runs()))
            results = run_study(study, workers=n, on_result=lambda _: bar.advance(task))
    else:
        results = run_study(study, workers=n)
    wall = time.perf_counter() - started
    summary = write_outputs(out, study, results, workers=n, wall_s=wall)
    if html is not None:
        from cnctwin.report import dexel_study_report

        dexel_study_report(html, summary, study, results)
    return summary


def dexel(
    out: Annotated[
        Path,
        typer.Option("--out", help="Folder for results.csv, heat maps, summary.json, report.md."),
    ],
    quick: Annotated[
        bool, typer.Option("--quick", help="24 short runs instead of the paper's 240.")
    ] = False,
    workers: Annotated[
        int | None,
        typer.Option("--workers", help="Parallel processes (default: the number of CPUs)."),
    ] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print summary.json to stdout.")] = False,
    html: Annotated[
        Path | None,
        typer.Option("--report", help="Write a self-contained HTML report (interactive maps)."),
    ] = None,
) -> None:
    """Heide 2025's dexel density x cycle time study: accuracy, runtime, score, optimum."""
    summary = dexel_report(
        out, quick=quick, workers=workers, progress=not as_json and sys.stderr.isatty(), html=html
    )
    if as_json:
        sys.stdout.write(finite_json.dumps(summary) + "\n")
        return
    paper, best = summary["paper"], summary["optimum"]
    table = Table(title="dexel study: optimum of S (Heide 2025, Eq. 3)", title_justify="left")
    table.add_column("")
    table.add_column("Heide 2025", justify="right")
    table.add_column("this run", justify="right")
    for label, key, scale, spec in (
        ("density [1/mm]", "density_per_mm", 1.0, ".3g"),
        ("cycle time [ms]", "cycle_s", 1e3, ".4g"),
        ("mean |delta ae| [mm]", "delta_ae_mm", 1.0, ".3g"),
        ("feed deviation [%]", "feed_deviation_pct", 1.0, ".2g"),
        ("runtime [s] (ours: CPU)", "cpu_s", 1.0, ".3g"),
        ("process time [s]", "process_s", 1.0, ".4g"),
        ("score S", "score", 1.0, ".3f"),
    ):
        theirs = paper.get("runtime_s" if key == "cpu_s" else key)
        table.add_row(
            escape(label),
            format(theirs * scale, spec) if theirs is not None else "–",
            format(best[key] * scale, spec),
        )
    console = Console()
    console.print(table)
    bounded = summary["optimum_within_volume_bound"]
    if bounded is not None:
        console.print(
            f"best S removing the volume of a continuous cut within "
            f"{summary['volume_bound_pct']:g} % at "
            f"every feed: {bounded['density_per_mm']:g} /mm, {bounded['cycle_ms']:g} ms "
            f"(S = {bounded['score']:.3f})",
            highlight=False,
        )
    fit = summary["t_star_fit"]
    if fit is not None:
        console.print(
            f"runtime ~ (rho^2/t_cycle)^{fit['exponent']:.2f}, R^2 = {fit['r2']:.3f}",
            highlight=False,
        )
    console.print(
        f"{summary['study']['runs']} runs in {summary['study']['wall_s']:.1f} s; "
        f"report: {out / 'report.md'}",
        highlight=False,
    )


app.command("dexel")(dexel)
