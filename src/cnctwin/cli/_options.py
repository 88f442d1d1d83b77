"""What the commands share: options, range checks of numeric options, a progress bar.

Each check raises a one-line :class:`~cnctwin.errors.InputError` that names the option, the
value given and the valid range; the CLI turns it into exit status 2. The checks run before a
command does any work, so a bad value never starts a machine, a server or a long computation.
The ranges and their reasons are listed in docs/cli.md ("Ranges of the options").
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated

import typer

from cnctwin.errors import InputError

__all__ = ["MAX_SEED", "check_count", "check_number", "progress"]


#: ``--density``: the simulation's dexel density, dexels per mm, overriding the config's.
Density = Annotated[
    float | None, typer.Option("--density", help="Dexels per mm (overrides the config).")
]
#: ``--cycle-ms``: the simulation's cycle time, ms, overriding the config's.
CycleMs = Annotated[
    float | None, typer.Option("--cycle-ms", help="Cycle time in ms (overrides the config).")
]
#: ``--json``: print the result as one JSON object instead of a table.
JsonOutput = Annotated[bool, typer.Option("--json", help="Print one JSON object.")]
#: ``--db``: the historian of the twin's runs (default: the installation's SQLite file).
HistorianDb = Annotated[
    str | None,
    typer.Option(
        "--db",
        help="Historian: SQLite file or postgresql://USER@HOST:PORT/DB "
        "(default: the installation's file).",
    ),
]
#: ``--report``: a self-contained HTML report of the command's result.
HtmlReport = Annotated[
    Path | None,
    typer.Option("--report", help="Write a self-contained HTML report (interactive plots)."),
]

#: Largest random seed accepted: the 32-bit seeds every generator of the project takes.
MAX_SEED = 2**32 - 1
#: Longest run of the twin (``cnctwin run --duration``), s: 30 days; beyond, omit the option.
MAX_RUN_S = 30 * 86_400.0
#: Longest wait for a machine or a start (``--connect-timeout``, ``virtual serve --delay``), s.
MAX_WAIT_S = 3_600.0
#: Fastest virtual machine, machine seconds per wall-clock second: its kernels keep up to it.
MAX_SPEED_FACTOR = 20.0


def check_number(
    option: str,
    value: float,
    low: float,
    high: float,
    *,
    low_open: bool = False,
    unit: str = "",
) -> float:
    """``value`` if it is finite and within ``[low, high]`` (``(low, high]`` with ``low_open``).

    ``high`` may be ``math.inf``: any finite value above ``low`` is then valid.

    Parameters
    ----------
    option
        The option as typed, e.g. ``--rpm``.
    value
        The value given, in ``unit``.
    low, high
        The valid range, in ``unit``.
    low_open
        Exclude ``low`` itself (for quantities that must be > 0).
    unit
        Unit named in the error message, e.g. ``mm``.

    Raises
    ------
    InputError
        For a non-finite value or one outside the range.
    """
    above = value > low if low_open else value >= low
    if not (math.isfinite(value) and above and value <= high):
        least = ">" if low_open else ">="
        most = f" and <= {high:g}" if math.isfinite(high) else ""
        suffix = f" {unit}" if unit else ""
        raise InputError(f"{option} {value!r}: give a value {least} {low:g}{most}{suffix}")
    return float(value)


def check_count(option: str, value: int, low: int, high: int, *, unit: str = "") -> int:
    """``value`` if ``low <= value <= high`` (integers: counts, seeds, ports).

    Raises
    ------
    InputError
        For a value outside the range, naming the option and the range.
    """
    if not (low <= value <= high):
        suffix = f" {unit}" if unit else ""
        raise InputError(f"{option} {value}: give an integer from {low:,} to {high:,}{suffix}")
    return int(value)


@contextmanager
def progress(label: str, shown: bool) -> Iterator[Callable[[float], None] | None]:
    """A progress bar on stderr for a long computation over program time, or none.

    Parameters
    ----------
    label
        What is computed, e.g. ``"simulating"``.
    shown
        Show the bar; without it the callback is ``None``.

    Yields
    ------
    callable or None
        Called with the program time reached, s (the ``on_chunk`` of
        :func:`cnctwin.simulation.program.simulate_program`).
    """
    if not shown:
        yield None
        return
    from rich.console import Console
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    with Progress(
        TextColumn(label),
        BarColumn(),
        TextColumn("{task.fields[t]:.1f} s"),
        TimeElapsedColumn(),
        console=Console(stderr=True),
        transient=True,
    ) as bar:
        task = bar.add_task(label, total=None, t=0.0)
        yield lambda t_s: bar.update(task, t=t_s)
