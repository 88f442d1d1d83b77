"""The report of ``cnctwin wear ekf``: the wear estimate with its band, stages and torque.

Christiand 2024, Fig. 9 shows the estimate with the bands of the wear stages; here the
estimate +- 2 standard deviations (the filter's own variance), the stage boundaries and the
stage events, and below it the measured spindle torque.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from cnctwin.report.document import Report
from cnctwin.wear import EKFRun, StageMonitor, TorqueSeries

__all__ = ["wear_ekf_report"]


def wear_ekf_report(
    path: Path,
    result: Mapping[str, Any],
    series: TorqueSeries,
    run: EKFRun,
    stages: StageMonitor,
) -> Path:
    """Write the wear estimate's report.

    Parameters
    ----------
    path
        The HTML file.
    result
        The ``cnctwin wear ekf --json`` object.
    series
        The torque series (time s, torque N*m, true wear mm where known).
    run
        The filter's run over it (estimate mm, variance mm^2, stage events).
    stages
        The stage boundaries (mm).
    """
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots

    t = series.time_s
    sd = np.sqrt(run.var_mm2)
    report = Report(
        "Tool wear estimate (EKF, Christiand 2024)",
        f"cnctwin wear ekf: {result['source']}, {result['steps']} samples; final wear "
        f"{result['final_vb_mm']:.4f} +- {result['final_sd_mm']:.4f} mm",
        result,
    )
    report.section(
        "Flank wear VB and spindle torque",
        "Shaded: the estimate +- 2 standard deviations. Dotted lines: entry of wear stages "
        "II, III, IV; vertical lines: the estimate entered a stage (red: earlier than a "
        "normal tool).",
    )
    figure = make_subplots(rows=2, cols=1, shared_xaxes=True, row_heights=(0.65, 0.35))
    figure.add_trace(
        go.Scatter(
            x=np.r_[t, t[::-1]],
            y=np.r_[run.vb_mm + 2 * sd, (run.vb_mm - 2 * sd)[::-1]],
            fill="toself",
            fillcolor="rgba(31,119,180,0.2)",
            line={"width": 0},
            name="estimate +- 2 sd",
            hoverinfo="skip",
        ),  # fmt: skip
        row=1,
        col=1,
    )
    figure.add_trace(go.Scatter(x=t, y=run.vb_mm, mode="lines", name="EKF estimate"), 1, 1)
    if series.vb_mm is not None:
        figure.add_trace(
            go.Scatter(
                x=t,
                y=series.vb_mm,
                mode="lines",
                line={"dash": "dash", "color": "black"},
                name="true wear",
            ),  # fmt: skip
            row=1,
            col=1,
        )
    for level in stages.boundaries_mm:
        figure.add_hline(y=level, line_dash="dot", line_color="grey", row=1, col=1)
    for event in run.events:
        figure.add_vline(x=event.time_s, line_color="red" if event.early else "orange",
                         annotation_text=f"stage {event.stage}", row=1, col=1)  # fmt: skip
    figure.add_trace(
        go.Scattergl(
            x=t,
            y=series.torque_nm * 1e3,
            mode="markers",
            marker={"size": 2},
            name="measured torque [mN m]",
        ),  # fmt: skip
        row=2,
        col=1,
    )
    figure.update_yaxes(title_text="VB [mm]", row=1, col=1)
    figure.update_yaxes(title_text="torque [mN m]", row=2, col=1)
    figure.update_xaxes(title_text="time [s]", row=2, col=1)
    report.figure(figure, height_px=680)
    if run.events:
        report.section("Stage events")
        report.table(
            [[e.stage, e.time_s, e.vb_mm, "yes" if e.early else "no"] for e in run.events],
            ["stage", "time [s]", "VB [mm]", "early"],
        )
    return report.write(path)
