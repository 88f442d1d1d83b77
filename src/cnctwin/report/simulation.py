"""The report of ``cnctwin simulate``: engagement over time and the final stock in 3D."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from cnctwin.geometry import DexelStock
from cnctwin.report.document import Report
from cnctwin.report.downsample import minmax_buckets
from cnctwin.simulation import StepTable

__all__ = ["simulation_report"]

#: Buckets of the time plots (points per trace at most twice this).
PLOT_BUCKETS = 2000

#: (column, label) of the engagement plots, in panel order.
_PANELS = (
    ("ae_mm", "ae [mm]"),
    ("ap_mm", "ap [mm]"),
    ("mrr_mm3_s", "MRR [mm^3/s]"),
    ("feed_mm_min", "reconstructed feed [mm/min]"),
)


def simulation_report(
    path: Path, result: Mapping[str, Any], table: StepTable, stock: DexelStock
) -> Path:
    """Write the simulation's report.

    Parameters
    ----------
    path
        The HTML file.
    result
        The command's JSON result (``cnctwin simulate --json``).
    table
        The simulation's steps (:class:`~cnctwin.simulation.cut.StepTable`; times in s).
    stock
        The stock after the program.
    """
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots

    from cnctwin.geometry import height_map

    report = Report(
        f"Simulation of {Path(str(result['file'])).name}",
        f"cnctwin simulate: {result['steps']} steps of {result['cycle_ms']:g} ms at "
        f"{result['density_per_mm']:g} dexels/mm",
        result,
    )
    t = table.column("t_s")
    report.section(
        "Engagement over time",
        "Each trace shows, per plot column, the smallest and largest value of the steps there "
        "(min/max downsampling), so no peak is hidden; zoom in for single steps.",
    )
    figure = make_subplots(rows=len(_PANELS), cols=1, shared_xaxes=True, vertical_spacing=0.03)
    for row, (name, label) in enumerate(_PANELS, start=1):
        if len(t):
            points = minmax_buckets(t, table.column(name), float(t[0]), float(t[-1]), PLOT_BUCKETS)
            x, y = points.t, points.y
        else:
            x = y = np.zeros(0)
        figure.add_trace(go.Scattergl(x=x, y=y, mode="lines", name=label), row=row, col=1)
        figure.update_yaxes(title_text=label, row=row, col=1)
    figure.update_xaxes(title_text="process time [s]", row=len(_PANELS), col=1)
    figure.update_layout(showlegend=False)
    report.figure(figure, height_px=820)
    hmap = height_map(stock)
    report.section(
        "Stock after the program",
        f"Top of the material over x and y (each cell the lowest top of {hmap.step} x "
        f"{hmap.step} dexel rays); drag to rotate, scroll to zoom.",
    )
    surface = go.Figure(
        go.Surface(
            x=hmap.x_mm,
            y=hmap.y_mm,
            z=hmap.z_mm,
            colorscale="Viridis",
            colorbar={"title": {"text": "z [mm]"}},
        )  # fmt: skip
    )
    surface.update_layout(
        scene={
            "xaxis_title": "x [mm]",
            "yaxis_title": "y [mm]",
            "zaxis_title": "z [mm]",
            "aspectmode": "data",
        }
    )
    report.figure(surface, height_px=640)
    if result.get("warnings"):
        report.section("Warnings")
        report.table([[w] for w in result["warnings"]], ["warning"])
    return report.write(path)
