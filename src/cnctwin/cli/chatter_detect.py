"""``cnctwin chatter detect``: chatter in a measured vibration or force signal (a CSV file).

The CSV has a header row, a time column (s) and one or more signal columns; the signal is
analysed in sliding windows by :mod:`cnctwin.dynamics.chatter_detection` (tooth-passing
harmonics notched out, energy ratio, chatter frequency, verdict per window). Guide:
docs/chatter.md.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import typer
from rich.console import Console
from rich.table import Table

from cnctwin import finite_json
from cnctwin.cli._options import check_number
from cnctwin.config import MAX_SPINDLE_RPM
from cnctwin.dynamics import (
    DEFAULT_THRESHOLD,
    ChatterDetection,
    DetectorSettings,
    detect_chatter,
)
from cnctwin.errors import InputError
from cnctwin.measurements import read_signal_csv

__all__ = ["detect", "detection_report"]


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
        "chatter_frequency_hz": [finite_json.finite(float(v)) for v in found.chatter_frequency_hz],
        "chatter_flags": [bool(v) for v in found.chatter],
        "windows": len(found),
        "chatter_windows": int(found.chatter.sum()),
        "chatter": bool(found.chatter.any()),
        "first_chatter_s": finite_json.finite(float(found.first_chatter_s)),
        "max_energy_ratio": float(found.energy_ratio[worst]),
        "dominant_chatter_frequency_hz": finite_json.finite(
            float(found.chatter_frequency_hz[worst])
        ),
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
    for option, value, least, high, unit in (
        ("--rpm", rpm, 1.0, MAX_SPINDLE_RPM, "rpm"),
        ("--window-s", window_s, 0.0, 3600.0, "s"),
        ("--hop-s", hop_s, 0.0, 3600.0, "s"),
    ):
        if value is not None:
            check_number(option, value, least, high, low_open=True, unit=unit)
    if not 1 <= teeth <= 100:
        raise InputError(f"--teeth {teeth!r}; give an integer from 1 to 100")
    if not (0.0 < threshold < 1.0):
        raise InputError(f"--threshold {threshold!r}; give 0 < threshold < 1")
    samples, rate, name = read_signal_csv(signal, column, time_column)
    settings = DetectorSettings(
        rate, rpm, teeth, window_s, hop_s, threshold, spindle_harmonics=spindle_harmonics
    )
    found = detect_chatter(samples, settings)
    report = detection_report(found, str(signal), name)
    if as_json:
        sys.stdout.write(finite_json.dumps(report) + "\n")
        return
    Console().print(_table(report))


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
