"""``cnctwin runs list|show|export``: the twin's recorded runs, from the historian.

``--db`` takes an SQLite file or a ``postgresql://`` URL; without it the installation's file
(:func:`cnctwin.store.default_database_path`). The commands only read: a missing file is an
error, not a new database.
"""

from __future__ import annotations

import sys
from datetime import UTC, datetime
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.table import Table

from cnctwin import finite_json
from cnctwin.cli._options import HistorianDb, JsonOutput
from cnctwin.store import Historian, RunSummary

__all__ = ["app", "export", "list_runs", "show"]

app = typer.Typer(help="Recorded runs of the twin: list, show, export.", no_args_is_help=True)

RunArg = Annotated[int, typer.Argument(help="Run id (see `cnctwin runs list`).", min=1)]


def _open(db: str | None) -> Historian:
    return Historian.open(db, create=False)


def _when(unix_s: float | None) -> str:
    if unix_s is None:
        return "-"
    return datetime.fromtimestamp(unix_s, UTC).strftime("%Y-%m-%d %H:%M:%S")


def _duration(run: RunSummary) -> str:
    return "-" if run.ended_at is None else f"{run.ended_at - run.started_at:.1f}"


@app.command("list")
def list_runs(db: HistorianDb = None, as_json: JsonOutput = False) -> None:
    """List the recorded runs, oldest first."""
    with _open(db) as h:
        runs = h.runs()
        location = h.location
    if as_json:
        report = {"database": location, "runs": [r.to_dict() for r in runs]}
        sys.stdout.write(finite_json.dumps(report) + "\n")
        return
    table = Table(title=f"runs in {location}", title_justify="left")
    for column in ("id", "status", "started UTC", "duration s", "program", "values"):
        table.add_column(column)
    for column in ("events", "decisions"):
        table.add_column(column, justify="right")
    for r in runs:
        table.add_row(
            str(r.run_id),
            r.status,
            _when(r.started_at),
            _duration(r),
            str(r.meta.get("program", "-")),
            f"{r.values:,}",
            str(r.events),
            str(r.decisions),
        )
    Console().print(table)


@app.command()
def show(run_id: RunArg, db: HistorianDb = None, as_json: JsonOutput = False) -> None:
    """Show one run: what it was, its counts, signals, events and decisions."""
    with _open(db) as h:
        detail = h.run(run_id)
    if as_json:
        sys.stdout.write(finite_json.dumps(detail.to_dict()) + "\n")
        return
    s = detail.summary
    console = Console()
    info = Table(title=f"run {s.run_id}", show_header=False, title_justify="left")
    rows: dict[str, Any] = {
        "status": s.status,
        "started (UTC)": _when(s.started_at),
        "ended (UTC)": _when(s.ended_at),
        "instants": s.frames,
        "signal values": s.values,
        "predicted values": s.predicted_values,
        "last t_s": s.last_t_s,
        "signals": ", ".join(detail.signals) or "-",
        "predicted": ", ".join(detail.predicted) or "-",
        **{f"meta.{k}": v for k, v in s.meta.items()},
        **{f"summary.{k}": v for k, v in (s.summary or {}).items() if k != "stage_results"},
    }
    for key, value in rows.items():
        info.add_row(key, str(value))
    console.print(info)
    for stage, result in ((s.summary or {}).get("stage_results") or {}).items():
        sections = result.get("sections") if isinstance(result, dict) else None
        if sections:  # the columns with a value (headers wrap at their words)
            columns = [k for k in sections[0] if any(row.get(k) is not None for row in sections)]
            table = Table(title=f"{stage} by program section", title_justify="left")
            for column in columns:
                table.add_column(column.replace("_", " "))
            for row in sections:
                table.add_row(*("-" if row.get(k) is None else f"{row[k]:.4g}" for k in columns))
            console.print(table)
    if detail.events:
        events = Table(title="events", title_justify="left")
        for column in ("t_s", "kind", "message"):
            events.add_column(column)
        for e in detail.events:
            events.add_row(f"{e.t_s:.4f}", e.kind, e.message)
        console.print(events)
    if detail.decisions:
        decisions = Table(title="decisions", title_justify="left")
        for column in ("t_s", "rule", "action", "value", "accepted", "read-back", "reason"):
            decisions.add_column(column)
        for d in detail.decisions:
            decisions.add_row(
                f"{d.t_s:.4f}",
                d.rule,
                d.action,
                f"{d.value:g}",
                "yes" if d.accepted else "no",
                "-" if d.readback is None else f"{d.readback:g}",
                d.reason,
            )
        console.print(decisions)


@app.command()
def export(
    run_id: RunArg,
    out: Annotated[Path, typer.Argument(help="OUT.csv or OUT.parquet; siblings get the rest.")],
    db: HistorianDb = None,
    as_json: JsonOutput = False,
) -> None:
    """Export a run: OUT gets the signals (time_s + one column per signal);
    OUT.predictions, OUT.events and OUT.decisions (same format) the rest."""
    with _open(db) as h:
        files = h.export(run_id, out)
    if as_json:
        report = {"run": run_id, "files": [str(f) for f in files]}
        sys.stdout.write(finite_json.dumps(report) + "\n")
        return
    for f in files:
        typer.echo(str(f))
