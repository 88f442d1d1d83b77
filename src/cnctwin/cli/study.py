"""``cnctwin study``: parameter studies; ``study dexel``: Heide 2025's density x cycle time."""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.markup import escape
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)
from rich.table import Table

from cnctwin import finite_json
from cnctwin.cli._options import check_count
from cnctwin.errors import CnctwinError, InputError
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
    volume_tolerance_pct: float = 1.0,
    min_realtime_factor: float = 1.0,
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
        Show a progress bar on stderr (a terminal); otherwise progress goes to stderr as lines.
        Either way the run count and, after the first run, the estimated time go to stderr.
    html
        File of the HTML report (:func:`~cnctwin.report.study.dexel_study_report`), or None.
    volume_tolerance_pct, min_realtime_factor
        The optimum's constraints (:class:`~cnctwin.studies.Constraints`).

    Returns
    -------
    dict
        The contents of summary.json (see :func:`cnctwin.studies.report.write_outputs`).
    """
    from cnctwin.studies import (
        Constraints,
        DexelStudy,
        RunResult,
        default_workers,
        estimate_wall_s,
        run_study,
        write_outputs,
    )

    n = default_workers() if workers is None else workers
    check_count("--workers", n, 1, MAX_WORKERS, unit="processes")
    try:
        constraints = Constraints(volume_tolerance_pct, min_realtime_factor)
    except CnctwinError as error:
        raise InputError(
            f"--volume-tolerance-pct {volume_tolerance_pct} / --min-realtime-factor "
            f"{min_realtime_factor}: {error}"
        ) from None
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {out}: not a folder; give a folder for the results")
    if html is not None:
        check_report_path(html)
    study = DexelStudy.quick() if quick else DexelStudy.paper()
    total = len(study.runs())
    err = Console(stderr=True, highlight=False)
    err.print(f"dexel study: {total} runs on {min(n, total)} process(es)")
    started = time.perf_counter()
    done = 0

    def report_progress(result: RunResult, advance: Callable[[], None] | None) -> None:
        nonlocal done
        done += 1
        if done == 1:
            scaled, bound = estimate_wall_s(study, result.spec, result.runtime_s, n)
            err.print(
                f"dexel study: first run {result.runtime_s:.2f} s; estimated {scaled:.0f} s for "
                f"all runs (the first scaled by each run's rho^2 / (t_cycle vf)), at most "
                f"{bound:.0f} s ({total} runs x the first, the longest, / {min(n, total)} "
                "process(es))"
            )
        if advance is not None:
            advance()
        elif done == total or done % max(1, total // 10) == 0:
            err.print(f"dexel study: {done}/{total} runs, {time.perf_counter() - started:.0f} s")

    if progress:
        with Progress(
            TextColumn("dexel study"),
            BarColumn(),
            MofNCompleteColumn(),
            TimeElapsedColumn(),
            TimeRemainingColumn(),
            console=err,
            transient=True,
        ) as bar:
            task = bar.add_task("runs", total=total)
            results = run_study(
                study, workers=n, on_result=lambda r: report_progress(r, lambda: bar.advance(task))
            )
    else:
        results = run_study(study, workers=n, on_result=lambda r: report_progress(r, None))
    wall = time.perf_counter() - started
    summary = write_outputs(out, study, results, workers=n, wall_s=wall, constraints=constraints)
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
    volume_tolerance_pct: Annotated[
        float,
        typer.Option(
            "--volume-tolerance-pct",
            help="The optimum's removed volume within this % of a continuous cut's.",
        ),
    ] = 1.0,
    min_realtime_factor: Annotated[
        float,
        typer.Option("--min-realtime-factor", help="The optimum's least process/CPU time."),
    ] = 1.0,
) -> None:
    """Heide 2025's dexel density x cycle time study: accuracy, runtime, score, optimum."""
    from cnctwin.studies import summary_lead

    summary = dexel_report(
        out,
        quick=quick,
        workers=workers,
        progress=not as_json and sys.stderr.isatty(),
        html=html,
        volume_tolerance_pct=volume_tolerance_pct,
        min_realtime_factor=min_realtime_factor,
    )
    if as_json:
        sys.stdout.write(finite_json.dumps(summary) + "\n")
        return
    console = Console()
    for line in summary_lead(summary):
        console.print(line, highlight=False)
    paper, top = summary["paper"], summary["score_optimum"]
    best = summary["optimum"] or {}
    table = Table(title="dexel study: optimum (Heide 2025's S, constrained)", title_justify="left")
    table.add_column("")
    table.add_column("Heide 2025", justify="right")
    table.add_column("optimum", justify="right")
    table.add_column("least S", justify="right")
    for label, key, scale, spec in (
        ("density [1/mm]", "density_per_mm", 1.0, ".3g"),
        ("cycle time [ms]", "cycle_s", 1e3, ".4g"),
        ("mean |delta ae| [mm]", "delta_ae_mm", 1.0, ".3g"),
        ("feed deviation [%]", "feed_deviation_pct", 1.0, ".2g"),
        ("runtime [s] (ours: CPU)", "cpu_s", 1.0, ".3g"),
        ("volume deviation, worst feed [%]", "volume_deviation_pct", 1.0, ".3g"),
        ("process time [s]", "process_s", 1.0, ".4g"),
        ("score S", "score", 1.0, ".3f"),
    ):
        theirs = paper.get("runtime_s" if key == "cpu_s" else key)
        table.add_row(
            escape(label),
            *(
                format(v * scale, spec) if v is not None else "–"
                for v in (theirs, best.get(key), top[key])
            ),
        )
    console.print(table)
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
