"""``cnctwin chatter detect``: chatter in a measured vibration or force signal (a CSV file).

The CSV has a header row, a time column (s) and one or more signal columns; the signal is
analysed in sliding windows by :mod:`cnctwin.dynamics.chatter_detection` (tooth-passing
harmonics notched out, energy ratio, chatter frequency, verdict per window). Guide:
docs/chatter.md.
"""

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
from cnctwin.config.machine import MAX_SPINDLE_RPM
from cnctwin.dynamics.chatter_detection import (
    DEFAULT_THRESHOLD,
    ChatterDetection,
    DetectorSettings,
    detect_chatter,
)
from cnctwin.errors import ConfigError, DataError

__all__ = ["detect", "detection_report", "read_signal"]

#: Names taken for the time column when ``--time-column`` is not given (case-insensitive).
TIME_NAMES = ("t_s", "time_s", "time", "t")
_UNIFORM = 1e-3  # largest relative deviation of a sampling interval from the mean


def read_signal(
    path: Path, column: str | None, time_column: str | None
) -> tuple[np.ndarray, float, str]:
    """Read one signal column and the sampling rate from a CSV with a header row.

    Parameters
    ----------
    path
        The CSV file.
    column
        Signal column; ``None``: the first column that is not the time column.
    time_column
        Time column (s); ``None``: the first of :data:`TIME_NAMES` present.

    Returns
    -------
    tuple
        The samples, the sampling rate in Hz and the signal column's name.

    Raises
    ------
    cnctwin.errors.DataError
        One line naming the file (and line) for a missing column, a cell that is not a
        number, fewer than 16 rows, or a time column that is not evenly increasing.
    """
    try:
        with path.open(newline="", encoding="utf-8-sig") as handle:
            rows = [row for row in csv.reader(handle) if any(cell.strip() for cell in row)]
    except UnicodeDecodeError as err:
        raise DataError(f"{path}: not a UTF-8 text file ({err.reason})") from None
    if not rows:
        raise DataError(f"{path}: empty; give a header row with a time column, then samples")
    header = [cell.strip() for cell in rows[0]]
    lowered = [name.lower() for name in header]
    if time_column is None:
        found = [name for name in TIME_NAMES if name in lowered]
        if not found:
            raise DataError(
                f"{path}: no time column among {header}; name one t_s, time_s, time or t, "
                "or give --time-column"
            )
        t_index = lowered.index(found[0])
    elif time_column in header:
        t_index = header.index(time_column)
    else:
        raise DataError(f"{path}: no column {time_column!r} (--time-column); columns: {header}")
    if column is None:
        others = [i for i in range(len(header)) if i != t_index]
        if not others:
            raise DataError(f"{path}: only a time column; add a signal column")
        s_index = others[0]
    elif column in header:
        s_index = header.index(column)
    else:
        raise DataError(f"{path}: no column {column!r} (--column); columns: {header}")
    data = np.empty((len(rows) - 1, 2))
    for line, row in enumerate(rows[1:], start=2):
        for j, index in enumerate((t_index, s_index)):
            try:
                data[line - 2, j] = float(row[index])
            except (IndexError, ValueError):
                cell = row[index] if index < len(row) else ""
                raise DataError(
                    f"{path}:{line}: column {header[index]!r} is {cell!r}; give a number"
                ) from None
    if data.shape[0] < 16:
        raise DataError(f"{path}: {data.shape[0]} samples; give at least 16")
    steps = np.diff(data[:, 0])
    mean = float(steps.mean())
    if not (mean > 0.0 and np.all(np.abs(steps - mean) <= _UNIFORM * mean)):
        raise DataError(
            f"{path}: column {header[t_index]!r} is not evenly increasing (steps "
            f"{steps.min():.6g} ... {steps.max():.6g} s); resample to a fixed rate"
        )
    if not np.all(np.isfinite(data[:, 1])):
        raise DataError(f"{path}: column {header[s_index]!r} holds a value that is not finite")
    return data[:, 1].copy(), 1.0 / mean, header[s_index]


def detection_report(found: ChatterDetection, source: str, column: str) -> dict[str, Any]:
    """The ``--json`` object of ``chatter detect``.

    Returns
    -------
    dict
        ``source``, ``column``, the settings (``sample_rate_hz``, ``spindle_rpm``, ``teeth``,
        ``tooth_passing_hz``, ``window_s``, ``hop_s``, ``resolution_hz``, ``threshold``,
        ``spindle_harmonics``), the per-window lists ``start_s``, ``end_s``,
        ``energy_ratio``, ``chatter_frequency_hz`` (null without energy), ``chatter_flags``,
        then
        ``windows``, ``chatter_windows``, ``chatter`` (any window chatters),
        ``first_chatter_s`` (end of the first chattering window, null if none),
        ``max_energy_ratio`` and ``dominant_chatter_frequency_hz`` (of that window).
    """
    settings = found.settings
    worst = int(np.argmax(found.energy_ratio))
    return {
        "source": source,
        "column": column,
        "sample_rate_hz": settings.sample_rate_hz,
        "spindle_rpm": settings.spindle_rpm,
        "teeth": settings.teeth,
        "tooth_passing_hz": settings.tooth_passing_hz,
        "window_s": settings.window_samples / settings.sample_rate_hz,
        "hop_s": settings.hop_samples / settings.sample_rate_hz,
        "resolution_hz": settings.resolution_hz,
        "threshold": settings.threshold,
        "spindle_harmonics": settings.spindle_harmonics,
        "start_s": found.start_s.tolist(),
        "end_s": found.end_s.tolist(),
        "energy_ratio": found.energy_ratio.tolist(),
        "chatter_frequency_hz": [_null(v) for v in found.chatter_frequency_hz],
        "chatter_flags": [bool(v) for v in found.chatter],
        "windows": len(found),
        "chatter_windows": int(found.chatter.sum()),
        "chatter": bool(found.chatter.any()),
        "first_chatter_s": _null(found.first_chatter_s),
        "max_energy_ratio": float(found.energy_ratio[worst]),
        "dominant_chatter_frequency_hz": _null(float(found.chatter_frequency_hz[worst])),
    }


def detect(
    signal: Annotated[
        Path, typer.Argument(help="CSV: a header row, a time column (s), signal columns.")
    ],
    rpm: Annotated[float, typer.Option("--rpm", help="Spindle speed, rpm.")],
    teeth: Annotated[int, typer.Option("--teeth", help="Number of teeth.")],
    column: Annotated[
        str | None,
        typer.Option("--column", help="Signal column (default: the first after the time)."),
    ] = None,
    time_column: Annotated[
        str | None,
        typer.Option("--time-column", help="Time column, s (default: t_s, time_s, time or t)."),
    ] = None,
    window_s: Annotated[
        float, typer.Option("--window-s", help="Window length, s (resolution 1/window).")
    ] = 0.1,
    hop_s: Annotated[
        float | None,
        typer.Option("--hop-s", help="Time between window starts, s (default: the window)."),
    ] = None,
    threshold: Annotated[
        float,
        typer.Option("--threshold", help="Energy ratio off the harmonics above which: chatter."),
    ] = DEFAULT_THRESHOLD,
    spindle_harmonics: Annotated[
        bool,
        typer.Option(
            "--spindle-harmonics",
            help="Notch the spindle harmonics too (runout; hides flip chatter of even teeth).",
        ),
    ] = False,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
) -> None:
    """Detect chatter in a measured vibration or force signal (sliding-window spectra).

    Per window: the energy off the tooth-passing harmonics over the total (the energy
    ratio), the dominant remaining peak (the chatter frequency) and the verdict
    (ratio > threshold, default 0.2).
    """
    # Ranges: a spindle speed as [machine] max_spindle_rpm, teeth as [[tools]] flutes, a
    # window or hop of at most an hour (a longer one overflows the sample count's arithmetic).
    for option, value, least, high in (
        ("--rpm", rpm, 1.0, MAX_SPINDLE_RPM),
        ("--window-s", window_s, 0.0, 3600.0),
        ("--hop-s", hop_s, 0.0, 3600.0),
    ):
        if value is not None and not (math.isfinite(value) and least < value <= high):
            raise ConfigError(f"{option} {value!r}; give a value > {least:g} and <= {high:g}")
    if not 1 <= teeth <= 100:
        raise ConfigError(f"--teeth {teeth!r}; give an integer from 1 to 100")
    if not (0.0 < threshold < 1.0):
        raise ConfigError(f"--threshold {threshold!r}; give 0 < threshold < 1")
    samples, rate, name = read_signal(signal, column, time_column)
    settings = DetectorSettings(
        rate, rpm, teeth, window_s, hop_s, threshold, spindle_harmonics=spindle_harmonics
    )
    found = detect_chatter(samples, settings)
    report = detection_report(found, str(signal), name)
    if as_json:
        sys.stdout.write(finite_json.dumps(report) + "\n")
        return
    Console().print(_table(report))


def _null(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


def _table(report: dict[str, Any]) -> Table:
    table = Table(
        title=f"chatter detection: {report['source']} ({report['column']})",
        show_header=False,
        title_justify="left",
    )
    table.add_column("quantity", style="bold")
    table.add_column("value", justify="right")
    table.add_row(
        "verdict",
        f"CHATTER in {report['chatter_windows']} of {report['windows']} windows"
        if report["chatter"]
        else f"stable ({report['windows']} windows)",
    )
    if report["first_chatter_s"] is not None:
        table.add_row("chatter known at", f"{report['first_chatter_s']:.4g} s")
    table.add_row("highest energy ratio", f"{report['max_energy_ratio']:.3g}")
    if report["dominant_chatter_frequency_hz"] is not None:
        table.add_row("its dominant frequency", f"{report['dominant_chatter_frequency_hz']:.1f} Hz")
    table.add_row("tooth passing", f"{report['tooth_passing_hz']:.2f} Hz")
    table.add_row(
        "windows",
        f"{report['window_s']:.4g} s every {report['hop_s']:.4g} s, "
        f"resolution {report['resolution_hz']:.3g} Hz, threshold {report['threshold']:g}",
    )
    return table
