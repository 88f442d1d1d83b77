"""``cnctwin nc``: read NC programs: summarize (``inspect``) and trace (``trace``) them.

The options are declared here, under typer; the work is :mod:`cnctwin.cli.nc_work`'s.
"""

from __future__ import annotations

from enum import Enum
from pathlib import Path
from typing import Annotated, Any

import typer

from cnctwin.cli.nc_work import (
    GUARD_LIMITS,
    inspect_program,
    inspect_report,
    report_table,
    trace_program,
)
from cnctwin.nc import MAX_PROGRAM_BYTES, MAX_REPEATED_LINES, MAX_SEGMENTS

__all__ = ["app", "inspect", "inspect_report", "report_table", "trace"]

app = typer.Typer(help="Read NC programs: summarize, trace, plot.", no_args_is_help=True)

ProgramArg = Annotated[Path, typer.Argument(help="NC program (.ngc, .nc, .tap, .mpf, ...).")]
ConfigOpt = Annotated[
    Path | None,
    typer.Option(
        "--config", "-c", help="Configuration TOML (machine, tools); defaults if omitted."
    ),
]


def _guard(name: str, help_text: str) -> Any:
    """The typer option of the work guard ``name`` (its range: ``GUARD_LIMITS``)."""
    _, least, greatest = GUARD_LIMITS[name]
    return typer.Option(name, min=least, max=greatest, help=help_text)


MaxSegmentsOpt = Annotated[
    int,
    _guard("--max-segments", "Stop with an error after this many motion segments (work guard)."),
]
MaxBytesOpt = Annotated[
    int, _guard("--max-bytes", "Refuse program files larger than this (bytes).")
]
MaxRepeatedOpt = Annotated[
    int,
    _guard(
        "--max-repeated-lines",
        "Stop with an error after O-word loops and calls execute this many lines again.",
    ),
]


@app.command()
def inspect(
    program: ProgramArg,
    config: ConfigOpt = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    plot: Annotated[
        Path | None, typer.Option("--plot", help="Also draw the tool-tip path to this PNG.")
    ] = None,
    max_segments: MaxSegmentsOpt = MAX_SEGMENTS,
    max_bytes: MaxBytesOpt = MAX_PROGRAM_BYTES,
    max_repeated_lines: MaxRepeatedOpt = MAX_REPEATED_LINES,
) -> None:
    """Summarize a program: lengths, times, bounds of the tool tip, tools, warnings.

    With --json, numbers that are not finite are written as null (see docs/cli.md).
    """
    inspect_program(program, config, as_json, plot, max_segments, max_bytes, max_repeated_lines)


class Frame(str, Enum):  # noqa: UP042 (str() of a StrEnum differs; kept as typer sees it)
    """Coordinates of a trace."""

    program = "program"
    machine = "machine"


@app.command()
def trace(
    program: ProgramArg,
    config: ConfigOpt = None,
    frame: Annotated[
        Frame,
        typer.Option(
            "--frame",
            help="program: program frame and units, comparable with LinuxCNC's traces; "
            "machine: machine coordinates in mm.",
        ),
    ] = Frame.program,
    max_segments: MaxSegmentsOpt = MAX_SEGMENTS,
    max_bytes: MaxBytesOpt = MAX_PROGRAM_BYTES,
    max_repeated_lines: MaxRepeatedOpt = MAX_REPEATED_LINES,
) -> None:
    """Print the canonical motion trace of a program, one call a line: source line, call."""
    trace_program(program, config, frame.value, max_segments, max_bytes, max_repeated_lines)
