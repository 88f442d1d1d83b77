"""The work of ``cnctwin nc inspect`` and ``cnctwin nc trace``, without typer.

:mod:`cnctwin.cli.nc` declares the commands' options under typer and calls these;
:mod:`cnctwin.cli.nc_argv` calls them for plain invocations read without typer.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterable, Iterator
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from cnctwin import finite_json
from cnctwin.nc import (
    DEFAULT_RAPID_MM_MIN,
    MAX_PROGRAM_BYTES,
    MAX_REPEATED_LINES,
    MAX_SEGMENTS,
    NCSetup,
    Segment,
    summarize,
)

if TYPE_CHECKING:
    from rich.table import Table

    from cnctwin.config import MachiningConfig
    from cnctwin.nc import MoveRun

__all__ = [
    "GUARD_FACTOR",
    "GUARD_LIMITS",
    "inspect_program",
    "inspect_report",
    "report_table",
    "trace_program",
]

#: The work guards (--max-*) may be raised up to this factor above their defaults, no further:
#: a guard is only a guard while it is bounded.
GUARD_FACTOR = 10

#: Each work guard option: (default, least, greatest value).
GUARD_LIMITS = {
    "--max-segments": (MAX_SEGMENTS, 1, GUARD_FACTOR * MAX_SEGMENTS),
    "--max-bytes": (MAX_PROGRAM_BYTES, 1, GUARD_FACTOR * MAX_PROGRAM_BYTES),
    "--max-repeated-lines": (MAX_REPEATED_LINES, 0, GUARD_FACTOR * MAX_REPEATED_LINES),
}


def _load(config: Path | None) -> MachiningConfig | None:
    """The configuration in ``config``; ``None`` (the defaults) when no file is given.

    pydantic and the configuration models are imported only for a file: without one, the
    interpreter's set-up is :class:`~cnctwin.nc.NCSetup`'s defaults, which equal those of
    a default :class:`~cnctwin.config.MachiningConfig` (a test keeps them equal).
    """
    if config is None:
        return None
    from cnctwin.config import load_config

    return load_config(config)


def _setup(settings: MachiningConfig | None) -> NCSetup:
    """The interpreter's set-up of ``settings``, or the defaults."""
    return settings.nc_setup() if settings is not None else NCSetup()


def _bounded(setup: NCSetup, max_segments: int, max_bytes: int, max_repeated: int) -> NCSetup:
    """``setup`` with the work limits given on the command line."""
    return replace(
        setup,
        max_segments=max_segments,
        max_program_bytes=max_bytes,
        max_repeated_lines=max_repeated,
    )


def inspect_report(
    program: Path,
    config: MachiningConfig | None,
    *,
    on_segment: Callable[[Segment], None] | None = None,
    check_travel: bool = True,
    setup: NCSetup | None = None,
) -> dict[str, Any]:
    """Interpret a program and summarize it, streaming.

    Parameters
    ----------
    program
        The NC file.
    config
        Machine and tools; ``None`` for the defaults (rapid rate
        :data:`~cnctwin.nc.setup.DEFAULT_RAPID_MM_MIN`, no travel check).
    on_segment
        Called with each segment as it streams by (e.g. to plot it).
    check_travel
        Warn about moves beyond the configured axis travel (off when the configuration
        is only the defaults, whose travel is a placeholder; always off without ``config``).
    setup
        The interpreter's set-up; that of ``config`` (or the defaults) if omitted.

    Returns
    -------
    dict
        The keys of ``cnctwin nc inspect --json``: lines, motion_blocks, feed_length_mm,
        rapid_length_mm, machining_time_s, rapid_time_s, dwell_time_s, total_time_s,
        bounds_mm, tools, units, warnings, file. Lengths in mm, times in s.

    Raises
    ------
    cnctwin.errors.CnctwinError
        NCError for a bad program, DataError for a bad tool table.
    OSError
        If the file cannot be read.
    """
    from cnctwin.nc import Interpreter  # the interpreter is heavy to import

    interpreter = Interpreter(setup if setup is not None else _setup(config))
    segments: Iterable[Segment | MoveRun]
    if on_segment is not None:
        segments = _tap(interpreter.run_file(program), on_segment)
    else:
        segments = interpreter.run_file_bulk(program)  # runs of moves summed in bulk
    travel = None
    rapid_mm_min = DEFAULT_RAPID_MM_MIN
    if config is not None:
        axes = config.machine.axes
        rapid_mm_min = config.machine.rapid_mm_min
        if check_travel:
            travel = (
                (axes.x.min_mm, axes.y.min_mm, axes.z.min_mm),
                (axes.x.max_mm, axes.y.max_mm, axes.z.max_mm),
            )
    summary = summarize(segments, rapid_mm_min=rapid_mm_min, travel_mm=travel).to_dict()
    return {
        "lines": interpreter.lines_read,
        **{key: summary[key] for key in _SUMMARY_KEYS},
        "units": interpreter.units or "mm",
        "warnings": [*interpreter.warnings, *summary["warnings"]],
        "file": str(program),
    }


_SUMMARY_KEYS = (
    "motion_blocks",
    "feed_length_mm",
    "rapid_length_mm",
    "machining_time_s",
    "rapid_time_s",
    "dwell_time_s",
    "total_time_s",
    "bounds_mm",
    "tools",
)


def inspect_program(
    program: Path,
    config: Path | None,
    as_json: bool,
    plot: Path | None,
    max_segments: int,
    max_bytes: int,
    max_repeated_lines: int,
) -> None:
    """``cnctwin nc inspect``: print the summary of ``program`` (a table, or JSON).

    Parameters are the command's options (docs/cli.md); ``plot`` also draws the tool-tip
    path to that PNG.
    """
    settings = _load(config)
    picture = None
    if plot is not None:
        from cnctwin.nc import ToolpathPlot  # matplotlib only when asked for

        picture = ToolpathPlot()
    report = inspect_report(
        program,
        settings,
        on_segment=picture.add if picture else None,
        check_travel=config is not None,
        setup=_bounded(_setup(settings), max_segments, max_bytes, max_repeated_lines),
    )
    if picture is not None and plot is not None:
        stock = (settings.stock.min_mm, settings.stock.max_mm) if settings is not None else None
        picture.save(plot, title=program.name, stock_mm=stock)
    if as_json:
        sys.stdout.write(finite_json.dumps(report) + "\n")
        return
    from rich.console import Console

    Console().print(report_table(report))
    if plot is not None:
        Console().print(f"tool path drawn to {plot}")
    warn = Console(stderr=True)
    for warning in report["warnings"]:
        warn.print(f"warning: {warning}", style="yellow", markup=False, highlight=False)


def trace_program(
    program: Path,
    config: Path | None,
    frame: str,
    max_segments: int,
    max_bytes: int,
    max_repeated_lines: int,
) -> None:
    """``cnctwin nc trace``: print the canonical motion trace of ``program``, one call a line.

    ``frame`` is ``"program"`` (program frame and units) or ``"machine"`` (machine
    coordinates, mm); the other parameters are the command's options (docs/cli.md).
    """
    from cnctwin.nc import Interpreter, trace_text

    setup = _bounded(_setup(_load(config)), max_segments, max_bytes, max_repeated_lines)
    interpreter = Interpreter(setup)
    pending: list[str] = []  # written 64 KiB at a time: one write a line costs
    size = 0
    try:
        for text in trace_text(interpreter.run_file_bulk(program), frame):
            pending.append(text)
            size += len(text)
            if size >= _TRACE_WRITE:
                _write_pieces("".join(pending))
                pending.clear()
                size = 0
    finally:  # the lines before an error are printed too
        _write_pieces("".join(pending))


#: Characters of a trace (ASCII) written at once: a pipe's capacity. A larger write to a
#: pipe that the reader closes part-way (``| head``) can end without an error.
_TRACE_WRITE = 1 << 16


def _write_pieces(text: str) -> None:
    out = sys.stdout
    for start in range(0, len(text), _TRACE_WRITE):
        out.write(text[start : start + _TRACE_WRITE])


def _tap(segments: Iterable[Segment], sink: Callable[[Segment], None]) -> Iterator[Segment]:
    for seg in segments:
        sink(seg)
        yield seg


def _duration(seconds: float) -> str:
    minutes, secs = divmod(seconds, 60.0)
    hours, minutes = divmod(int(minutes), 60)
    return f"{seconds:.1f} s ({hours}:{minutes:02d}:{secs:04.1f})"


def report_table(report: dict[str, Any]) -> Table:
    """A rich table of an :func:`inspect_report`."""
    from rich.table import Table

    table = Table(title=report["file"], show_header=False, title_justify="left")
    table.add_column("quantity", style="bold")
    table.add_column("value", justify="right")
    table.add_row("lines", str(report["lines"]))
    table.add_row("units", report["units"])
    table.add_row("motion blocks", str(report["motion_blocks"]))
    table.add_row("feed length", f"{report['feed_length_mm']:.3f} mm")
    table.add_row("rapid length", f"{report['rapid_length_mm']:.3f} mm")
    table.add_row("machining time", _duration(report["machining_time_s"]))
    table.add_row("rapid time", _duration(report["rapid_time_s"]))
    table.add_row("dwell time", _duration(report["dwell_time_s"]))
    table.add_row("total time", _duration(report["total_time_s"]))
    low, high = report["bounds_mm"]["min"], report["bounds_mm"]["max"]
    for axis, name in enumerate("XYZ"):
        span = f"{low[axis]:.3f} .. {high[axis]:.3f} mm" if low else "-"
        table.add_row(f"tool tip {name}", span)
    table.add_row("tools", ", ".join(f"T{t}" for t in report["tools"]) or "-")
    table.add_row("warnings", str(len(report["warnings"])))
    return table
